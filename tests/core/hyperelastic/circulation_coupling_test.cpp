// The accurate tier's time steps coupled to the lumped circulation
// (core/hyperelastic/circulation_coupling.hpp) on a small contracting neo-Hookean left
// ventricle: every step the cavity holds the loop's volume, blood is conserved, the
// ventricle ejects and refills, and a loose tolerance agrees with a tight one.
#include "core/hyperelastic/circulation_coupling.hpp"

#include "core/lv_ellipsoid.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>

namespace fiberfem::core::hyperelastic {
namespace {

namespace cc = circulation;
constexpr double kPeriod = 0.8;
constexpr double kPi = 3.14159265358979323846;

struct Setup {
  TetMesh corners = make_lv_ellipsoid(fiberfem::testing::lv_spec(12, 6, 2));
  std::shared_ptr<const ElementMesh> mesh = std::make_shared<const ElementMesh>(corners, 1);
  Problem problem{mesh};
  CavitySurface endo = cavity_surface(corners, corners.node_set("endo"));

  Setup() {
    LawParameters law;
    law.kind = LawKind::neo_hookean;
    law.mu_pa = 10e3;
    law.bulk_modulus_pa = 100e3;
    problem.region_laws = {law};
    problem.region_density_kg_m3 = {1060};
    problem.element_region.assign(static_cast<size_t>(mesh->num_elements()), 0);
    problem.fixed_dofs.assign(static_cast<size_t>(3 * mesh->num_nodes()), 0);
    for (int n : corners.node_set("base"))
      for (int i = 0; i < 3; ++i) problem.fixed_dofs[static_cast<size_t>(3 * n + i)] = 1;
    for (int e = 0; e < mesh->num_elements(); ++e) {
      Vec3 c = Vec3::Zero();
      for (int n : corners.tets()[static_cast<size_t>(e)]) c += corners.rest_positions().col(n) / 4;
      problem.axes.push_back(MaterialAxes::from(Vec3(-c.y(), c.x(), 0.1 * std::hypot(c.x(), c.y()))));
    }
    problem.active_tension_pa.assign(static_cast<size_t>(mesh->num_elements()), 30e3);
    const std::set<int> endo_nodes(corners.node_set("endo").begin(), corners.node_set("endo").end());
    PressureLoad load;
    load.pressure_pa = 1.0;
    for (int f = 0; f < static_cast<int>(mesh->boundary_faces().size()); ++f) {
      const auto& face = mesh->boundary_faces()[static_cast<size_t>(f)];
      if (endo_nodes.count(face[0]) && endo_nodes.count(face[1]) && endo_nodes.count(face[2])) load.faces.push_back(f);
    }
    problem.pressures = {load};
  }

  // The loop, scaled to this ventricle (rest cavity about 2.4 mL) and material.
  cc::Parameters loop() const {
    cc::Parameters p;
    p.period_s = kPeriod;
    p.scale(0.1, volume_scale());
    return p;
  }
  cc::State initial() const {
    cc::State s = cc::State::regazzoni_initial();
    for (double& v : s.volume_m3) v *= volume_scale();
    for (double& q : s.pressure_pa) q *= 0.1;
    return s;
  }
  double volume_scale() const { return cavity_volume(endo, corners.rest_positions()) / 120e-6; }
};

// Active tension of the beat: sin^2 over the first 0.3 s of each period.
double twitch(double t) {
  const double phase = std::fmod(t, kPeriod);
  return phase < 0.3 ? std::pow(std::sin(kPi * phase / 0.3), 2) : 0.0;
}

struct Trace {
  std::vector<double> pressure, volume;
};

Trace run(double tolerance, int steps) {
  Setup s;
  DynamicSettings settings;
  settings.mass_damping_1_s = 20;
  settings.newton.tolerance = std::min(1e-9, 1e-2 * tolerance);  // the volumes as exact as asked
  DynamicSolver solver(s.problem, settings);
  CirculationCoupledDynamics coupled(solver, s.problem, s.loop(), s.initial(), {{cc::lv, 0, s.endo}}, tolerance);
  const double blood0 = cc::total_volume(coupled.parameters(), coupled.state());
  const double rest = cavity_volume(s.endo, s.corners.rest_positions());
  Trace r;
  for (int i = 0; i < steps; ++i) {
    Loading loading;
    loading.active_factor = twitch(solver.time_s() + settings.dt_s);
    const CoupledStepReport rep = coupled.step(loading);
    EXPECT_TRUE(rep.converged) << "step " << i << ": " << rep.message;
    if (!rep.converged) break;
    const cc::State& st = coupled.state();
    EXPECT_LE(std::abs(coupled.volumes()[0] - st.volume_m3[cc::lv]), tolerance * 1.0001 * rest);
    EXPECT_NEAR(cc::total_volume(coupled.parameters(), st), blood0, 1e-13 * blood0);
    r.pressure.push_back(st.external_pa[0]);
    r.volume.push_back(coupled.volumes()[0]);
  }
  // The state's stored energy is that of its positions and pressures (the last iterate's).
  const Assembler assembler(s.problem);
  Eigen::VectorXd R;
  const double energy = assembler.evaluate(solver.positions(), solver.pressures(), Loading{}, R, nullptr).energy_j;
  EXPECT_GT(energy, 0);
  EXPECT_NEAR(solver.elastic_energy_j(), energy, 1e-12 * energy);
  return r;
}

TEST(CirculationCoupledDynamics, TheCavityHoldsTheLoopsVolumeAndEjects) {
  const Trace r = run(1e-8, 48);
  ASSERT_EQ(r.volume.size(), 48u);
  const auto [lo, hi] = std::minmax_element(r.volume.begin(), r.volume.end());
  EXPECT_GT((*hi - *lo) / *hi, 0.05);                                      // it ejected
  EXPECT_GT(*std::max_element(r.pressure.begin(), r.pressure.end()), 0.1 * 60 * cc::kPaPerMmHg);  // above the aortic diastolic
}

TEST(CirculationCoupledDynamics, ALooseToleranceAgreesWithATightOne) {
  const Trace loose = run(1e-6, 24), tight = run(1e-10, 24);
  ASSERT_EQ(loose.pressure.size(), tight.pressure.size());
  double worst = 0, peak = 0;
  for (size_t i = 0; i < loose.pressure.size(); ++i) {
    worst = std::max(worst, std::abs(loose.pressure[i] - tight.pressure[i]));
    peak = std::max(peak, tight.pressure[i]);
  }
  EXPECT_LT(worst, 2e-3 * peak);
}

}  // namespace
}  // namespace fiberfem::core::hyperelastic
