// The `circulation` scene key (io/scene_circulation.cpp, docs/circulation.md): what it
// builds, its units and defaults, and the errors that name the bad key.
#include "core/circulation/circulation.hpp"
#include "core/simulator.hpp"
#include "io/scene.hpp"

#include <gtest/gtest.h>

#include <string>

namespace sc = fiberfem::io;
namespace cc = fiberfem::core::circulation;

namespace {

const std::string kBase = R"(name: lv-circ
mesh:
  generator: lv_ellipsoid
  resolution: {circumferential: 12, longitudinal: 6, transmural: 2}
regions:
  - name: myocardium
    select: all
    material: {E: 60.0e3, nu: 0.45, density: 1060}
fibers:
  rule: {endo_angle: 60, epi_angle: -60}
fixed:
  - node_set: base
contraction:
  peak_tension: 20.0e3
  heart_rate: 75
measure:
  cavities:
    lv: {node_set: endo}
)";

const std::string kCirculation = R"(circulation:
  ventricles: {left: lv}
  scale: {pressure: 0.1, volume: 0.02}
  systemic:
    arteries: {resistance: 0.8, compliance: 1.2, inertance: 0.005}
  valves:
    aortic: {R_min: 0.0075, R_max: 75006.2}
)";

std::string replace_once(std::string s, const std::string& from, const std::string& to) {
  const size_t at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) s.replace(at, from.size(), to);
  return s;
}

void expect_error(const std::string& yaml, std::initializer_list<std::string> fragments) {
  try {
    sc::parse_scene(yaml, "circ.yaml");
    ADD_FAILURE() << "expected a SceneError mentioning " << *fragments.begin();
  } catch (const sc::SceneError& e) {
    const std::string msg = e.what();
    for (const auto& f : fragments) EXPECT_NE(msg.find(f), std::string::npos) << "'" << msg << "' lacks '" << f << "'";
  }
}

}  // namespace

TEST(SceneCirculation, WithoutTheKeyThereIsNoCirculation) {
  const sc::Scene s = sc::parse_scene(kBase, "circ.yaml");
  EXPECT_FALSE(s.model.circulation.enabled());
}

TEST(SceneCirculation, BuildsTheScaledLoopInSiUnits) {
  const sc::Scene s = sc::parse_scene(kBase + kCirculation, "circ.yaml");
  const cc::Coupling& c = s.model.circulation;
  ASSERT_TRUE(c.enabled());
  ASSERT_EQ(c.cavities.size(), 1u);
  EXPECT_EQ(c.cavities[0].chamber, cc::lv);
  EXPECT_EQ(c.cavities[0].name, "lv");
  EXPECT_EQ(c.parameters.chambers[cc::lv].kind, cc::ChamberKind::external);
  EXPECT_EQ(c.parameters.chambers[cc::rv].kind, cc::ChamberKind::elastance);  // the lumped right ventricle
  EXPECT_NEAR(c.parameters.period_s, 0.8, 1e-12);                              // the contraction's 75 beats/min
  // 1.2 mL/mmHg, scaled by volume/pressure = 0.2, in m^3/Pa.
  EXPECT_NEAR(c.parameters.compartments[cc::ar_sys].compliance_m3_pa, 1.2e-6 / 133.322387415 * 0.2, 1e-18);
  // 0.8 mmHg s/mL scaled by 5.
  EXPECT_NEAR(c.parameters.compartments[cc::ar_sys].resistance_pa_s_m3, 0.8 * 133.322387415e6 * 5, 1e-3);
  // Initial state: the paper's, scaled (80 mmHg x 0.1).
  EXPECT_NEAR(c.initial.pressure_pa[cc::ar_sys], 8 * 133.322387415, 1e-9);
  // And it runs.
  fiberfem::core::Simulator sim(s.model, s.settings);
  for (int i = 0; i < 5; ++i) EXPECT_NE(sim.step().status, fiberfem::core::StepStatus::failed);
  EXPECT_GT(sim.circulation_state().time_s, 0.08);
}

TEST(SceneCirculation, BadInputNamesTheKey) {
  const std::string good = kBase + kCirculation;
  expect_error(replace_once(good, "compliance: 1.2", "compliance: -1.2"),
               {"circ.yaml:", "circulation.systemic.arteries.compliance"});
  expect_error(replace_once(good, "{left: lv}", "{left: lvv}"), {"circulation.ventricles.left", "not a measured cavity", "lv"});
  expect_error(replace_once(good, "R_min: 0.0075", "R_min: 80000"), {"circulation.valves.aortic", "never opens"});
  expect_error(replace_once(good, "fixed:\n  - node_set: base\n", ""), {"circulation.ventricles.left", "not closed", "fix its base"});
  expect_error(replace_once(good, "  ventricles: {left: lv}\n", ""), {"circulation", "needs ventricles"});
  expect_error(replace_once(good, "scale: {pressure: 0.1", "scale: {pressure: 0"), {"circulation.scale.pressure"});
  expect_error(replace_once(good, "  systemic:", "  systemic_typo: 1\n  systemic:"), {"circulation.systemic_typo", "unknown key"});
}

// A scene on the accurate tier takes the key too, with the looser default volume tolerance
// its Newton solves allow (an explicit one is kept).
TEST(SceneCirculation, TheAccurateTierTakesItWithItsOwnDefaultTolerance) {
  const std::string accurate = replace_once(kBase + kCirculation, "material: {E:", "material: {law: neo_hookean, E:");
  const sc::Scene s = sc::parse_scene(accurate, "circ.yaml");
  ASSERT_TRUE(s.accurate());
  ASSERT_TRUE(s.model.circulation.enabled());
  EXPECT_EQ(s.model.circulation.volume_tolerance, 1e-6);
  EXPECT_EQ(sc::parse_scene(kBase + kCirculation, "circ.yaml").model.circulation.volume_tolerance, 1e-9);
  const sc::Scene told = sc::parse_scene(replace_once(accurate, "ventricles: {left: lv}", "ventricles: {left: lv}\n  volume_tolerance: 1e-7"), "circ.yaml");
  EXPECT_EQ(told.model.circulation.volume_tolerance, 1e-7);
}
