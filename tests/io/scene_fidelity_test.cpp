// The `fidelity` scene key (docs/scenes.md): each preset's step, mesh refinement and PCG
// tolerance; explicit keys override the preset; a bad value names the key and the allowed
// values. And the scene warnings (Scene::warnings) for settings beyond the stability map.

#include "core/amg_preconditioner.hpp"
#include "io/scene.hpp"
#include "test_support.hpp"

#include <string>

namespace io = fiberfem::io;

namespace {

const std::string kBox = R"(
name: box
mesh:
  generator: box
  size: [0.1, 0.01, 0.01]
  cells: [20, 2, 2]
regions:
  - material: {E: 1.0e5, nu: 0.3, density: 1000.0}
fixed:
  - plane: {axis: x, value: 0.0}
solver: {mode: dynamic}
)";

const std::string kLv = R"(
name: lv
mesh:
  generator: lv_ellipsoid
  resolution: {circumferential: 24, longitudinal: 10, transmural: 2}
regions:
  - material: {E: 1.0e5, nu: 0.3, density: 1000.0}
fixed:
  - node_set: base
)";

std::string expect_error(const std::string& yaml, const std::vector<std::string>& overrides = {}) {
  try {
    io::parse_scene(yaml, "test.yaml", "", overrides);
  } catch (const io::SceneError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no error";
  return "";
}

}  // namespace

TEST(SceneFidelity, NoPresetKeepsTheEngineDefaults) {
  const io::Scene s = io::parse_scene(kBox, "test.yaml");
  const fiberfem::core::SimulatorSettings d;
  EXPECT_EQ(s.settings.dt_s, d.dt_s);
  EXPECT_EQ(s.settings.solver.tolerance, d.solver.tolerance);
  EXPECT_EQ(s.model.mesh.num_elements(), 20 * 2 * 2 * 6);
  EXPECT_TRUE(s.warnings.empty());
}

TEST(SceneFidelity, EachPresetSetsStepRefinementToleranceAndRefresh) {
  struct Expect {
    const char* name;
    double dt, tol;
    int cells[3];
    int refresh_iterations;
    double refresh_budget;
  };
  // Box cells [20, 2, 2] times the refinement (0.5, 1, 1.5), rounded, at least 1.
  // interactive also refreshes its factor by the budget rule (SolverSettings::refresh_budget).
  const fiberfem::core::SolverSettings defaults;
  for (const Expect& e : {Expect{"interactive", 1.0 / 30, 1e-3, {10, 1, 1}, 32, 1.0},
                          Expect{"balanced", 1.0 / 60, 1e-6, {20, 2, 2}, defaults.refresh_iterations, defaults.refresh_budget},
                          Expect{"accurate", 1.0 / 120, 1e-6, {30, 3, 3}, defaults.refresh_iterations, defaults.refresh_budget}}) {
    const io::Scene s = io::parse_scene(kBox + "fidelity: " + e.name + "\n", "test.yaml");
    EXPECT_DOUBLE_EQ(s.settings.dt_s, e.dt) << e.name;
    EXPECT_DOUBLE_EQ(s.settings.solver.tolerance, e.tol) << e.name;
    EXPECT_EQ(s.model.mesh.num_elements(), e.cells[0] * e.cells[1] * e.cells[2] * 6) << e.name;
    EXPECT_EQ(s.settings.solver.refresh_iterations, e.refresh_iterations) << e.name;
    EXPECT_DOUBLE_EQ(s.settings.solver.refresh_budget, e.refresh_budget) << e.name;
    // Everything else stays the engine's default.
    EXPECT_EQ(s.settings.solver.method, fiberfem::core::LinearSolverKind::pcg) << e.name;
    EXPECT_EQ(s.settings.rotation, fiberfem::core::RotationMethod::polar) << e.name;
  }
  // The ellipsoid generator's resolution is refined too: interactive halves 24/10/2.
  const io::Scene coarse = io::parse_scene(kLv + "fidelity: interactive\n", "test.yaml");
  const io::Scene plain = io::parse_scene(kLv, "test.yaml");
  const io::Scene fine = io::parse_scene(kLv + "fidelity: accurate\n", "test.yaml");
  EXPECT_LT(coarse.model.mesh.num_elements(), plain.model.mesh.num_elements() / 4);
  EXPECT_GT(fine.model.mesh.num_elements(), 2 * plain.model.mesh.num_elements());
}

TEST(SceneFidelity, ExplicitKeysOverrideThePreset) {
  const io::Scene s = io::parse_scene(kBox, "test.yaml", "", {"fidelity=interactive", "solver.dt=0.005", "solver.tolerance=1.0e-9"});
  EXPECT_DOUBLE_EQ(s.settings.dt_s, 0.005);
  EXPECT_DOUBLE_EQ(s.settings.solver.tolerance, 1e-9);
  EXPECT_EQ(s.model.mesh.num_elements(), 10 * 1 * 1 * 6);  // the mesh part of the preset still applies
  // mesh.refine overrides the preset's refinement; --set overrides both.
  const io::Scene r = io::parse_scene(kBox + "fidelity: interactive\n", "test.yaml", "", {"mesh.refine=2", "solver.dt=0.01"});
  EXPECT_EQ(r.model.mesh.num_elements(), 40 * 4 * 4 * 6);
  EXPECT_DOUBLE_EQ(r.settings.dt_s, 0.01);
  EXPECT_DOUBLE_EQ(r.settings.solver.tolerance, 1e-3);
}

TEST(SceneFidelity, BadValuesNameTheKeyAndTheAllowedValues) {
  const std::string e = expect_error(kBox + "fidelity: ultra\n");
  EXPECT_NE(e.find("fidelity"), std::string::npos) << e;
  EXPECT_NE(e.find("'ultra'"), std::string::npos) << e;
  for (const char* name : {"interactive", "balanced", "accurate"}) EXPECT_NE(e.find(name), std::string::npos) << e;
  const std::string r = expect_error(kBox, {"mesh.refine=0"});
  EXPECT_NE(r.find("mesh.refine"), std::string::npos) << r;
  const std::string f = expect_error("name: f\nmesh: {file: x.msh, refine: 2}\nregions: [{material: {E: 1.0, nu: 0.3, density: 1.0}}]\n");
  EXPECT_NE(f.find("mesh.refine"), std::string::npos) << f;
  EXPECT_NE(f.find("generator"), std::string::npos) << f;
}

TEST(SceneFidelity, CorotationKey) {
  EXPECT_TRUE(io::parse_scene(kBox, "test.yaml").settings.corotation);
  EXPECT_FALSE(io::parse_scene(kBox, "test.yaml", "", {"solver.corotation=false"}).settings.corotation);
  const std::string e = expect_error(kBox, {"solver.corotation=maybe"});
  EXPECT_NE(e.find("solver.corotation"), std::string::npos) << e;
}

TEST(SceneFidelity, WarnsBeyondTheStabilityMap) {
  const std::string aniso = R"(
name: a
mesh: {generator: box, size: [0.1, 0.02, 0.02], cells: [4, 1, 1]}
regions:
  - material: {E_L: 60.0e3, E_T: 6.0, nu_LT: 0.25, nu_T: 0.45, G_L: 8.0e3, density: 1000.0}
fixed:
  - plane: {axis: x, value: 0.0}
)";
  const io::Scene s = io::parse_scene(aniso, "test.yaml");
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("E_T"), std::string::npos) << s.warnings[0];
  EXPECT_NE(s.warnings[0].find("1000"), std::string::npos) << s.warnings[0];
  EXPECT_TRUE(io::parse_scene(aniso, "test.yaml", "", {"regions[0].material.E_T=60.0"}).warnings.empty());
}

TEST(SceneFidelity, WarnsWhenTheStepIsLargerThanTheRequestedFidelitys) {
  const io::Scene s = io::parse_scene(kBox + "fidelity: accurate\n", "test.yaml", "", {"solver.dt=0.02"});
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("solver.dt"), std::string::npos) << s.warnings[0];
  EXPECT_NE(s.warnings[0].find("accurate"), std::string::npos) << s.warnings[0];
  // A smaller step than the preset's, or no preset, warns of nothing.
  EXPECT_TRUE(io::parse_scene(kBox + "fidelity: accurate\n", "test.yaml", "", {"solver.dt=0.001"}).warnings.empty());
  EXPECT_TRUE(io::parse_scene(kBox, "test.yaml", "", {"solver.dt=0.5"}).warnings.empty());
  EXPECT_TRUE(io::parse_scene(kBox + "fidelity: interactive\n", "test.yaml").warnings.empty());
}

// solver.preconditioner takes amg (a build without AMGCL refuses it with a message naming
// AMGCL); a bad value lists the three.
TEST(SceneFidelity, PreconditionerKeyTakesAmg) {
  if (!fiberfem::core::has_amg()) {
    EXPECT_NE(expect_error(kBox, {"solver.preconditioner=amg"}).find("AMGCL"), std::string::npos);
    return;
  }
  const io::Scene s = io::parse_scene(kBox, "test.yaml", "", {"solver.preconditioner=amg"});
  EXPECT_EQ(s.settings.solver.preconditioner, fiberfem::core::PreconditionerKind::amg);
  const std::string e = expect_error(kBox, {"solver.preconditioner=multigrid"});
  for (const char* word : {"solver.preconditioner", "cholesky", "block_jacobi", "amg"})
    EXPECT_NE(e.find(word), std::string::npos) << word << " not in: " << e;
}
