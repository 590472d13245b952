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

// Steering (Simulator::set_circulation_parameters): the loop's state carries over as it is,
// the first step after the change moves the pressure no more than a step of the unsteered
// run ever does, blood stays conserved (a resistance holds no volume), and a tripled
// systemic resistance raises the mean aortic pressure of the next beat.
TEST(CoupledSimulator, SteeringCarriesTheLoopStateOverAndTakesEffect) {
  core::Simulator steered(ventricle(true, true), direct_settings()), plain(ventricle(true, true), direct_settings());
  const double total0 = cc::total_volume(steered.model().circulation.parameters, steered.circulation_state());
  for (int i = 0; i < 30; ++i) {
    ASSERT_NE(steered.step().status, core::StepStatus::failed);
    ASSERT_NE(plain.step().status, core::StepStatus::failed);
  }
  cc::Parameters p = steered.model().circulation.parameters;
  p.compartments[cc::ar_sys].resistance_pa_s_m3 *= 3;
  steered.set_circulation_parameters(p);
  EXPECT_EQ(steered.model().circulation.parameters.compartments[cc::ar_sys].resistance_pa_s_m3,
            p.compartments[cc::ar_sys].resistance_pa_s_m3);
  const cc::State& a = steered.circulation_state();
  const cc::State& b = plain.circulation_state();
  EXPECT_TRUE(a.pressure_pa == b.pressure_pa && a.volume_m3 == b.volume_m3 && a.flow_m3_s == b.flow_m3_s);
  double largest_step = 0, last = b.pressure_pa[cc::ar_sys], first_gap = -1;
  double mean_steered = 0, mean_plain = 0;
  for (int i = 0; i < 96; ++i) {  // two beats
    ASSERT_NE(steered.step().status, core::StepStatus::failed);
    ASSERT_NE(plain.step().status, core::StepStatus::failed);
    const double now = plain.circulation_state().pressure_pa[cc::ar_sys];
    largest_step = std::max(largest_step, std::abs(now - last));
    last = now;
    if (first_gap < 0) first_gap = std::abs(steered.circulation_state().pressure_pa[cc::ar_sys] - now);
    if (i >= 48) {
      mean_steered += steered.circulation_state().pressure_pa[cc::ar_sys] / 48;
      mean_plain += now / 48;
    }
    EXPECT_NEAR(cc::total_volume(steered.model().circulation.parameters, steered.circulation_state()), total0, 1e-13 * total0);
  }
  EXPECT_GT(first_gap, 0);
  EXPECT_LE(first_gap, largest_step);
  EXPECT_GT(mean_steered, 1.2 * mean_plain) << mean_steered << " vs " << mean_plain;

  // Refused, nothing changed: invalid parameters, or a model without a circulation.
  cc::Parameters bad = steered.model().circulation.parameters;
  bad.compartments[cc::ven_sys].compliance_m3_pa = -1;
  try {
    steered.set_circulation_parameters(bad);
    ADD_FAILURE() << "accepted a negative compliance";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("systemic.veins.compliance"), std::string::npos) << e.what();
  }
  EXPECT_GT(steered.model().circulation.parameters.compartments[cc::ven_sys].compliance_m3_pa, 0);
  core::Simulator uncoupled(ventricle(true, false), direct_settings());
  EXPECT_THROW(uncoupled.set_circulation_parameters(cc::Parameters{}), std::invalid_argument);
}

// A new heart rate keeps the beat under way: set with the contraction's at the same step
// boundary, the chambers' pressures are those of just before (the lumped right ventricle is
// relaxing, the atria resting), and loop and contraction count their next beats from the
// same time (the beat under way began at 0.8 s).
TEST(CoupledSimulator, ANewHeartRateKeepsTheBeatUnderWayForLoopAndContraction) {
  core::Model m = ventricle(true, true);
  for (cc::ChamberId c : {cc::la, cc::ra}) m.circulation.parameters.chambers[c].elastance.onset_s = 0.4;
  core::Simulator sim(std::move(m), direct_settings());
  for (int i = 0; i < 75; ++i) ASSERT_NE(sim.step().status, core::StepStatus::failed);  // 1.25 s: 0.45 s into beat 2
  const cc::Observables before = cc::observe(sim.model().circulation.parameters, sim.circulation_state());
  cc::Parameters p = sim.model().circulation.parameters;
  p.period_s = 0.6;
  sim.set_circulation_parameters(p);
  core::Contraction c = sim.model().contraction;
  c.period_s = 0.6;
  sim.set_contraction(c);
  const cc::Observables after = cc::observe(sim.model().circulation.parameters, sim.circulation_state());
  for (int k : {cc::la, cc::ra, cc::rv}) EXPECT_NEAR(after.chamber_pa[k], before.chamber_pa[k], 1e-9 * std::abs(before.chamber_pa[k]) + 1e-9);
  EXPECT_GT(before.chamber_pa[cc::rv], 0);
  const double loop_origin = sim.circulation_state().beat_origin_s;
  EXPECT_NEAR(loop_origin, 0.8, 1e-9);
  const double beats = (loop_origin - sim.contraction_origin_s()) / 0.6;
  EXPECT_NEAR(beats, std::round(beats), 1e-9);
  for (int i = 0; i < 72; ++i) ASSERT_NE(sim.step().status, core::StepStatus::failed);  // two beats at the new rate
}
