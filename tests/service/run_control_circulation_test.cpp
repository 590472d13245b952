// set_circulation against a running scene (service/run_control_circulation.cpp), without
// DDS: bad values refused with the key named and nothing changed; accepted ones change the
// loop from the next step, keep its state, raise the aortic pressure as a higher systemic
// resistance must, set one heart rate for loop and contraction, and are written into the
// parameter state so that a resumed run continues with them.

#include "service/run_control.hpp"

#include "io/scene.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <sstream>

namespace fiberfem::service {
namespace {

namespace cc = core::circulation;

// A small contracting left ventricle coupled to the loop (scaled to it); the loop beats
// with the contraction (no circulation.heart_rate).
const std::string kVentricleFile = std::string(FIBERFEM_SOURCE_DIR) + "/tests/scenes/lv-circulation.yaml";

std::string ventricle_text() {
  std::ifstream f(kVentricleFile);
  std::stringstream text;
  text << f.rdbuf();
  return text.str();
}

io::Scene ventricle() { return io::load_scene(kVentricleFile); }

void run(RunControl& rc, int steps) {
  for (int i = 0; i < steps; ++i) {
    rc.before_step();
    ASSERT_NE(rc.engine().step().status, core::StepStatus::failed);
  }
}

double aortic_pa(const RunControl& rc) { return rc.engine().circulation_state()->pressure_pa[cc::ar_sys]; }

TEST(RunControlCirculation, BadValuesAreRefusedNamingTheKeyAndChangeNothing) {
  struct Bad {
    const char* args;
    const char* reason_has;
  };
  const Bad bad[] = {
      {R"({"systemic": {"arteries": {"compliance": -1.2}}})", "'systemic.arteries.compliance'"},
      {R"({"pulmonary": {"veins": {"resistance": 0}}})", "'pulmonary.veins.resistance'"},
      {R"({"valves": {"aortic": {"R_min": 1e9}}})", "never opens"},
      {R"({"heart_rate": 0})", "'heart_rate'"},
      {R"({"heart_rate": "fast"})", "'heart_rate' must be a number"},
      {R"({"chambers": {"left_atrium": {"onset": [1, 2]}}})", "'chambers.left_atrium.onset' must be a number"},
      {R"({"chambers": {"left_atrium": {"stiffness": 1}}})", "unknown argument 'stiffness'"},
      {R"({"chambers": {"left_ventricle": {"active_elastance": 1}}})", "'chambers.left_ventricle.active_elastance': this ventricle is the mesh's cavity 'lv'"},
      {R"({"scale": {"pressure": 2}})", "unknown argument 'scale'"},
      {R"({"systemic": {"arteries": {"resistance": .nan}}})", "'systemic.arteries.resistance'"},
      {R"({})", "give the keys to change"},
  };
  RunControl rc(ventricle()), untouched(ventricle());
  run(rc, 10);
  run(untouched, 10);
  const std::string state = rc.parameter_state_json();
  for (const Bad& b : bad) {
    const CommandResult r = rc.apply("set_circulation", b.args);
    EXPECT_FALSE(r.accepted) << b.args;
    EXPECT_NE(r.reason.find(b.reason_has), std::string::npos) << b.args << ": " << r.reason;
  }
  EXPECT_EQ(rc.parameter_version(), 0u);
  EXPECT_EQ(rc.parameter_state_json(), state);
  run(rc, 20);
  run(untouched, 20);
  EXPECT_EQ(aortic_pa(rc), aortic_pa(untouched));
  EXPECT_EQ((rc.engine().positions() - untouched.engine().positions()).cwiseAbs().maxCoeff(), 0.0);

  // A run without a circulation refuses the command by name.
  std::string plain = ventricle_text();
  plain.erase(plain.find("circulation:"), plain.find("solver:") - plain.find("circulation:"));
  RunControl none(io::parse_scene(plain, "plain"));
  const CommandResult r = none.apply("set_circulation", R"({"heart_rate": 90})");
  EXPECT_FALSE(r.accepted);
  EXPECT_NE(r.reason.find("no circulation"), std::string::npos) << r.reason;
}

// Values are the scene's (mmHg s/mL, before scale): a command gives exactly the loop a scene
// with that key gives. A higher systemic resistance raises the aortic pressure from the next
// beat on, the state carrying over; the parameter state resumes the steered run bit for bit.
TEST(RunControlCirculation, SteeredKeysActLikeSceneKeysAndResumeWithTheRun) {
  RunControl rc(ventricle()), plain(ventricle());
  run(rc, 30);
  run(plain, 30);
  const cc::State before = *rc.engine().circulation_state();
  const CommandResult ok = rc.apply("set_circulation", R"({"systemic": {"arteries": {"resistance": 2.4}}})");
  ASSERT_TRUE(ok.accepted) << ok.reason;
  EXPECT_EQ(rc.parameter_version(), 1u);
  EXPECT_TRUE(rc.engine().circulation_state()->pressure_pa == before.pressure_pa);
  const io::Scene with_key = io::load_scene(kVentricleFile, {"circulation.systemic.arteries.resistance=2.4"});
  EXPECT_EQ(rc.engine().model().circulation.parameters.compartments[cc::ar_sys].resistance_pa_s_m3,
            with_key.model.circulation.parameters.compartments[cc::ar_sys].resistance_pa_s_m3);
  run(rc, 5);
  run(plain, 5);
  const std::string state = rc.parameter_state_json();
  const auto saved = rc.engine().checkpoint();
  double steered_mean = 0, plain_mean = 0;
  for (int i = 0; i < 48; ++i) {  // a beat
    run(rc, 1);
    run(plain, 1);
    steered_mean += aortic_pa(rc) / 48;
    plain_mean += aortic_pa(plain) / 48;
  }
  EXPECT_GT(steered_mean, 1.1 * plain_mean) << steered_mean << " vs " << plain_mean;
  const YAML::Node written = YAML::Load(nlohmann::json::parse(state)["scene_yaml"].get<std::string>());
  EXPECT_EQ(written["circulation"]["systemic"]["arteries"]["resistance"].as<double>(), 2.4);

  RunControl resumed(ventricle());
  resumed.restore_parameter_state(state);
  resumed.engine().restore(saved);
  run(resumed, 48);
  EXPECT_EQ(aortic_pa(resumed), aortic_pa(rc));
  EXPECT_EQ((resumed.engine().positions() - rc.engine().positions()).cwiseAbs().maxCoeff(), 0.0);
}

// heart_rate is the heart's: loop and contraction both take it (the status shows it), and
// set_contraction's rate moves a loop that beats with the contraction.
TEST(RunControlCirculation, OneHeartRateForLoopAndContraction) {
  RunControl rc(ventricle());
  run(rc, 20);
  const CommandResult rate = rc.apply("set_circulation", R"({"heart_rate": 100})");
  ASSERT_TRUE(rate.accepted) << rate.reason;
  EXPECT_DOUBLE_EQ(rc.heart_rate_bpm(), 100);
  EXPECT_DOUBLE_EQ(rc.engine().model().circulation.parameters.period_s, 60.0 / 100);
  // A rate the contraction's twitch cannot beat at (it would not decay between beats) is
  // refused whole: neither the loop nor the contraction changes.
  const CommandResult fast = rc.apply("set_circulation", R"({"heart_rate": 140})");
  EXPECT_FALSE(fast.accepted);
  EXPECT_NE(fast.reason.find("twitch"), std::string::npos) << fast.reason;
  EXPECT_DOUBLE_EQ(rc.engine().model().circulation.parameters.period_s, 60.0 / 100);
  EXPECT_DOUBLE_EQ(rc.heart_rate_bpm(), 100);
  run(rc, 20);
  RunControl follows(ventricle());
  run(follows, 20);
  ASSERT_TRUE(follows.apply("set_contraction", R"({"heart_rate": 90})").accepted);
  EXPECT_DOUBLE_EQ(follows.engine().model().circulation.parameters.period_s, 60.0 / 90);
  // The written scene reads back to the same loop.
  RunControl resumed(ventricle());
  resumed.restore_parameter_state(follows.parameter_state_json());
  EXPECT_EQ(resumed.engine().model().circulation.parameters.period_s, follows.engine().model().circulation.parameters.period_s);
  resumed.restore_parameter_state(rc.parameter_state_json());
  EXPECT_EQ(resumed.engine().model().circulation.parameters.period_s, rc.engine().model().circulation.parameters.period_s);
  EXPECT_DOUBLE_EQ(resumed.heart_rate_bpm(), 100);
}

}  // namespace
}  // namespace fiberfem::service

namespace fiberfem::service {
namespace {

// The accurate tier steers its circulation by rebuilding its engine from the running scene
// (which reads the steered keys): the loop's state carries over unchanged, the new
// resistance is the loop's from then on and raises the aortic pressure against an
// unsteered run; a bad value is refused and changes nothing.
TEST(RunControlCirculation, TheAccurateTierSteersItsLoopKeepingItsState) {
  std::string text = ventricle_text();
  const std::string linear = "material: {E_L: 60.0e3, E_T: 20.0e3, nu_LT: 0.4, nu_T: 0.45, G_L: 8.0e3, density: 1060.0}";
  ASSERT_NE(text.find(linear), std::string::npos);
  text.replace(text.find(linear), linear.size(), "material: {law: neo_hookean, E: 40000.0, nu: 0.3, density: 1060.0}");
  text.replace(text.find("pressure: 0.1,"), 14, "pressure: 0.00125,");
  RunControl steered(io::parse_scene(text, "accurate-ventricle")), plain(io::parse_scene(text, "accurate-ventricle"));
  ASSERT_NE(steered.engine().accurate(), nullptr);
  ASSERT_TRUE(steered.engine().model().circulation.enabled());
  run(steered, 10);
  run(plain, 10);
  const cc::State before = *steered.engine().circulation_state();
  const double r0 = steered.engine().model().circulation.parameters.compartments[cc::ar_sys].resistance_pa_s_m3;
  const std::string state = steered.parameter_state_json();
  const CommandResult bad = steered.apply("set_circulation", R"({"systemic": {"arteries": {"compliance": -1.2}}})");
  EXPECT_FALSE(bad.accepted);
  EXPECT_NE(bad.reason.find("'systemic.arteries.compliance'"), std::string::npos) << bad.reason;
  EXPECT_EQ(steered.parameter_state_json(), state);
  const CommandResult r = steered.apply("set_circulation", R"({"systemic": {"arteries": {"resistance": 2.4}}})");
  ASSERT_TRUE(r.accepted) << r.reason;
  const cc::State& after = *steered.engine().circulation_state();
  EXPECT_EQ(after.volume_m3, before.volume_m3);
  EXPECT_EQ(after.pressure_pa, before.pressure_pa);
  EXPECT_EQ(after.flow_m3_s, before.flow_m3_s);
  EXPECT_NEAR(steered.engine().model().circulation.parameters.compartments[cc::ar_sys].resistance_pa_s_m3 / r0, 3.0, 1e-12);
  EXPECT_EQ(steered.engine().step_count(), 10);
  run(steered, 40);
  run(plain, 40);
  EXPECT_GT(aortic_pa(steered), 1.2 * aortic_pa(plain));
}

}  // namespace
}  // namespace fiberfem::service
