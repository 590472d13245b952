// Scenes on the accurate tier (docs/scenes.md): material.law and its constants, mesh.order,
// the Newton keys; the linear material of a law's small-strain limit against the closed
// form of REFERENCES.md; the problem built for the solver; a bad key named in the error.

#include "io/scene.hpp"
#include "io/scene_accurate.hpp"
#include "io/scene_sections.hpp"
#include "io/gmsh_test_files.hpp"
#include "core/hyperelastic/newton.hpp"
#include "core/static_solver.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <string>
#include <vector>

namespace fiberfem::io {
namespace {

const std::string kBeam = R"(name: law-beam
mesh: {generator: box, size: [0.010, 0.001, 0.001], cells: [4, 1, 1], order: 2}
regions:
  - name: myocardium
    material: {law: guccione, C: 2000.0, b_f: 8.0, b_t: 2.0, b_fs: 4.0, incompressible: true, density: 1000.0}
fixed:
  - plane: {axis: x, value: 0.0}
loads:
  tractions:
    - on: {plane: {axis: z, value: 0.0}}
      pressure: 4.0
      follower: true
solver: {mode: static, load_steps: 3, quadrature: 11, newton: {tolerance: 1.0e-8, increment_tolerance: 1.0e-5, max_iterations: 12, line_search: false}}
)";

std::string with(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

void expect_error(const std::string& yaml, const std::string& fragment) {
  try {
    const Scene s = parse_scene(yaml, "test.yaml");
    accurate_problem(s);
    ADD_FAILURE() << "expected an error mentioning " << fragment;
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
  }
}

TEST(SceneLaws, AGuccioneBeamBecomesTheProblemItDescribes) {
  const Scene s = parse_scene(kBeam, "test.yaml");
  ASSERT_TRUE(s.accurate());
  EXPECT_EQ(s.mesh_order, 2);
  const AccurateProblem ap = accurate_problem(s);
  const auto& law = ap.problem->region_laws.at(0);
  EXPECT_EQ(law.kind, core::hyperelastic::LawKind::guccione);
  EXPECT_DOUBLE_EQ(law.guccione_c_pa, 2000.0);
  EXPECT_DOUBLE_EQ(law.guccione_b_fs, 4.0);
  EXPECT_TRUE(law.incompressible);
  EXPECT_EQ(ap.mesh->order(), 2);
  EXPECT_EQ(ap.problem->points(), 11);
  EXPECT_EQ(ap.newton.load_steps, 3);
  EXPECT_DOUBLE_EQ(ap.newton.tolerance, 1e-8);
  EXPECT_DOUBLE_EQ(ap.newton.increment_tolerance, 1e-5);
  EXPECT_EQ(ap.newton.max_iterations, 12);
  EXPECT_FALSE(ap.newton.line_search);
  ASSERT_EQ(ap.problem->pressures.size(), 1u);
  EXPECT_TRUE(ap.problem->pressures[0].follower);
  EXPECT_EQ(ap.problem->pressures[0].faces.size(), 4u * 2u);  // two triangles per cell face
  // Every node on x = 0 fixed, edge nodes included.
  int fixed = 0;
  for (int n = 0; n < ap.mesh->num_nodes(); ++n)
    if (ap.mesh->rest_positions()(0, n) < 1e-12) fixed += ap.problem->fixed_dofs[static_cast<size_t>(3 * n)];
  EXPECT_EQ(fixed, 9);  // a 3 x 3 grid of corner and edge nodes on a 1 x 1 face of two triangles
}

TEST(SceneLaws, TheSmallStrainLimitOfGuccioneIsTheClosedForm) {
  // REFERENCES.md: E_L = C (b_f + b_t/2), G_L = C b_fs / 2 for the incompressible law; the
  // shear modulus is free of the bulk part, so it is checked exactly.
  const Scene s = parse_scene(kBeam, "test.yaml");
  const core::Mat6& C = s.model.region_materials.at(0).stiffness();
  EXPECT_NEAR(C(4, 4), 2000.0 * 4.0 / 2, 1e-6);  // yz: fiber (z) with a cross-fiber axis
  EXPECT_NEAR(C(5, 5), 2000.0 * 4.0 / 2, 1e-6);
  EXPECT_NEAR(C(3, 3), 2000.0 * 2.0 / 2, 1e-6);  // xy: the cross-fiber plane, G_T = C b_t / 2
}

TEST(SceneLaws, TheLawIsWrittenBackAsItWasRead) {
  const Scene s = parse_scene(kBeam, "test.yaml");
  const Scene again = parse_scene(write_scene_parameters(s.yaml_text, s.parameters), "again.yaml");
  const auto& a = s.parameters.regions[0].material.law;
  const auto& b = again.parameters.regions[0].material.law;
  ASSERT_TRUE(a && b);
  EXPECT_EQ(a->kind, b->kind);
  EXPECT_EQ(a->guccione_c_pa, b->guccione_c_pa);
  EXPECT_EQ(a->guccione_b_t, b->guccione_b_t);
  EXPECT_EQ(a->incompressible, b->incompressible);
  EXPECT_EQ(again.parameters.solver.newton_max_iterations, 12);
  EXPECT_EQ(again.parameters.solver.newton_increment_tolerance, 1e-5);
}

// Without the key, the increments before the last are loose on the mixed form only.
TEST(SceneLaws, TheIncrementToleranceDefaultsByTheVolumetricForm) {
  const std::string unset = with(kBeam, "increment_tolerance: 1.0e-5, ", "");
  EXPECT_DOUBLE_EQ(accurate_problem(parse_scene(unset, "test.yaml")).newton.increment_tolerance,
                   core::hyperelastic::NewtonSettings::kMixedIncrementTolerance);
  const AccurateProblem penalty =
      accurate_problem(parse_scene(with(unset, "incompressible: true", "incompressible: false"), "test.yaml"));
  EXPECT_LE(penalty.newton.increment_tolerance, penalty.newton.tolerance) << "a penalty solves every increment fully";
}

TEST(SceneLaws, ACompressibleLawTakesADefaultBulkModulus) {
  const Scene s = parse_scene(with(kBeam, "incompressible: true", "incompressible: false"), "test.yaml");
  const auto& law = *s.parameters.regions[0].material.law;
  EXPECT_NEAR(law.bulk_modulus_pa, kDefaultBulkFactor * 2000.0 * 2.0 / 2, 1e-9);
  const Scene nh = parse_scene(with(kBeam, "law: guccione, C: 2000.0, b_f: 8.0, b_t: 2.0, b_fs: 4.0, incompressible: true",
                                    "law: neo_hookean, E: 3000.0, nu: 0.25"),
                               "test.yaml");
  const auto& l = *nh.parameters.regions[0].material.law;
  EXPECT_NEAR(l.mu_pa, 3000.0 / 2.5, 1e-9);
  EXPECT_NEAR(l.bulk_modulus_pa, 3000.0 / 1.5, 1e-9);
}

TEST(SceneLaws, BadInputNamesTheKey) {
  expect_error(with(kBeam, "law: guccione", "law: mooney"), "'mooney' is not a law");
  expect_error(with(kBeam, "C: 2000.0", "C: -1.0"), "material.C must be > 0");
  expect_error(with(kBeam, "b_f: 8.0,", "b_f: 8.0, mu: 3.0,"), "mu");
  expect_error(with(kBeam, "law: guccione, C: 2000.0, b_f: 8.0, b_t: 2.0, b_fs: 4.0", "law: neo_hookean"),
               "neo_hookean needs mu");
  expect_error(with(kBeam, "law: guccione, C: 2000.0, b_f: 8.0, b_t: 2.0, b_fs: 4.0", "law: holzapfel_ogden"),
               "holzapfel_ogden needs a sheet direction");
  expect_error(with(kBeam, "order: 2", "order: 3"), "mesh.order");
  expect_error(with(kBeam, "quadrature: 11", "quadrature: 5"), "solver.quadrature");
  expect_error(with(kBeam, "load_steps: 3", "load_steps: 0"), "solver.load_steps");
  expect_error(with(kBeam, "tolerance: 1.0e-8", "tolerance: 2.0"), "solver.newton.tolerance");
  expect_error(with(kBeam, "increment_tolerance: 1.0e-5", "increment_tolerance: 0"), "solver.newton.increment_tolerance");
  expect_error(with(kBeam, "line_search: false", "line_search: false, damping: 1"), "damping");
  // A second region without a law.
  const std::string two = with(kBeam, "regions:\n", "regions:\n  - name: stiff\n    select: {box: [[0, 0, 0], [0.002, 0.001, 0.001]]}\n    material: {E: 1.0e5, nu: 0.3, density: 1000.0}\n");
  expect_error(two, "regions[0].material: needs a law");
  expect_error(with(kBeam, "      follower: true\n", "      follower: true\n  point_forces:\n    - at: [0.01, 0, 0]\n      force: [0, 0, 1]\n"),
               "point forces");
}

TEST(SceneLaws, HolzapfelOgdenTakesTheSheetOfAUniformField) {
  const std::string ho = with(with(kBeam, "law: guccione, C: 2000.0, b_f: 8.0, b_t: 2.0, b_fs: 4.0", "law: holzapfel_ogden"),
                              "fixed:", "fibers: {uniform: [1, 0, 0], sheet: [1, 1, 0]}\nfixed:");
  const Scene s = parse_scene(ho, "test.yaml");
  const AccurateProblem ap = accurate_problem(s);
  ASSERT_FALSE(ap.problem->axes.empty());
  EXPECT_NEAR(ap.problem->axes[0].s.dot(core::Vec3::UnitY()), 1.0, 1e-12);  // made orthogonal to the fiber
  expect_error(with(ho, "sheet: [1, 1, 0]", "sheet: [2, 0, 0]"), "fibers.sheet");
}

// Sheets from a fiber file's second vector (per element or per node), or fibers.sheet with
// a file or strokes: each made orthogonal to its element's fiber, the same axes as the
// uniform field with the same directions gives.
TEST(SceneLaws, HolzapfelOgdenTakesTheSheetsOfAFiberFile) {
  const std::string ho = with(kBeam, "law: guccione, C: 2000.0, b_f: 8.0, b_t: 2.0, b_fs: 4.0", "law: holzapfel_ogden");
  const std::string uniform = with(ho, "fixed:", "fibers: {uniform: [1, 0.2, 0], sheet: [0.1, 1, 0.5]}\nfixed:");
  const AccurateProblem reference = accurate_problem(parse_scene(uniform, "test.yaml"));
  const int elements = parse_scene(uniform, "test.yaml").model.mesh.num_elements();
  const int nodes = parse_scene(uniform, "test.yaml").model.mesh.num_nodes();
  const std::string dir = ::testing::TempDir();
  auto write = [&](const std::string& name, int lines, const std::string& line) {
    std::ofstream f(dir + name);
    f << "# fiber and sheet\n";
    for (int k = 0; k < lines; ++k) f << line << "\n";
  };
  write("per_element.txt", elements, "1 0.2 0   0.1 1 0.5");
  write("per_node.txt", nodes, "2 0.4 0 0.2 2 1");
  write("fibers_only.txt", elements, "1 0.2 0");
  for (const std::string file : {"per_element.txt", "per_node.txt"}) {
    const Scene s = parse_scene(with(ho, "fixed:", "fibers: {file: " + dir + file + "}\nfixed:"), "test.yaml");
    ASSERT_EQ(s.sheets.size(), static_cast<size_t>(elements)) << file;
    const AccurateProblem ap = accurate_problem(s);
    ASSERT_EQ(ap.problem->axes.size(), reference.problem->axes.size()) << file;
    for (size_t e = 0; e < ap.problem->axes.size(); ++e) {
      EXPECT_NEAR(std::abs(ap.problem->axes[e].f.dot(reference.problem->axes[e].f)), 1.0, 1e-12) << file;
      EXPECT_NEAR(std::abs(ap.problem->axes[e].s.dot(reference.problem->axes[e].s)), 1.0, 1e-12) << file;
      EXPECT_NEAR(ap.problem->axes[e].f.dot(ap.problem->axes[e].s), 0.0, 1e-12) << file;
    }
  }
  // fibers.sheet beside a file of fibers alone: the same axes again.
  const Scene beside = parse_scene(with(ho, "fixed:", "fibers: {file: " + dir + "fibers_only.txt, sheet: [0.1, 1, 0.5]}\nfixed:"), "test.yaml");
  EXPECT_NEAR(std::abs(accurate_problem(beside).problem->axes[0].s.dot(reference.problem->axes[0].s)), 1.0, 1e-12);
  // Without a sheet, the law names the ways to give one.
  expect_error(with(ho, "fixed:", "fibers: {file: " + dir + "fibers_only.txt}\nfixed:"), "fx fy fz sx sy sz");
  // A sheet twice, a sheet with the rule, a mixed file, a parallel sheet: named.
  expect_error(with(ho, "fixed:", "fibers: {file: " + dir + "per_element.txt, sheet: [0, 1, 0]}\nfixed:"), "the fiber file gives its own sheets");
  write("mixed.txt", 2, "1 0 0 0 1 0");
  { std::ofstream f(dir + "mixed.txt", std::ios::app); f << "1 0 0\n"; }
  expect_error(with(ho, "fixed:", "fibers: {file: " + dir + "mixed.txt}\nfixed:"), "mixed.txt:4: 3 numbers, but line 2 has 6");
  write("parallel.txt", elements, "1 0 0 -2 0 0");
  expect_error(with(ho, "fixed:", "fibers: {file: " + dir + "parallel.txt}\nfixed:"), "parallel.txt:2: the sheet (vector 0) is zero or parallel");
}

TEST(SceneLaws, AQuadraticGmshFileKeepsItsCurvedEdgeNodes) {
  // A gmsh file of 10-node tetrahedra (one edge node moved off its chord): the scene runs on
  // the file's element mesh at order 2, not on a promotion of its corners.
  const std::string dir = ::testing::TempDir();
  {
    std::ofstream f(dir + "/two.msh");
    f << fiberfem::testing::kTwoQuadraticTets;
  }
  const std::string scene = R"(mesh: {file: two.msh, scale: 0.001}
regions:
  - material: {law: neo_hookean, mu: 1000.0, bulk_modulus: 1.0e5, density: 1000.0}
solver: {mode: static}
)";
  const Scene s = parse_scene(scene, "two.yaml", dir);
  EXPECT_EQ(s.mesh_order, 2);
  const AccurateProblem ap = accurate_problem(s);
  ASSERT_EQ(ap.mesh->order(), 2);
  bool moved = false;  // the node at (0.55, 0, -0.55) mm, off the chord's midpoint (0.5, 0, -0.5)
  for (int n = ap.mesh->num_corner_nodes(); n < ap.mesh->num_nodes(); ++n)
    moved = moved || (ap.mesh->rest_positions().col(n) - core::Vec3(0.55e-3, 0, -0.55e-3)).norm() < 1e-12;
  EXPECT_TRUE(moved);
  // Without a law, the error says how to run its corners instead.
  try {
    parse_scene(with(scene, "law: neo_hookean, mu: 1000.0, bulk_modulus: 1.0e5", "E: 1.0e4, nu: 0.3"), "two.yaml", dir);
    ADD_FAILURE() << "expected an error";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("mesh.order: 1"), std::string::npos) << e.what();
  }
  const Scene corners = parse_scene(
      with(with(scene, "scale: 0.001}", "scale: 0.001, order: 1}"), "law: neo_hookean, mu: 1000.0, bulk_modulus: 1.0e5", "E: 1.0e4, nu: 0.3"),
      "two.yaml", dir);
  EXPECT_FALSE(corners.accurate());
}

// solver.tier: real_time runs a law's small-strain limit on the corotated linear engine.
// Two independent solvers on the same linear tetrahedra under a load small enough for
// linear elasticity (tip about 1e-4 of the beam): the real-time tier's static solve with
// the linearised material and the accurate tier's Newton with the neo-Hookean law must
// give the same tip deflection to the size of the nonlinear terms.
TEST(SceneLaws, TheRealTimeTierRunsALawAsItsSmallStrainLimit) {
  const std::string beam = R"(name: tiers
mesh: {generator: box, size: [0.010, 0.002, 0.002], cells: [10, 2, 2]}
regions:
  - name: body
    material: {law: neo_hookean, E: 10000.0, nu: 0.3, density: 1000.0}
fixed:
  - plane: {axis: x, value: 0.0}
loads: {gravity: [0.0, 0.0, -0.01]}
solver: {mode: static, load_steps: 1}
probes: {tip: [0.010, 0.001, 0.001]}
)";
  const Scene accurate = parse_scene(beam, "tiers.yaml");
  const Scene fast = parse_scene(beam, "tiers.yaml", "", {"solver.tier=real_time"});
  ASSERT_TRUE(accurate.accurate());
  ASSERT_FALSE(fast.accurate());
  EXPECT_TRUE(parse_scene(beam, "tiers.yaml", "", {"solver.tier=accurate"}).accurate());

  core::Positions x_fast;
  const core::StaticReport rf = core::solve_static(fast.model, x_fast);
  ASSERT_TRUE(rf.converged) << rf.message;
  const double tip_fast = fast.probes.at(0).displacement(fast.model.mesh, x_fast).z();

  const AccurateProblem ap = accurate_problem(accurate);
  core::Positions x = ap.mesh->rest_positions();
  Eigen::VectorXd p;
  const core::hyperelastic::NewtonReport ra = core::hyperelastic::solve_static(*ap.problem, x, p, ap.newton);
  ASSERT_TRUE(ra.converged) << ra.message;
  const double tip_accurate = accurate_probe_displacement(*ap.mesh, accurate.probes.at(0), x).z();

  ASSERT_LT(tip_accurate, -1e-7);  // a deflection to compare (about 1 um)
  EXPECT_GT(tip_accurate, -1e-5);  // small strain
  EXPECT_NEAR(tip_fast / tip_accurate, 1.0, 2e-3) << tip_fast << " " << tip_accurate;
}

// The message of the error parsing `yaml` with `overrides` gives ("" when it parses).
std::string parse_error(const std::string& yaml, const std::vector<std::string>& overrides) {
  try {
    parse_scene(yaml, "test.yaml", "", overrides);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

TEST(SceneLaws, TheTierIsCheckedAgainstTheMeshAndTheMaterial) {
  // real_time on 10-node tetrahedra: named, with the way out.
  const std::string quadratic = parse_error(kBeam, {"solver.tier=real_time"});
  EXPECT_NE(quadratic.find("solver.tier: real_time runs linear tetrahedra"), std::string::npos) << quadratic;
  EXPECT_NE(quadratic.find("mesh.order: 1"), std::string::npos) << quadratic;
  // The law's scene at order 1 runs on the real-time tier with the linearised material.
  const Scene fast = parse_scene(kBeam, "test.yaml", "", {"solver.tier=real_time", "mesh.order=1"});
  EXPECT_FALSE(fast.accurate());
  EXPECT_NEAR(fast.model.region_materials.at(0).constants().C33, linearised_material(*fast.parameters.regions[0].material.law, 1000.0).constants().C33, 1e-6);
  // accurate without a law: the region named.
  const std::string linear = with(kBeam, "material: {law: guccione, C: 2000.0, b_f: 8.0, b_t: 2.0, b_fs: 4.0, incompressible: true, density: 1000.0}",
                                  "material: {E: 10000.0, nu: 0.3, density: 1000.0}");
  const std::string no_law = parse_error(linear, {"solver.tier=accurate", "mesh.order=1"});
  EXPECT_NE(no_law.find("regions[0].material: needs a law (solver.tier: accurate"), std::string::npos) << no_law;
  // A bad name lists the allowed ones.
  const std::string bad = parse_error(kBeam, {"solver.tier=fast"});
  EXPECT_NE(bad.find("solver.tier"), std::string::npos) << bad;
  EXPECT_NE(bad.find("real_time"), std::string::npos) << bad;
}

}  // namespace
}  // namespace fiberfem::io
