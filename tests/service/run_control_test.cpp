// Commands against a running scene (service/run_control.hpp), without DDS: every bad
// command is refused with a reason naming what is wrong and leaves the run bit-for-bit as
// it was; accepted ones do what an independent computation says they should.

#include "service/run_control.hpp"

#include "core/static_solver.hpp"
#include "io/scene_accurate.hpp"
#include "service/engine_accurate.hpp"

#include "accurate_beam_scene.hpp"
#include "io/scene.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>

namespace fiberfem::service {
namespace {

const char* kBeam = R"(
name: beam
mesh: {generator: box, size: [0.1, 0.01, 0.01], cells: [10, 2, 2]}
regions:
  - name: tissue
    select: all
    material: {E_L: 60.0e3, E_T: 20.0e3, nu_LT: 0.25, nu_T: 0.45, G_L: 8.0e3, density: 1000.0}
    damping: {mass: 40.0, stiffness: 0.0}
fibers: {uniform: [1, 0, 0]}
fixed:
  - plane: {axis: x, value: 0.0}
loads: {gravity: [0, 0, -9.81]}
solver: {dt: 0.01}
)";

io::Scene beam() { return io::parse_scene(kBeam, "beam"); }

core::Positions run(RunControl& rc, int steps) {
  for (int i = 0; i < steps; ++i) {
    rc.before_step();
    EXPECT_NE(rc.simulator().step().status, core::StepStatus::failed);
  }
  return rc.simulator().positions();
}

TEST(RunControl, BadCommandsAreRefusedWithAReasonAndChangeNothing) {
  struct Bad {
    const char* kind;
    const char* args;
    const char* reason_has;
  };
  const Bad bad[] = {
      {"warp_drive", "{}", "unknown command 'warp_drive'"},
      {"set_gravity", "{gravity: [0, 0", "not valid JSON"},
      {"set_gravity", "[1, 2, 3]", "JSON object"},
      {"set_gravity", R"({"gravity": [0, 0, .nan]})", "gravity[2]"},
      {"set_gravity", R"({"gravity": [0, 0, 1e999]})", "gravity[2]"},
      {"set_gravity", R"({"gravity": [0, 0]})", "three numbers"},
      {"set_gravity", R"({"g": [0, 0, 1]})", "unknown argument 'g'"},
      {"set_time_step", R"({"dt": -0.01})", "'dt'"},
      {"set_time_step", R"({"dt": "fast"})", "'dt' must be a number"},
      {"set_material", R"({"region": "bone", "E_L": 1e5})", "no region 'bone'"},
      {"set_material", R"({"nu_T": 1.5})", "nu_T"},
      {"set_material", R"({"E": 1e5})", "nu"},
      {"set_damping", R"({"mass": -1})", "'mass'"},
      {"set_contraction", R"({"heart_rate": 0})", "heart_rate"},
      {"set_contraction", R"({"peak_tension": 1000, "twitch": {"tau1": -1}})", "tau1"},
      {"set_fibers", R"({"uniform": [0, 0, 0]})", "fibers"},
      {"set_solver", R"({"method": "magic"})", "method"},
      {"set_solver", R"({"tolerance": 2})", "tolerance"},
      {"apply_force", R"({"target": {"node": 100000}, "force": [0, 0, 1]})", "target.node"},
      {"apply_force", R"({"target": {"node_set": "nowhere"}, "force": [0, 0, 1]})", "no node set 'nowhere'"},
      {"apply_force", R"({"target": {"node": 3}})", "exactly one of 'force'"},
      {"apply_force", R"({"target": {"node": 3}, "magnitude": 1})", "along: fibers"},
      {"clear_force", R"({"name": "ghost"})", "no force named 'ghost'"},
      {"step", R"({"count": 0})", "'count'"},
      {"step", R"({"count": 1.5})", "whole number"},
      {"pause", R"({"now": true})", "takes none"},
  };
  RunControl rc(beam());
  run(rc, 3);
  for (const Bad& b : bad) {
    const CommandResult r = rc.apply(b.kind, b.args);
    EXPECT_FALSE(r.accepted) << b.kind << " " << b.args;
    EXPECT_NE(r.reason.find(b.reason_has), std::string::npos) << b.kind << " " << b.args << ": " << r.reason;
  }
  EXPECT_EQ(rc.parameter_version(), 0u);
  EXPECT_FALSE(rc.paused());
  // The run goes on exactly as an untouched one.
  RunControl untouched(beam());
  run(untouched, 3);
  const core::Positions a = run(rc, 20), b = run(untouched, 20);
  EXPECT_EQ((a - b).cwiseAbs().maxCoeff(), 0.0);
}

// A force spread over the free end, held until the damped beam settles, must give the
// static equilibrium of the same load (the static Newton solver, an independent path).
TEST(RunControl, AppliedForceSettlesToTheStaticEquilibriumOfThatLoad) {
  io::Scene sc = io::parse_scene(kBeam, "beam", "", {"loads.gravity=[0, 0, 0]", "regions[0].damping.mass=60"});
  RunControl rc(sc);
  const CommandResult r = rc.apply("apply_force", R"({"name": "push", "target": {"node_set": "xmax"}, "force": [0, 0, -2e-3]})");
  ASSERT_TRUE(r.accepted) << r.reason;
  const core::Positions x_dyn = run(rc, 600);  // 6 s at 60 1/s mass damping

  core::Model m = sc.model;
  const auto& xmax = m.mesh.node_set("xmax");
  for (int n : xmax) m.loads.point_forces.push_back({n, core::Vec3(0, 0, -2e-3 / static_cast<double>(xmax.size()))});
  core::Positions x_static;
  ASSERT_TRUE(core::solve_static(m, x_static).converged);
  const double tip = (x_static - m.mesh.rest_positions()).col(xmax[0]).norm();
  EXPECT_GT(tip, 1e-3);  // a real deflection
  EXPECT_LT((x_dyn - x_static).cwiseAbs().maxCoeff(), 1e-3 * tip);

  // Cleared, it swings back to rest.
  ASSERT_TRUE(rc.apply("clear_force", R"({"name": "push"})").accepted);
  const core::Positions x_back = run(rc, 600);
  EXPECT_LT((x_back - m.mesh.rest_positions()).cwiseAbs().maxCoeff(), 1e-3 * tip);
}

TEST(RunControl, TimedForceExpiresAfterItsDuration) {
  RunControl rc(io::parse_scene(kBeam, "beam", "", {"loads.gravity=[0, 0, 0]"}));
  ASSERT_TRUE(rc.apply("apply_force", R"({"name": "tap", "target": {"point": [0.1, 0.005, 0.005]}, "force": [0, 0, -1e-3], "duration": 0.05})").accepted);
  EXPECT_EQ(rc.forces().count("tap"), 1u);
  run(rc, 5);  // t = 0.05 s
  rc.before_step();
  EXPECT_EQ(rc.forces().count("tap"), 0u);
}

TEST(RunControl, MaterialCommandMergesIntoTheRegionsMaterial) {
  RunControl rc(beam());
  ASSERT_TRUE(rc.apply("set_material", R"({"region": "tissue", "E_L": 120e3})").accepted);
  core::EngineeringConstants c{120e3, 20e3, 0.45, 0.25, 8e3};
  const core::Material expect = core::Material::from_engineering(c, 1000.0);
  const core::Material& got = rc.simulator().model().region_materials[0];
  EXPECT_LT((got.stiffness() - expect.stiffness()).norm(), 1e-9 * expect.stiffness().norm());
  // Switching to the isotropic form drops the engineering keys.
  ASSERT_TRUE(rc.apply("set_material", R"({"E": 50e3, "nu": 0.3})").accepted);
  const core::Material iso = core::Material::isotropic(50e3, 0.3, 1000.0);
  EXPECT_LT((rc.simulator().model().region_materials[0].stiffness() - iso.stiffness()).norm(),
            1e-9 * iso.stiffness().norm());
  EXPECT_EQ(rc.parameter_version(), 2u);
  // Reset with parameters: the scene's material again, at rest, time zero.
  run(rc, 5);
  ASSERT_TRUE(rc.apply("reset", R"({"parameters": true})").accepted);
  const core::Material scene_material = core::Material::from_engineering({60e3, 20e3, 0.45, 0.25, 8e3}, 1000.0);
  EXPECT_LT((rc.simulator().model().region_materials[0].stiffness() - scene_material.stiffness()).norm(),
            1e-9 * scene_material.stiffness().norm());
  EXPECT_EQ(rc.simulator().time_s(), 0.0);
  EXPECT_EQ((rc.simulator().positions() - rc.scene().model.mesh.rest_positions()).cwiseAbs().maxCoeff(), 0.0);
}

TEST(RunControl, PauseStepResumeAndTimeStep) {
  RunControl rc(beam());
  ASSERT_TRUE(rc.apply("pause", "").accepted);
  EXPECT_FALSE(rc.take_step_permission());
  ASSERT_TRUE(rc.apply("step", R"({"count": 2})").accepted);
  EXPECT_TRUE(rc.take_step_permission());
  EXPECT_TRUE(rc.take_step_permission());
  EXPECT_FALSE(rc.take_step_permission());
  ASSERT_TRUE(rc.apply("resume", "{}").accepted);
  EXPECT_TRUE(rc.take_step_permission());
  ASSERT_TRUE(rc.apply("set_time_step", R"({"dt": 0.004})").accepted);
  const double t0 = rc.simulator().time_s();
  rc.simulator().step();
  EXPECT_NEAR(rc.simulator().time_s() - t0, 0.004, 1e-15);
  ASSERT_TRUE(rc.apply("shutdown", "{}").accepted);
  EXPECT_TRUE(rc.shutdown_requested());
}

// checkpoint / restore: the restored run continues bit-for-bit as it did after the
// checkpoint, also when parameters changed in between (the saved ones come back).
TEST(RunControl, RestoreContinuesBitForBitWithTheSavedParameters) {
  RunControl rc(beam());
  run(rc, 10);
  ASSERT_TRUE(rc.apply("apply_force", R"({"name": "p", "target": {"node_set": "xmax"}, "force": [0, 0, 1e-3]})").accepted);
  ASSERT_TRUE(rc.apply("checkpoint", R"({"name": "a"})").accepted);
  const core::Positions after = run(rc, 15);
  ASSERT_TRUE(rc.apply("set_time_step", R"({"dt": 0.004})").accepted);
  ASSERT_TRUE(rc.apply("clear_force", "{}").accepted);
  ASSERT_TRUE(rc.apply("set_material", R"({"E_L": 90e3})").accepted);
  run(rc, 3);
  const CommandResult r = rc.apply("restore", R"({"name": "a"})");
  ASSERT_TRUE(r.accepted) << r.reason;
  EXPECT_EQ(rc.simulator().settings().dt_s, 0.01);
  EXPECT_EQ(rc.forces().count("p"), 1u);
  const core::Positions again = run(rc, 15);
  EXPECT_EQ((again - after).cwiseAbs().maxCoeff(), 0.0);
  const CommandResult missing = rc.apply("restore", R"({"name": "b"})");
  EXPECT_FALSE(missing.accepted);
  EXPECT_NE(missing.reason.find("saved: a"), std::string::npos) << missing.reason;
}

// A heart-rate change keeps the beat under way (no jump in the tension) and the beats
// after it come at the new period.
TEST(RunControl, HeartRateChangeKeepsThePhaseAndSetsTheNewPeriod) {
  io::Scene sc = io::parse_scene(kBeam, "beam", "",
                                 {"loads.gravity=[0, 0, 0]", "solver.dt=0.002",
                                  "contraction={peak_tension: 500, heart_rate: 60, twitch: {shape: sine, systole: 0.3}}"});
  RunControl rc(sc);
  std::vector<double> t, a;
  auto sample = [&](int steps) {
    for (int i = 0; i < steps; ++i) {
      rc.simulator().step();
      t.push_back(rc.simulator().time_s());
      a.push_back(rc.simulator().active_tension()[0]);
    }
  };
  sample(1050);  // t = 2.1 s: 0.1 s into the third beat (beats start at 0, 1, 2 s)
  const double before = a.back();
  ASSERT_TRUE(rc.apply("set_contraction", R"({"heart_rate": 120})").accepted);
  EXPECT_NEAR(rc.heart_rate_bpm(), 120.0, 1e-9);
  sample(1);
  // No jump: the change of tension over this step is that of a step of the sine twitch.
  EXPECT_LT(std::abs(a.back() - before), 500.0 * M_PI / 0.3 * 0.002 * 1.01);
  sample(1500);
  // Beat onsets (tension rising from zero) after the change are 0.5 s apart.
  std::vector<double> onsets;
  for (size_t i = 1; i < a.size(); ++i)
    if (a[i - 1] == 0.0 && a[i] > 0.0 && t[i] > 2.2) onsets.push_back(t[i]);
  ASSERT_GE(onsets.size(), 3u);
  for (size_t k = 1; k < onsets.size(); ++k) EXPECT_NEAR(onsets[k] - onsets[k - 1], 0.5, 0.0021);
  // The first new beat starts one new period after the beat under way began (at 2 s).
  EXPECT_NEAR(onsets[0], 2.5, 0.0021);
}

// The parameter state after parameter commands of every family (its scene text written
// from the running typed values) rebuilds a run that continues bit-for-bit, and writes the
// same state again; a state in the form written before (the scene document with the
// command's keys merged in) still restores.
// The scene text the parameter state carries is kept between commands: each parameter
// command must show in the next state asked for, and a force must not rewrite it.
TEST(RunControl, TheRecordedSceneFollowsEveryParameterCommand) {
  RunControl rc(io::parse_scene(kBeam, "beam", "", {"contraction={peak_tension: 500, heart_rate: 60}"}));
  const auto scene_yaml = [&] { return nlohmann::json::parse(rc.parameter_state_json())["scene_yaml"].get<std::string>(); };
  for (const auto& [kind, args] : std::vector<std::pair<const char*, const char*>>{
           {"set_material", R"({"E_L": 90000})"},
           {"set_damping", R"({"mass": 12.5})"},
           {"set_contraction", R"({"period": 0.7})"},
           {"set_fibers", R"({"uniform": [1, 0.1, 0]})"},
           {"set_gravity", R"({"gravity": [0, -1, -9.81]})"},
           {"set_time_step", R"({"dt": 0.0075})"},
           {"set_solver", R"({"tolerance": 1e-8})"}}) {
    const std::string before = scene_yaml();
    ASSERT_TRUE(rc.apply(kind, args).accepted) << kind;
    EXPECT_NE(scene_yaml(), before) << kind << " does not show in the recorded scene";
  }
  const std::string before = scene_yaml();
  ASSERT_TRUE(rc.apply("apply_force", R"({"name": "p", "target": {"node_set": "xmax"}, "force": [0, 0, 1e-3]})").accepted);
  EXPECT_EQ(scene_yaml(), before);
  EXPECT_EQ(nlohmann::json::parse(rc.parameter_state_json())["forces"].size(), 1u);
  ASSERT_TRUE(rc.apply("reset", R"({"parameters": true})").accepted);
  EXPECT_EQ(rc.running_scene().model.loads.gravity_m_s2, beam().model.loads.gravity_m_s2) << "reset's scene";
}

TEST(RunControl, ParameterStateAfterCommandsResumesBitForBit) {
  RunControl rc(io::parse_scene(kBeam, "beam", "", {"contraction={peak_tension: 500, heart_rate: 60}"}));
  run(rc, 5);
  for (const auto& [kind, args] : std::vector<std::pair<const char*, const char*>>{
           {"set_material", R"({"E_L": 90000.33333333333, "nu_T": 0.4})"},
           {"set_damping", R"({"mass": 12.5})"},
           {"set_contraction", R"({"period": 0.7, "twitch": {"tau1": 0.04}, "pacing": {"at": [0, 0, 0], "speed": 0.5}})"},
           {"set_fibers", R"({"uniform": [1, 0.1, 0]})"},
           {"set_gravity", R"({"gravity": [0, -1, -9.81]})"},
           {"set_time_step", R"({"dt": 0.0075})"},
           {"set_solver", R"({"tolerance": 1e-8, "rotation": "svd", "max_iterations": 300})"}}) {
    const CommandResult r = rc.apply(kind, args);
    ASSERT_TRUE(r.accepted) << kind << ": " << r.reason;
  }
  ASSERT_TRUE(rc.apply("apply_force", R"({"name": "p", "target": {"node_set": "xmax"}, "force": [0, 0, 1e-3]})").accepted);
  run(rc, 5);
  const std::string state = rc.parameter_state_json();
  const core::SimulatorCheckpoint saved = rc.simulator().checkpoint();
  const core::Positions a = run(rc, 20);

  RunControl resumed(beam());
  resumed.restore_parameter_state(state);
  resumed.simulator().restore(saved);
  EXPECT_EQ(resumed.simulator().settings().dt_s, 0.0075);
  const core::Positions b = run(resumed, 20);
  EXPECT_EQ((a - b).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(resumed.parameter_state_json(), state);
  EXPECT_EQ(rc.running_scene().model.region_materials[0].stiffness(), rc.simulator().model().region_materials[0].stiffness());

  RunControl earlier(beam());
  std::string doc = kBeam;
  doc.replace(doc.find("E_L: 60.0e3"), 11, "E_L: 120000");
  earlier.restore_parameter_state(nlohmann::json{{"scene_yaml", doc}, {"forces", nlohmann::json::array()}}.dump());
  RunControl commanded(beam());
  ASSERT_TRUE(commanded.apply("set_material", R"({"E_L": 120e3})").accepted);
  EXPECT_EQ(earlier.simulator().model().region_materials[0].stiffness(),
            commanded.simulator().model().region_materials[0].stiffness());
}


io::Scene accurate_beam(std::vector<std::string> overrides = {}) {
  return io::parse_scene(testing::kAccurateBeamScene, "accurate-beam", "", overrides);
}

// Steps through the run's engine (either tier); @return the corner positions.
core::Positions step_engine(RunControl& rc, int steps) {
  for (int i = 0; i < steps; ++i) {
    rc.before_step();
    const core::StepReport r = rc.engine().step();
    EXPECT_NE(r.status, core::StepStatus::failed) << r.message;
  }
  return rc.engine().positions();
}

// The accurate tier's own time stepper, driven directly as `fiberfem run` drives it (the
// loads at each step's end): the reference the service's engine must equal.
core::Positions direct_run(const io::Scene& sc, int steps) {
  const io::AccurateProblem ap = io::accurate_problem(sc);
  core::hyperelastic::DynamicSolver solver(*ap.problem, io::accurate_dynamic_settings(sc, ap));
  std::vector<double> tension;
  for (int s = 1; s <= steps; ++s) EXPECT_TRUE(solver.step(io::accurate_loading(sc, s * sc.settings.dt_s, tension)).converged);
  return solver.positions().leftCols(ap.mesh->num_corner_nodes());
}

TEST(RunControl, AnAccurateSceneStepsOnTheAccurateTier) {
  const io::Scene sc = accurate_beam();
  ASSERT_TRUE(sc.accurate());
  RunControl rc(sc);
  ASSERT_NE(rc.engine().accurate(), nullptr);
  EXPECT_EQ(rc.engine().real_time(), nullptr);
  EXPECT_THROW(rc.simulator(), std::logic_error);
  const core::Positions x = step_engine(rc, 12);
  EXPECT_EQ(x.cols(), sc.model.mesh.num_nodes());  // the corner mesh the topology names
  const core::Positions ref = direct_run(sc, 12);
  const double tip = (ref - sc.model.mesh.rest_positions()).cwiseAbs().maxCoeff();
  EXPECT_GT(tip, 1e-4);  // the beam bends (a tenth of a millimetre and more)
  EXPECT_LT((x - ref).cwiseAbs().maxCoeff(), 1e-9 * tip);
  EXPECT_NEAR(rc.engine().time_s(), 0.12, 1e-12);
  EXPECT_EQ(rc.engine().step_count(), 12);
}

// A law constant changed by command before the first step gives the same run, bit for
// bit, as a scene that has it; changed mid-run it changes the answer from then on.
TEST(RunControl, ALiveLawCommandChangesTheAnswerAsTheSceneKeyDoes) {
  RunControl live(accurate_beam());
  const CommandResult r = live.apply("set_material", R"({"C": 4000})");  // the law's own key; law kept
  ASSERT_TRUE(r.accepted) << r.reason;
  RunControl fresh(accurate_beam({"regions[0].material.C=4000"}));
  RunControl unchanged(accurate_beam());
  const core::Positions a = step_engine(live, 8), b = step_engine(fresh, 8), c = step_engine(unchanged, 8);
  EXPECT_EQ((a - b).cwiseAbs().maxCoeff(), 0.0);
  const double du = (c - accurate_beam().model.mesh.rest_positions()).cwiseAbs().maxCoeff();
  EXPECT_GT((a - c).cwiseAbs().maxCoeff(), 0.1 * du);  // twice as stiff: clearly less bent
  // The running scene carries the new constant (what a recording's header and checkpoints hold).
  EXPECT_NE(live.running_scene().yaml_text.find("4000"), std::string::npos);
  // Bad law arguments are refused by name and change nothing.
  const unsigned v = live.parameter_version();
  const CommandResult bad = live.apply("set_material", R"({"b_f": -1})");
  EXPECT_FALSE(bad.accepted);
  EXPECT_NE(bad.reason.find("b_f"), std::string::npos) << bad.reason;
  const CommandResult stiff = live.apply("set_damping", R"({"stiffness": 0.01})");
  EXPECT_FALSE(stiff.accepted);
  EXPECT_NE(stiff.reason.find("mass damping only"), std::string::npos) << stiff.reason;
  const CommandResult solver = live.apply("set_solver", R"({"tolerance": 1e-8})");
  EXPECT_FALSE(solver.accepted);
  EXPECT_NE(solver.reason.find("accurate tier"), std::string::npos) << solver.reason;
  EXPECT_EQ(live.parameter_version(), v);
  EXPECT_EQ((step_engine(live, 3) - step_engine(fresh, 3)).cwiseAbs().maxCoeff(), 0.0);
}

// Checkpoint, go on with other parameters, restore: the run continues exactly as the one
// that never left the checkpoint (positions, velocities, pressures, time, step count and
// the lagged factor all restored, the law constants of the checkpoint rebuilt).
TEST(RunControl, AnAccurateRunRestoresBitForBit) {
  RunControl rc(accurate_beam());
  step_engine(rc, 4);
  ASSERT_TRUE(rc.apply("set_material", R"({"C": 3000})").accepted);
  step_engine(rc, 2);
  ASSERT_TRUE(rc.apply("checkpoint", R"({"name": "a"})").accepted);
  const core::Positions x_on = step_engine(rc, 5);
  const core::Positions v_on = rc.engine().velocities();
  const Eigen::VectorXd p_on = rc.engine().accurate()->pressures();
  ASSERT_TRUE(rc.apply("set_material", R"({"C": 1500})").accepted);
  step_engine(rc, 3);
  const CommandResult back = rc.apply("restore", R"({"name": "a"})");
  ASSERT_TRUE(back.accepted) << back.reason;
  EXPECT_EQ(rc.engine().step_count(), 6);
  const core::Positions x_back = step_engine(rc, 5);
  EXPECT_EQ((x_back - x_on).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((core::Positions(rc.engine().velocities()) - v_on).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((rc.engine().accurate()->pressures() - p_on).cwiseAbs().maxCoeff(), 0.0);
  // A run resumed in another RunControl from the parameter state and checkpoint alike.
  RunControl other(accurate_beam());
  ASSERT_TRUE(rc.apply("restore", R"({"name": "a"})").accepted);
  other.restore_parameter_state(rc.parameter_state_json());
  other.engine().restore(rc.engine().checkpoint());
  EXPECT_EQ((step_engine(other, 5) - x_on).cwiseAbs().maxCoeff(), 0.0);
}

// apply_force on the accurate tier: a nodal load on the corner nodes it names.
TEST(RunControl, AForceCommandLoadsTheAccurateTier) {
  RunControl pushed(accurate_beam({"loads.tractions=[]"}));
  ASSERT_TRUE(pushed.apply("apply_force", R"({"name": "up", "target": {"node_set": "xmax"}, "force": [0, 0, 1e-4]})").accepted);
  const core::Positions x = step_engine(pushed, 10);
  const io::Scene sc = accurate_beam();
  const auto& xmax = sc.model.mesh.node_set("xmax");
  for (int n : xmax) EXPECT_GT(x(2, n) - sc.model.mesh.rest_positions()(2, n), 1e-5) << "node " << n;
  ASSERT_TRUE(pushed.apply("clear_force", R"({"name": "up"})").accepted);
  const CommandResult bad = pushed.apply("apply_force", R"({"target": {"node": 100000}, "force": [0, 0, 1]})");
  EXPECT_FALSE(bad.accepted);
  EXPECT_NE(bad.reason.find("target.node"), std::string::npos) << bad.reason;
}


// set_contraction drives the accurate tier's active tension: given at rest, the run of a
// scene with that contraction, bit for bit; the published activation follows the twitch.
TEST(RunControl, AContractionCommandDrivesTheAccurateTiersActiveTension) {
  const std::vector<std::string> gentle = {"loads.tractions=[]",
                                           "contraction={peak_tension: 200, heart_rate: 60, twitch: {shape: sine, systole: 0.3}}"};
  RunControl live(accurate_beam(gentle));
  const CommandResult r = live.apply("set_contraction", R"({"peak_tension": 400})");
  ASSERT_TRUE(r.accepted) << r.reason;
  std::vector<std::string> stronger = gentle;
  stronger[1] = "contraction={peak_tension: 400, heart_rate: 60, twitch: {shape: sine, systole: 0.3}}";
  RunControl fresh(accurate_beam(stronger));
  RunControl unchanged(accurate_beam(gentle));
  const core::Positions a = step_engine(live, 10), b = step_engine(fresh, 10), c = step_engine(unchanged, 10);
  EXPECT_EQ((a - b).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_GT((a - c).cwiseAbs().maxCoeff(), 1e-6);  // twice the tension: a different shape
  ASSERT_EQ(live.engine().active_tension().size(), static_cast<size_t>(live.engine().model().mesh.num_elements()));
  EXPECT_GT(live.engine().active_tension()[0], 0.0);  // 0.1 s into the beat's rise
  EXPECT_LE(live.engine().active_tension()[0], 400.0);
  EXPECT_DOUBLE_EQ(live.peak_tension_pa(), 400.0);
}

// A heart rate steered on the accurate tier keeps the beat under way in phase, as on the
// real-time tier: the sine twitch (systole 0.3 s) 0.1 s into the second beat at 60/min
// reads peak sin^2(pi/3) before and after a change to 80/min (without the rule, t mod the
// new period 0.75 s would put it past systole, at 0), reaches the peak 0.05 s later, and
// the next beat starts one new period after the current one began (1 + 0.75 s). A run
// resumed from the parameter state and a checkpoint continues it bit for bit.
TEST(RunControl, AnAccurateHeartRateChangeKeepsThePhase) {
  const std::vector<std::string> sine = {"loads.tractions=[]", "solver.dt=0.05",
                                         "contraction={peak_tension: 200, heart_rate: 60, twitch: {shape: sine, systole: 0.3}}"};
  RunControl rc(accurate_beam(sine));
  step_engine(rc, 22);  // t = 1.1 s
  const double peak = 200.0, before = rc.engine().active_tension()[0];
  EXPECT_NEAR(before, peak * std::pow(std::sin(M_PI * 0.1 / 0.3), 2), 1e-9);
  ASSERT_TRUE(rc.apply("set_contraction", R"({"heart_rate": 80})").accepted);
  EXPECT_NEAR(rc.engine().active_tension()[0], before, 1e-9) << "the rate change jumped the twitch";
  step_engine(rc, 1);  // t = 1.15 s: the sine's peak
  EXPECT_NEAR(rc.engine().active_tension()[0], peak, 1e-9);
  ASSERT_TRUE(rc.apply("checkpoint", R"({"name": "steered"})").accepted);
  step_engine(rc, 10);  // t = 1.65 s: past systole, before the next beat
  EXPECT_EQ(rc.engine().active_tension()[0], 0.0);
  step_engine(rc, 2);  // t = 1.75 s: the next beat starts (sin^2 0)
  EXPECT_NEAR(rc.engine().active_tension()[0], 0.0, 1e-9);
  const core::Positions x_on = step_engine(rc, 1);  // t = 1.8 s: 0.05 s into it
  EXPECT_NEAR(rc.engine().active_tension()[0], peak * std::pow(std::sin(M_PI * 0.05 / 0.3), 2), 1e-9);
  const std::vector<double> tension_on = rc.engine().active_tension();
  RunControl other(accurate_beam(sine));
  ASSERT_TRUE(rc.apply("restore", R"({"name": "steered"})").accepted);
  other.restore_parameter_state(rc.parameter_state_json());
  other.engine().restore(rc.engine().checkpoint());
  EXPECT_EQ((step_engine(other, 13) - x_on).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(other.engine().active_tension(), tension_on);
}

}  // namespace
}  // namespace fiberfem::service
