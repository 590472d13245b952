// The Simulator coupled to the lumped circulation (core/simulator_circulation.cpp) on a
// small contracting left ventricle: the cavity volume equals the loop's every step, blood
// is conserved, isovolumic phases keep the volume without oscillating, one coupled step
// equals a plain step loaded with the pressure it found, and checkpoints restore bit for bit.
#include "core/circulation/circulation.hpp"
#include "core/lv_ellipsoid.hpp"
#include "core/simulator.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>

namespace core = fiberfem::core;
namespace cc = fiberfem::core::circulation;

namespace {

constexpr double kPeriod = 0.8;

// A coarse truncated ellipsoid, base fixed, circumferential fibers, contracting once per
// period; the left ventricle coupled to the loop, scaled to its size and stiffness.
core::Model ventricle(bool contract, bool couple) {
  core::Model m(core::make_lv_ellipsoid(fiberfem::testing::lv_spec(12, 6, 2)));
  m.region_materials = {core::Material::isotropic(60e3, 0.45, 1060)};
  m.region_damping = {core::RayleighDamping{20.0, 0.0}};
  m.fix_nodes(m.mesh.node_set("base"));
  m.fibers.resize(static_cast<size_t>(m.mesh.num_elements()));
  for (int e = 0; e < m.mesh.num_elements(); ++e) {
    core::Vec3 c = core::Vec3::Zero();
    for (int n : m.mesh.tets()[static_cast<size_t>(e)]) c += m.mesh.rest_positions().col(n) / 4;
    m.fibers[static_cast<size_t>(e)] = core::Vec3(-c.y(), c.x(), 0.1 * std::hypot(c.x(), c.y())).normalized();
  }
  if (contract) {
    m.contraction.period_s = kPeriod;
    m.contraction.region_peak_pa = {25e3};
  }
  if (couple) {
    cc::Coupling& c = m.circulation;
    const core::CavitySurface s = core::cavity_surface(m.mesh, m.mesh.node_set("endo"));
    const double v_rest = core::cavity_volume(s, m.mesh.rest_positions());
    const double vs = v_rest / (120 * cc::kM3PerMl), ps = 0.1;
    c.parameters.period_s = kPeriod;
    c.parameters.scale(ps, vs);
    c.initial = cc::State::regazzoni_initial();
    for (double& v : c.initial.volume_m3) v *= vs;
    for (double& p : c.initial.pressure_pa) p *= ps;
    c.cavities.push_back({cc::lv, "endo", s});
  }
  return m;
}

core::SimulatorSettings direct_settings() {
  core::SimulatorSettings s;
  s.solver.method = core::LinearSolverKind::direct;
  s.threads = 1;
  return s;
}

}  // namespace

TEST(CoupledSimulator, CavityFollowsTheLoopAndBloodIsConserved) {
  core::Simulator sim(ventricle(true, true), direct_settings());
  const cc::Parameters& p = sim.model().circulation.parameters;
  const double total0 = cc::total_volume(p, sim.circulation_state());
  const double v_rest = sim.coupled_cavity_volumes()[0];
  double peak_p = 0, vmin = 1, vmax = 0;
  for (int i = 0; i < 96; ++i) {  // two beats
    const core::StepReport r = sim.step();
    ASSERT_NE(r.status, core::StepStatus::failed) << r.message;
    const cc::State& s = sim.circulation_state();
    // The mesh's cavity holds what the loop says, to the coupling's tolerance.
    EXPECT_LE(std::abs(sim.coupled_cavity_volumes()[0] - s.volume_m3[cc::lv]), 1e-9 * v_rest * 1.0001);
    EXPECT_NEAR(cc::total_volume(p, s), total0, 1e-13 * total0);
    peak_p = std::max(peak_p, s.external_pa[0]);
    vmin = std::min(vmin, s.volume_m3[cc::lv]);
    vmax = std::max(vmax, s.volume_m3[cc::lv]);
  }
  // It beat: the pressure rose past the scaled aortic diastolic pressure and it ejected.
  EXPECT_GT(peak_p, 0.1 * 60 * cc::kPaPerMmHg);
  EXPECT_GT((vmax - vmin) / vmax, 0.05);
}

TEST(CoupledSimulator, IsovolumicPhasesKeepTheVolumeAndDoNotOscillate) {
  // A step of 1/240 s resolves the phases (at 1/60 s this small ventricle contracts
  // isovolumically within one step).
  core::SimulatorSettings settings = direct_settings();
  settings.dt_s = 1.0 / 240;
  core::Simulator sim(ventricle(true, true), settings);
  const cc::Parameters& p = sim.model().circulation.parameters;
  // Steps during which both valves of the ventricle are shut (flows below 0.1 % of the
  // cavity's volume per second): runs of them are the isovolumic phases.
  int phases = 0, in_phase = 0;
  double v_start = 0, p_last = 0, dp_last = 0;
  int reversals = 0;
  for (int i = 0; i < 384; ++i) {
    ASSERT_NE(sim.step().status, core::StepStatus::failed);
    const cc::State& s = sim.circulation_state();
    const cc::Observables o = cc::observe(p, s);
    const double v = sim.coupled_cavity_volumes()[0];
    const bool shut = std::abs(o.valve_m3_s[cc::mitral]) < 1e-3 * v && std::abs(o.valve_m3_s[cc::aortic]) < 1e-3 * v;
    if (shut && in_phase == 0) v_start = v, dp_last = 0;
    if (shut) {
      ++in_phase;
      EXPECT_LT(std::abs(v - v_start) / v_start, 1e-3) << "step " << i;
      const double dp = s.external_pa[0] - p_last;
      if (in_phase > 1 && dp * dp_last < 0) ++reversals;
      dp_last = dp;
    } else {
      if (in_phase >= 2) ++phases;
      in_phase = 0;
    }
    p_last = s.external_pa[0];
  }
  EXPECT_GE(phases, 2);      // contraction and relaxation, at least one each beat
  EXPECT_EQ(reversals, 0);   // the pressure rises or falls monotonically within a phase
}

TEST(CoupledSimulator, AStepEqualsAPlainStepLoadedWithItsPressure) {
  // From rest (no contraction: the loop fills the ventricle), one coupled step finds p;
  // the plain engine loaded with a follower pressure p on the same wall must land on the
  // same positions, and the loop with that pressure on the same volume.
  core::Simulator coupled(ventricle(false, true), direct_settings());
  ASSERT_EQ(coupled.step().status, core::StepStatus::ok);
  const double p = coupled.circulation_state().external_pa[0];
  EXPECT_GT(p, 0);
  core::Model plain_model = ventricle(false, false);
  core::SurfaceLoad load;
  load.faces = core::cavity_surface(plain_model.mesh, plain_model.mesh.node_set("endo")).faces;
  load.pressure_pa = p;
  load.follower = true;
  plain_model.loads.surface_loads.push_back(load);
  core::Simulator plain(std::move(plain_model), direct_settings());
  ASSERT_EQ(plain.step().status, core::StepStatus::ok);
  const double scale = (coupled.positions() - coupled.model().mesh.rest_positions()).cwiseAbs().maxCoeff();
  EXPECT_GT(scale, 0);
  EXPECT_LT((coupled.positions() - plain.positions()).cwiseAbs().maxCoeff(), 1e-8 * scale);
  const core::CavitySurface s = core::cavity_surface(plain.model().mesh, plain.model().mesh.node_set("endo"));
  EXPECT_NEAR(core::cavity_volume(s, plain.positions()), coupled.circulation_state().volume_m3[cc::lv],
              1e-8 * coupled.circulation_state().volume_m3[cc::lv]);
}

TEST(CoupledSimulator, LooseToleranceConvergesToTheTightOne) {
  // A run with the default tolerance against one converged 1000 times tighter: the
  // pressures agree to far better than a mmHg over a beat.
  core::Model loose_model = ventricle(true, true), tight_model = ventricle(true, true);
  loose_model.circulation.volume_tolerance = 1e-6;
  tight_model.circulation.volume_tolerance = 1e-12;
  core::Simulator loose(std::move(loose_model), direct_settings()), tight(std::move(tight_model), direct_settings());
  double worst = 0, peak = 0;
  for (int i = 0; i < 48; ++i) {
    ASSERT_NE(loose.step().status, core::StepStatus::failed);
    ASSERT_NE(tight.step().status, core::StepStatus::failed);
    worst = std::max(worst, std::abs(loose.circulation_state().external_pa[0] - tight.circulation_state().external_pa[0]));
    peak = std::max(peak, tight.circulation_state().external_pa[0]);
  }
  EXPECT_LT(worst, 1e-3 * peak);
}

TEST(CoupledSimulator, CheckpointRestoresTheLoopBitForBit) {
  core::SimulatorSettings s;  // the default PCG solver with its recycled solutions
  s.threads = 1;
  core::Simulator sim(ventricle(true, true), s);
  for (int i = 0; i < 20; ++i) sim.step();
  const core::SimulatorCheckpoint c = sim.checkpoint();
  for (int i = 0; i < 15; ++i) sim.step();
  const core::Positions x1 = sim.positions();
  const cc::State s1 = sim.circulation_state();
  sim.restore(c);
  for (int i = 0; i < 15; ++i) sim.step();
  EXPECT_EQ((sim.positions() - x1).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(sim.circulation_state().external_pa, s1.external_pa);
  EXPECT_EQ(sim.circulation_state().volume_m3, s1.volume_m3);
  EXPECT_EQ(sim.circulation_state().pressure_pa, s1.pressure_pa);
  EXPECT_EQ(sim.circulation_state().flow_m3_s, s1.flow_m3_s);
}

TEST(CoupledSimulator, RefusesAnOpenCavity) {
  core::Model m = ventricle(true, true);
  m.fixed_dofs.clear();
  m.fix_nodes(m.mesh.node_set("apex_epi"));
  try {
    core::Simulator sim(std::move(m), direct_settings());
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("not closed"), std::string::npos) << e.what();
  }
}
