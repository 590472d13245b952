// Contraction (core/contraction.hpp, PHYSICS.md section 6): the twitch shapes against their
// closed forms, the schedule's period and pacing delays, and the engine driven by the
// schedule: a bar on rollers contracting quasi-statically shortens by T(t) / E_L along its
// fibers (uniaxial stress), in both the active-stress and the paper's nodal-force modes.

#include "core/box_generator.hpp"
#include "core/contraction.hpp"
#include "core/simulator.hpp"
#include "test_support.hpp"

#include <cmath>

namespace core = fiberfem::core;
using core::Vec3;
using fiberfem::testing::expect_invalid;

TEST(Twitch, BiexponentialPeaksAtOneAtTheAnalyticTime) {
  core::Twitch tw;  // tau1 0.05, tau2 0.11 (REFERENCES.md)
  const double t_star = 0.05 * 0.11 * std::log(0.11 / 0.05) / (0.11 - 0.05);
  EXPECT_NEAR(tw.peak_time(), t_star, 1e-15);
  EXPECT_NEAR(tw.value(t_star), 1.0, 1e-12);
  EXPECT_LT(tw.value(t_star - 1e-3), 1.0);
  EXPECT_LT(tw.value(t_star + 1e-3), 1.0);
  EXPECT_EQ(tw.value(0.0), 0.0);
  EXPECT_EQ(tw.value(-0.1), 0.0);
  // The closed form of REFERENCES.md, transcribed: r = tau1/tau2,
  // beta = r^(1/(1-r)) - r^(r/(1-r)) (negative here, as is the numerator after t = 0).
  const double r = 0.05 / 0.11, beta = std::pow(r, 1 / (1 - r)) - std::pow(r, r / (1 - r));
  for (double t : {0.01, 0.08, 0.3, 0.5})
    EXPECT_NEAR(tw.value(t), (std::exp(-t / 0.05) - std::exp(-t / 0.11)) / beta, 1e-14) << t;
  EXPECT_GT(tw.value(0.5), 0.0);
}

TEST(Twitch, SineIsSinSquaredOverTheSystole) {
  core::Twitch tw;
  tw.shape = core::TwitchShape::sine;
  tw.systole_s = 0.4;
  EXPECT_NEAR(tw.value(0.2), 1.0, 1e-15);
  EXPECT_NEAR(tw.value(0.1), 0.5, 1e-15);
  EXPECT_EQ(tw.value(0.4), 0.0);
  EXPECT_EQ(tw.value(0.7), 0.0);
  EXPECT_NEAR(tw.peak_time(), 0.2, 1e-15);
}

TEST(Contraction, PeriodicAndDelayedByPacing) {
  core::Contraction c;
  c.period_s = 0.8;
  c.twitch.shape = core::TwitchShape::sine;
  c.twitch.systole_s = 0.3;
  c.region_peak_pa = {1000.0, 0.0};
  EXPECT_TRUE(c.enabled());
  EXPECT_NEAR(c.tension(0, 0.0, 0.15), 1000.0, 1e-9);
  EXPECT_NEAR(c.tension(0, 0.0, 0.15 + 3 * 0.8), 1000.0, 1e-9);
  EXPECT_EQ(c.tension(1, 0.0, 0.15), 0.0);
  EXPECT_NEAR(c.tension(0, 0.1, 0.25), 1000.0, 1e-9);  // delayed by 0.1 s
  EXPECT_EQ(c.tension(0, 0.1, 0.05), 0.0);
  // Pacing: delay = distance / speed from the site to each centroid.
  core::BoxSpec b;
  b.size_m = Vec3(0.04, 0.01, 0.01);
  b.cells = {4, 1, 1};
  const core::TetMesh m = core::make_box(b);
  const std::vector<double> d = core::pacing_delays(m.rest_positions(), m.tets(), Vec3(0, 0.005, 0.005), 0.5);
  for (int e = 0; e < m.num_elements(); ++e) {
    Vec3 cen = Vec3::Zero();
    for (int n : m.tets()[static_cast<size_t>(e)]) cen += 0.25 * m.rest_positions().col(n);
    EXPECT_NEAR(d[static_cast<size_t>(e)], (cen - Vec3(0, 0.005, 0.005)).norm() / 0.5, 1e-15);
  }
}

// A bar along x with fibers along x, on rollers at x = 0 (x held) and pinned against
// rigid motion, contracting with a slow sine twitch (systole 2 s) under heavy mass damping:
// quasi-static, so the strain along x follows -T(t) / E_L (uniaxial stress: the active
// stress T f f^T is balanced by the elastic stress, no lateral load). Tolerance 3%: the
// damping force of the slow motion (alpha m v against the elastic force) lags the strain
// by alpha h-scale times; measured 0.4% at the peak.
TEST(Contraction, BarShortensByTensionOverModulusInBothModes) {
  for (auto mode : {core::ContractionMode::active_stress, core::ContractionMode::nodal_forces}) {
    core::BoxSpec b;
    b.size_m = Vec3(0.02, 0.004, 0.004);
    b.cells = {10, 2, 2};
    core::Model model(core::make_box(b));
    core::EngineeringConstants ec;  // E_L 60 kPa, E_T 20 kPa, nu_LT 0.25, nu_T 0.45, G_L 8 kPa
    model.region_materials = {core::Material::from_engineering(ec, 1000.0)};
    model.region_damping = {core::RayleighDamping{200.0, 0.0}};
    model.set_uniform_fiber(Vec3::UnitX());
    model.fix_nodes(model.mesh.node_set("xmin"), 0b001);
    // One corner pinned in y and z, a second in z: no rigid motion, no lateral constraint.
    int corner = -1, corner_y = -1;
    for (int n : model.mesh.node_set("xmin")) {
      const Vec3 p = model.mesh.rest_positions().col(n);
      if (p.y() == 0 && p.z() == 0) corner = n;
      if (p.y() > 0.0039 && p.z() == 0) corner_y = n;
    }
    model.fix_nodes({corner}, 0b110);
    model.fix_nodes({corner_y}, 0b100);
    model.contraction.mode = mode;
    model.contraction.period_s = 4.0;
    model.contraction.twitch.shape = core::TwitchShape::sine;
    model.contraction.twitch.systole_s = 2.0;
    model.contraction.region_peak_pa = {600.0};  // 1% strain
    core::SimulatorSettings st;
    st.dt_s = 0.01;
    core::Simulator sim(model, st);
    const auto& xmax = model.mesh.node_set("xmax");
    auto strain = [&] {
      double mean = 0;
      for (int n : xmax) mean += sim.positions()(0, n);
      return (mean / static_cast<double>(xmax.size()) - 0.02) / 0.02;
    };
    for (int s = 0; s < 100; ++s) sim.step();  // t = 1 s: the peak
    EXPECT_NEAR(strain() / (-600.0 / 60e3), 1.0, 0.03) << core::to_string(mode);
    for (int s = 0; s < 200; ++s) sim.step();  // t = 3 s: relaxed
    EXPECT_LT(std::abs(strain()), 1e-3 * 0.01) << core::to_string(mode);
    expect_invalid([&] { sim.set_active_tension(std::vector<double>(static_cast<size_t>(model.mesh.num_elements()), 1.0)); },
                   {"contraction schedule"});
  }
}

TEST(Contraction, BadSettingsNameTheField) {
  core::Contraction c;
  c.region_peak_pa = {1.0};
  c.period_s = 0;
  expect_invalid([&] { c.validate(1, 1); }, {"period_s"});
  c.period_s = 1;
  c.twitch.tau2_s = 0.01;
  expect_invalid([&] { c.validate(1, 1); }, {"tau2_s"});
  c.twitch = core::Twitch{};
  c.region_peak_pa = {-1.0};
  expect_invalid([&] { c.validate(1, 1); }, {"region_peak_pa[0]"});
  c.region_peak_pa = {1.0, 2.0};
  expect_invalid([&] { c.validate(1, 1); }, {"2 entries for 1 regions"});
  c.region_peak_pa = {1.0};
  c.element_delay_s = {0.0, -1.0};
  expect_invalid([&] { c.validate(1, 2); }, {"element_delay_s[1]"});
  expect_invalid([&] { core::pacing_delays(core::Positions::Zero(3, 4), {{0, 1, 2, 3}}, Vec3::Zero(), 0.0); }, {"speed"});
  // A twitch that outlasts two periods would need more than the previous beat's tail.
  c.element_delay_s.clear();
  c.twitch.tau2_s = 0.5;
  c.period_s = 0.5;
  expect_invalid([&] { c.validate(1, 1); }, {"two periods", "tau2_s"});
}

// The tabulated beat the engine reads agrees with the closed form to 1e-5 of the peak over
// several beats (first beat without a previous tail, later ones with it), for both shapes.
TEST(Contraction, TabulatedBeatMatchesTheClosedForm) {
  for (auto shape : {core::TwitchShape::biexponential, core::TwitchShape::sine}) {
    core::Contraction c;
    c.twitch.shape = shape;
    c.region_peak_pa = {1.0};
    const core::TwitchTable table = c.tabulate();
    double worst = 0;
    for (int k = 0; k < 40000; ++k) {
      const double t = -0.1 + 3.5 * k / 40000.0;
      worst = std::max(worst, std::abs(table.value(t) - c.tension(0, 0.0, t)));
    }
    EXPECT_LT(worst, 1e-5) << core::to_string(shape);
  }
}
