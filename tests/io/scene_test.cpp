// Scene files (docs/scenes.md): the documented example parses into the model it describes
// (counts, loads and constants checked by hand), regions match first-wins by element
// centroid, and every kind of bad input is refused with the line and key path.

#include "io/mesh_io.hpp"
#include "io/scene.hpp"

#include "core/box_generator.hpp"
#include "core/fiber_fields.hpp"
#include "core/lv_ellipsoid.hpp"
#include "test_support.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>

namespace sc = fiberfem::io;
namespace core = fiberfem::core;
using core::Vec3;

namespace {

using fiberfem::testing::replace_once;

const char* kExample = R"(name: beam-demo
mesh:
  generator: box
  size: [0.010, 0.001, 0.001]
  cells: [40, 4, 4]
regions:
  - name: all
    select: all
    material:
      E_L: 60.0e3
      E_T: 20.0e3
      nu_LT: 0.25
      nu_T: 0.45
      G_L: 8.0e3
      density: 1000.0
    damping: {mass: 2.0, stiffness: 0.001}
fibers:
  uniform: [1, 0, 0]
fixed:
  - plane: {axis: x, value: 0.0, tol: 1.0e-9}
loads:
  gravity: [0, 0, -9.81]
  tractions:
    - on: {plane: {axis: z, value: 0.0}}
      pressure: 4.0
  point_forces:
    - at: [0.010, 0.0005, 0.0005]
      force: [0, 0, -1.0e-3]
solver:
  mode: dynamic
  dt: 0.0166667
  method: pcg
  tolerance: 1.0e-6
  max_iterations: 500
  rotation: svd
probes:
  tip: [0.010, 0.0005, 1.0e-3]
)";

// Expects parse_scene to throw a SceneError whose message contains every fragment.
void expect_error(const std::string& yaml, std::initializer_list<std::string> fragments) {
  try {
    sc::parse_scene(yaml, "test.yaml");
    ADD_FAILURE() << "expected a SceneError mentioning " << *fragments.begin() << " for:\n" << yaml;
  } catch (const sc::SceneError& e) {
    const std::string msg = e.what();
    for (const auto& f : fragments) EXPECT_NE(msg.find(f), std::string::npos) << "'" << msg << "' lacks '" << f << "'";
  }
}

// parse_scene with a base directory, expecting a SceneError mentioning every fragment.
void expect_error_in(const std::string& yaml, const std::string& dir, std::initializer_list<std::string> fragments) {
  try {
    sc::parse_scene(yaml, dir + "/lv.yaml", dir);
    ADD_FAILURE() << "expected a SceneError mentioning " << *fragments.begin();
  } catch (const sc::SceneError& e) {
    const std::string msg = e.what();
    for (const auto& f : fragments) EXPECT_NE(msg.find(f), std::string::npos) << "'" << msg << "' lacks '" << f << "'";
  }
}

}  // namespace

TEST(Scene, DocumentedExampleBuildsTheModelItDescribes) {
  const sc::Scene s = sc::parse_scene(kExample, "example.yaml");
  EXPECT_EQ(s.name, "beam-demo");
  const core::Model& m = s.model;
  EXPECT_EQ(m.mesh.num_elements(), 6 * 40 * 4 * 4);
  EXPECT_EQ(m.mesh.num_nodes(), 41 * 5 * 5);
  EXPECT_NEAR(m.mesh.total_volume(), 0.010 * 0.001 * 0.001, 1e-18);
  // Material: the compliance of the engineering constants.
  EXPECT_LT((m.region_materials[0].compliance() - fiberfem::testing::engineering_compliance([] {
               core::EngineeringConstants c;
               c.E_L = 60e3, c.E_T = 20e3, c.nu_LT = 0.25, c.nu_T = 0.45, c.G_L = 8e3;
               return c;
             }()))
                .cwiseAbs()
                .maxCoeff(),
            1e-15);
  ASSERT_EQ(m.region_damping.size(), 1u);
  EXPECT_EQ(m.region_damping[0].mass_1_s, 2.0);
  EXPECT_EQ(m.region_damping[0].stiffness_s, 0.001);
  // Fixed: the 5 x 5 nodes of the x = 0 face, all components.
  int fixed = 0;
  for (auto f : m.fixed_dofs) fixed += f;
  EXPECT_EQ(fixed, 3 * 25);
  // Loads: gravity, a 4 Pa pressure on the z = 0 face (area 1e-5 m^2, inward normal +z),
  // and 1 mN at the tip corner node nearest (0.010, 0.0005, 0.0005).
  const Eigen::VectorXd f = m.external_forces();
  Vec3 total = Vec3::Zero();
  for (int n = 0; n < m.mesh.num_nodes(); ++n) total += f.segment<3>(3 * n);
  const double mass = 1000.0 * 1e-8;
  EXPECT_NEAR(total.z(), -9.81 * mass + 4.0 * 1e-5 - 1e-3, 1e-15);
  EXPECT_NEAR(total.x(), 0, 1e-18);
  ASSERT_EQ(m.loads.point_forces.size(), 1u);
  EXPECT_LT((m.mesh.rest_positions().col(m.loads.point_forces[0].node) - Vec3(0.010, 0.0005, 0.0005)).norm(), 1e-12);
  EXPECT_NEAR(s.settings.dt_s, 0.0166667, 1e-15);
  EXPECT_EQ(s.settings.solver.method, core::LinearSolverKind::pcg);
  EXPECT_EQ(s.settings.rotation, core::RotationMethod::svd);
  EXPECT_EQ(s.mode, sc::Mode::dynamic);
  ASSERT_EQ(s.probes.size(), 1u);
  EXPECT_EQ(s.probes[0].name, "tip");
  // The probe interpolates linearly: a uniform translation moves it by the same amount,
  // and a linear field u = G X gives u = G p at the probe point.
  core::Positions x = m.mesh.rest_positions();
  core::Mat3 G;
  G << 0.01, 0.02, -0.03, 0.005, 0.0, 0.01, -0.02, 0.03, 0.04;
  for (int n = 0; n < m.mesh.num_nodes(); ++n) x.col(n) += G * m.mesh.rest_positions().col(n) + Vec3(1e-4, 0, 0);
  EXPECT_LT((s.probes[0].displacement(m.mesh, x) - (G * Vec3(0.010, 0.0005, 1.0e-3) + Vec3(1e-4, 0, 0))).norm(), 1e-15);
  // And it runs.
  core::Simulator sim(s.model, s.settings);
  for (int i = 0; i < 3; ++i) EXPECT_NE(sim.step().status, core::StepStatus::failed);
}

// Two regions, first match wins by element centroid; the other material forms.
TEST(Scene, RegionsMatchFirstWinsByCentroid) {
  const std::string yaml = R"(mesh: {generator: box, size: [0.04, 0.01, 0.01], cells: [4, 1, 1]}
regions:
  - name: left
    select: {box: [[0, 0, 0], [0.02, 0.01, 0.01]]}
    material: {lame: [40.0e3, 10.0e3], fiber_factor: 3, density: 1000}
  - name: rest
    material: {E: 30.0e3, nu: 0.3, density: 1100}
fixed:
  - node_set: xmin
)";
  const sc::Scene s = sc::parse_scene(yaml);
  const core::Model& m = s.model;
  ASSERT_EQ(m.mesh.num_regions(), 2);
  for (int e = 0; e < m.mesh.num_elements(); ++e) {
    Vec3 c = Vec3::Zero();
    for (int n : m.mesh.tets()[static_cast<size_t>(e)]) c += 0.25 * m.mesh.rest_positions().col(n);
    EXPECT_EQ(m.mesh.regions()[static_cast<size_t>(e)], c.x() <= 0.02 ? 0 : 1) << "element " << e;
  }
  EXPECT_FALSE(m.region_materials[0].is_isotropic());
  EXPECT_TRUE(m.region_materials[1].is_isotropic());
  EXPECT_DOUBLE_EQ(m.region_materials[1].density_kg_m3(), 1100);
  // Lame form: C33 = 3 (lambda + 2 mu).
  EXPECT_NEAR(m.region_materials[0].stiffness()(2, 2), 3 * (40e3 + 2 * 10e3), 1e-9);
}

TEST(Scene, BadInputNamesTheLineAndKeyPath) {
  const std::string ex = kExample;
  // Unknown key, at its own line (line 3 is "  generator: box").
  expect_error(replace_once(ex, "  generator: box", "  generater: box"), {"test.yaml:3:", "mesh.generater", "unknown key"});
  expect_error(replace_once(ex, "probes:", "probez:"), {"probez", "unknown key"});
  // Wrong type and out of range.
  expect_error(replace_once(ex, "dt: 0.0166667", "dt: fast"), {"solver.dt", "expected a number"});
  expect_error(replace_once(ex, "dt: 0.0166667", "dt: -1"), {"test.yaml:31:", "solver.dt", "must be in"});
  expect_error(replace_once(ex, "dt: 0.0166667", "dt: 0.0166667\n  threads: -2"), {"solver.threads", "must be in"});
  expect_error(replace_once(ex, "dt: 0.0166667", "dt: 0.0166667\n  threads: many"), {"solver.threads"});
  expect_error(replace_once(ex, "cells: [40, 4, 4]", "cells: [40, 0, 4]"), {"mesh.cells[1]", "must be in"});
  expect_error(replace_once(ex, "method: pcg", "method: magic"), {"solver.method", "'magic' is not one of pcg, direct"});
  expect_error(replace_once(ex, "gravity: [0, 0, -9.81]", "gravity: [0, -9.81]"), {"loads.gravity", "three numbers"});
  // Material: missing density, two forms, not positive definite (the engine's message).
  expect_error(replace_once(ex, "      density: 1000.0\n", ""), {"regions[0].material", "density"});
  expect_error(replace_once(ex, "      G_L: 8.0e3\n", "      G_L: 8.0e3\n      E: 1.0\n"), {"regions[0].material", "one form"});
  expect_error(replace_once(ex, "nu_T: 0.45", "nu_T: 1.5"), {"regions[0].material", "nu_T"});
  // Selectors that match nothing, regions that leave elements out.
  expect_error(replace_once(ex, "value: 0.0, tol", "value: 0.5, tol"), {"fixed[0]", "matches no node"});
  expect_error(replace_once(ex, "    select: all", "    select: {box: [[0, 0, 0], [0.005, 0.001, 0.001]]}"),
               {"regions", "matched by no region"});
  // Not available yet, and not YAML.
  expect_error(replace_once(ex, "generator: box", "generator: palm"), {"mesh.generator", "available: box, lv_ellipsoid"});
  expect_error(replace_once(ex, "generator: box", "generator: lv_ellipsoid"), {"mesh.size", "box key"});
  expect_error(replace_once(ex, "  uniform: [1, 0, 0]", "  rule: {}"), {"fibers.rule.inner", "no node set 'endo'"});
  expect_error(replace_once(ex, "  uniform: [1, 0, 0]", "  uniform: [1, 0, 0]\n  file: f.txt"), {"fibers", "exactly one of"});
  expect_error("mesh: [unclosed", {"test.yaml:", "not valid YAML"});
  expect_error(replace_once(ex, "tip: [0.010, 0.0005, 1.0e-3]", "tip: [0.02, 0.0005, 1.0e-3]"), {"probes.tip", "outside the mesh"});
  expect_error("regions: []\n", {"mesh", "missing"});
  // A YAML complex key (a mapping as key: the scene fuzzer's find) is an error, not a crash.
  expect_error(replace_once(ex, "  dt: 0.0166667", "  ? dt: 0.0166667"), {"test.yaml:31:", "solver", "plain name"});
  expect_error(replace_once(ex, "tip: [0.010, 0.0005, 1.0e-3]", "? [tip]: [0.010, 0.0005, 1.0e-3]"), {"probes", "plain name"});
}

TEST(Scene, LoadsFilesAndReportsUnreadableOnes) {
  const std::string path = ::testing::TempDir() + "/fiberfem_scene_test.yaml";
  {
    std::ofstream f(path);
    f << kExample;
  }
  EXPECT_EQ(sc::load_scene(path).model.mesh.num_elements(), 3840);
  std::remove(path.c_str());
  try {
    sc::load_scene(path);
    ADD_FAILURE() << "expected an error for a missing file";
  } catch (const sc::SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot open"), std::string::npos) << e.what();
  }
}

// mesh.file: a gmsh file next to the scene (relative path), scaled from millimetres; its
// region tags select materials.
TEST(Scene, ReadsAMeshFileRelativeToTheScene) {
  core::BoxSpec b;
  b.size_m = {40, 10, 10};  // millimetres
  b.cells = {4, 1, 1};
  const core::TetMesh box = core::make_box(b);
  std::vector<int> tags(static_cast<size_t>(box.num_elements()));
  for (size_t e = 0; e < tags.size(); ++e) tags[e] = e < tags.size() / 2 ? 3 : 5;
  core::TetMesh tagged(box.rest_positions(), box.tets(), tags);
  for (const auto& [name, nodes] : box.node_sets()) tagged.set_node_set(name, nodes);
  const std::string dir = ::testing::TempDir();
  {
    std::ofstream f(dir + "/fiberfem_scene_mesh.msh");
    fiberfem::io::write_gmsh22(tagged, f);
    std::ofstream s(dir + "/fiberfem_scene_mesh.yaml");
    s << "mesh: {file: fiberfem_scene_mesh.msh, scale: 0.001}\n"
         "regions:\n"
         "  - {select: {tag: 3}, material: {E: 20.0e3, nu: 0.3, density: 1000}}\n"
         "  - {select: {tag: 5}, material: {E: 80.0e3, nu: 0.3, density: 1000}}\n"
         "fixed: [{node_set: xmin}]\n";
  }
  const sc::Scene s = sc::load_scene(dir + "/fiberfem_scene_mesh.yaml");
  EXPECT_NEAR(s.model.mesh.total_volume(), 0.04 * 0.01 * 0.01, 1e-15);
  for (size_t e = 0; e < tags.size(); ++e) EXPECT_EQ(s.model.mesh.regions()[e], tags[e] == 3 ? 0 : 1);
  std::remove((dir + "/fiberfem_scene_mesh.msh").c_str());
  try {
    sc::load_scene(dir + "/fiberfem_scene_mesh.yaml");
    ADD_FAILURE() << "expected an error for the missing mesh file";
  } catch (const sc::SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("mesh.file"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("cannot open"), std::string::npos) << e.what();
  }
  std::remove((dir + "/fiberfem_scene_mesh.yaml").c_str());
}

// --set overrides: keys, list indices and YAML values; bad paths are named.
TEST(Scene, SolverThreadsReachTheEngineSettings) {
  EXPECT_EQ(sc::parse_scene(kExample, "ex.yaml", "", {"solver.threads=1"}).settings.threads, 1);
  EXPECT_EQ(sc::parse_scene(kExample, "ex.yaml").settings.threads, 0);
}

TEST(Scene, OverridesSetKeysBeforeParsing) {
  const sc::Scene s = sc::parse_scene(kExample, "ex.yaml", "",
                                      {"solver.dt=0.01", "regions[0].material.E_L=70.0e3", "loads.gravity=[0, 0, -1]",
                                       "solver.max_energy_gain=inf", "name=sweep-1"});
  EXPECT_DOUBLE_EQ(s.settings.dt_s, 0.01);
  EXPECT_NEAR(1.0 / s.model.region_materials[0].compliance()(2, 2), 70e3, 1e-6);
  EXPECT_EQ(s.model.loads.gravity_m_s2, Vec3(0, 0, -1));
  EXPECT_TRUE(std::isinf(s.settings.max_energy_gain));
  EXPECT_EQ(s.name, "sweep-1");
  // A value that fails validation is reported at its key path like any other.
  try {
    sc::parse_scene(kExample, "ex.yaml", "", {"solver.dt=-1"});
    ADD_FAILURE();
  } catch (const sc::SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("ex.yaml: --set solver.dt: must be in"), std::string::npos) << e.what();
  }
  for (const char* bad : {"solver.dt", "regions[3].material.E_L=1", "regions[x]=1", "name.sub=1"}) {
    try {
      sc::parse_scene(kExample, "ex.yaml", "", {bad});
      ADD_FAILURE() << bad;
    } catch (const sc::SceneError& e) {
      EXPECT_NE(std::string(e.what()).find("--set"), std::string::npos) << bad << ": " << e.what();
    }
  }
}

// --set creates the mappings on its path that the scene leaves out (a scene without a
// solver section gets one).
TEST(Scene, OverridesCreateMissingMappings) {
  const std::string yaml = R"(name: bare
mesh:
  generator: lv_ellipsoid
  inner: {rs: 0.007, rl: 0.017}
  outer: {rs: 0.010, rl: 0.020}
  base_z: 0.005
  resolution: {circumferential: 12, longitudinal: 4, transmural: 1}
regions:
  - select: all
    material: {E: 10.0e3, nu: 0.45, density: 1000}
fixed:
  - node_set: base
)";
  const sc::Scene s = sc::parse_scene(yaml, "bare.yaml", "", {"solver.dt=0.02", "solver.tolerance=1e-4"});
  EXPECT_DOUBLE_EQ(s.settings.dt_s, 0.02);
  EXPECT_DOUBLE_EQ(s.settings.solver.tolerance, 1e-4);
}

// The benchmark ellipsoid from a scene: the keys reach the generator (the same mesh as
// core's generator with the same spec), its surfaces are node sets that selectors use (the
// base held, a cavity pressure on the endocardium), and box keys are refused by name.
TEST(Scene, LvEllipsoidGeneratorAndItsSurfaces) {
  const std::string yaml = R"(name: lv
mesh:
  generator: lv_ellipsoid
  inner: {rs: 0.007, rl: 0.017}
  outer: {rs: 0.010, rl: 0.020}
  base_z: 0.005
  resolution: {circumferential: 18, longitudinal: 6, transmural: 2}
regions:
  - select: all
    material: {E: 10.0e3, nu: 0.45, density: 1000}
fixed:
  - node_set: base
loads:
  tractions:
    - on: {node_set: endo}
      pressure: 1000.0
)";
  const sc::Scene s = sc::parse_scene(yaml, "lv.yaml");
  core::LvEllipsoidSpec spec;
  spec.circumferential = 18;
  spec.longitudinal = 6;
  spec.transmural = 2;
  const core::TetMesh m = core::make_lv_ellipsoid(spec);
  EXPECT_EQ(s.model.mesh.rest_positions(), m.rest_positions());
  EXPECT_EQ(s.model.mesh.tets(), m.tets());
  // Base nodes fixed, nothing else.
  const auto& base = m.node_set("base");
  int fixed = 0;
  for (std::uint8_t f : s.model.fixed_dofs) fixed += f;
  EXPECT_EQ(fixed, 3 * static_cast<int>(base.size()));
  // The cavity pressure acts on endocardial faces only, and its net force on the closed
  // cavity is the pressure times the base opening's projected area along +z (the cavity
  // is open at the base): p * pi * rs_base^2 with rs_base = rs sqrt(1 - (z_b / rl)^2),
  // up to the faceting of the base ring (a polygon of 18 sides: area factor
  // 18 sin(2 pi / 18) / (2 pi) = 0.980).
  ASSERT_EQ(s.model.loads.surface_loads.size(), 1u);
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * m.num_nodes());
  core::add_surface_load(m.rest_positions(), s.model.loads.surface_loads[0], f);
  Vec3 net = Vec3::Zero();
  for (int n = 0; n < m.num_nodes(); ++n) net += f.segment<3>(3 * n);
  const double rs_base = 0.007 * std::sqrt(1 - std::pow(0.005 / 0.017, 2));
  const double polygon = 18 * std::sin(2 * M_PI / 18) / (2 * M_PI);
  EXPECT_NEAR(net.z() / (1000.0 * M_PI * rs_base * rs_base * polygon), -1.0, 1e-9);
  EXPECT_NEAR(net.x(), 0, 1e-12);
  EXPECT_NEAR(net.y(), 0, 1e-12);

  expect_error(replace_once(yaml, "base_z: 0.005", "base_z: 0.005\n  cells: [1, 1, 1]"), {"test.yaml:7:", "mesh.cells", "box key"});
  expect_error(replace_once(yaml, "transmural: 2", "transmural: 0"), {"test.yaml:7:", "mesh.resolution.transmural"});
  expect_error(replace_once(yaml, "rs: 0.010", "rs: 0.005"), {"test.yaml:", "mesh", "epi_rs_m"});
  expect_error(replace_once(yaml, "lv_ellipsoid", "biventricle"), {"test.yaml:3:", "mesh.generator", "available: box, lv_ellipsoid"});
  // apex_grading reaches the generator; out of [1, 3] it is named.
  const sc::Scene graded = sc::parse_scene(replace_once(yaml, "base_z: 0.005", "base_z: 0.005\n  apex_grading: 1.5"), "lv.yaml");
  spec.apex_grading = 1.5;
  EXPECT_EQ(graded.model.mesh.rest_positions(), core::make_lv_ellipsoid(spec).rest_positions());
  EXPECT_NE(graded.model.mesh.rest_positions(), m.rest_positions());
  expect_error(replace_once(yaml, "base_z: 0.005", "base_z: 0.005\n  apex_grading: 0.8"), {"test.yaml:7:", "mesh.apex_grading"});
}

namespace {
const char* kLv = R"(name: lv
mesh:
  generator: lv_ellipsoid
  resolution: {circumferential: 18, longitudinal: 6, transmural: 2}
regions:
  - name: myocardium
    select: all
    material: {E_L: 60.0e3, E_T: 20.0e3, nu_LT: 0.25, nu_T: 0.45, G_L: 8.0e3, density: 1000}
fibers:
  rule: {endo_angle: 60, epi_angle: -60}
fixed:
  - node_set: base
)";
}  // namespace

// fibers.rule is core's helix rule on the harmonic coordinate between endo and epi.
TEST(Scene, FiberRuleIsTheHelixRule) {
  const sc::Scene s = sc::parse_scene(kLv, "lv.yaml");
  const core::TetMesh& m = s.model.mesh;
  const core::FiberField f =
      core::helix_rule_fibers(m, core::laplace_coordinate(m, m.node_set("endo"), m.node_set("epi")), core::HelixRule{});
  ASSERT_EQ(s.model.fibers.size(), f.fiber.size());
  for (size_t e = 0; e < f.fiber.size(); ++e) EXPECT_LT((s.model.fibers[e] - f.fiber[e]).norm(), 1e-12);
  expect_error(replace_once(kLv, "epi_angle: -60", "epi_angle: -200"), {"test.yaml:10:", "fibers.rule.epi_angle"});
  expect_error(replace_once(kLv, "{endo_angle: 60, epi_angle: -60}", "{inner: {node_set: base}, outer: {node_set: base}}"),
               {"fibers", "in both sets"});
}

// fibers.file: one vector per element, or per node (interpolated sign-blind); counts and
// bad vectors are refused with the file and line.
TEST(Scene, FiberFilePerElementAndPerNode) {
  const std::string dir = ::testing::TempDir();
  const std::string yaml = replace_once(kLv, "rule: {endo_angle: 60, epi_angle: -60}", "file: fibers.txt");
  const sc::Scene base = sc::parse_scene(kLv, "lv.yaml");
  const int ne = base.model.mesh.num_elements(), nn = base.model.mesh.num_nodes();
  auto write = [&](int count, const std::string& line, int bad_at = -1, const std::string& bad = "") {
    std::ofstream f(dir + "/fibers.txt");
    f << "# fibers\n";
    for (int i = 0; i < count; ++i) f << (i == bad_at ? bad : line) << "\n";
  };
  write(ne, "0 0 2");
  sc::Scene s = sc::parse_scene(yaml, dir + "/lv.yaml", dir);
  for (const Vec3& f : s.model.fibers) EXPECT_LT((f - Vec3::UnitZ()).norm(), 1e-15);
  write(nn, "0 -3 0");  // per node: every node the same axis, so every element too
  s = sc::parse_scene(yaml, dir + "/lv.yaml", dir);
  for (const Vec3& f : s.model.fibers) EXPECT_LT(core::fiber_angle_deg(f, Vec3::UnitY()), 1e-6);
  write(ne - 1, "1 0 0");
  expect_error_in(yaml, dir, {"fibers.file", "has " + std::to_string(ne - 1) + " vectors", std::to_string(ne) + " elements"});
  write(ne, "1 0 0", 4, "0 0 0");
  expect_error_in(yaml, dir, {"fibers.txt:6:", "zero vector (vector 4)"});
  write(ne, "1 0 0", 2, "1 nan 0");
  expect_error_in(yaml, dir, {"fibers.txt:4:"});
  write(ne, "1 0 0", 2, "1 0");
  expect_error_in(yaml, dir, {"fibers.txt:4:", "three numbers"});
}

// fibers.strokes: nodes near a stroke take its tangent; a single straight stroke makes a
// uniform field along it (whatever direction it was drawn in).
TEST(Scene, StrokesGiveTheirTangent) {
  const std::string yaml = replace_once(kLv, "rule: {endo_angle: 60, epi_angle: -60}",
                                        "strokes: {lines: [[[0.0, -0.02, -0.01], [0.0, 0.02, 0.01]]], radius: 0.004}");
  const sc::Scene s = sc::parse_scene(yaml, "lv.yaml");
  const Vec3 d = Vec3(0, 0.04, 0.02).normalized();
  for (const Vec3& f : s.model.fibers) EXPECT_LT(core::fiber_angle_deg(f, d), 1e-6);
  expect_error(replace_once(yaml, "radius: 0.004", "radius: 1.0e-9"), {"fibers.strokes", "no node lies within"});
  expect_error(replace_once(yaml, "[0.0, 0.02, 0.01]", "[0.0, -0.02, -0.01]"), {"fibers.strokes.lines[0]", "two distinct"});
}

// contraction: keys reach core::Contraction; regions by name; pacing delays by distance.
TEST(Scene, ContractionKeys) {
  const std::string yaml = std::string(kLv) + R"(contraction:
  peak_tension: 60.0e3
  heart_rate: 75
  twitch: {shape: sine, systole: 0.3}
  pacing: {at: [0.0, 0.0, -0.02], speed: 0.5}
)";
  const sc::Scene s = sc::parse_scene(yaml, "lv.yaml");
  const core::Contraction& c = s.model.contraction;
  EXPECT_TRUE(c.enabled());
  EXPECT_NEAR(c.period_s, 0.8, 1e-15);
  EXPECT_EQ(c.twitch.shape, core::TwitchShape::sine);
  EXPECT_EQ(c.region_peak_pa, std::vector<double>({60e3}));
  ASSERT_EQ(c.element_delay_s.size(), static_cast<size_t>(s.model.mesh.num_elements()));
  for (int e = 0; e < s.model.mesh.num_elements(); e += 97) {
    Vec3 cen = Vec3::Zero();
    for (int n : s.model.mesh.tets()[static_cast<size_t>(e)]) cen += 0.25 * s.model.mesh.rest_positions().col(n);
    EXPECT_NEAR(c.element_delay_s[static_cast<size_t>(e)], (cen - Vec3(0, 0, -0.02)).norm() / 0.5, 1e-15);
  }
  const sc::Scene r = sc::parse_scene(replace_once(yaml, "peak_tension: 60.0e3", "regions: {myocardium: 5.0e3}"), "lv.yaml");
  EXPECT_EQ(r.model.contraction.region_peak_pa, std::vector<double>({5e3}));
  expect_error(replace_once(yaml, "peak_tension: 60.0e3", "regions: {scar: 1.0}"), {"contraction.regions.scar", "myocardium"});
  expect_error(replace_once(yaml, "systole: 0.3", "systole: 2.0"), {"contraction.twitch.systole", "longer than the period"});
  expect_error(replace_once(yaml, "heart_rate: 75", "heart_rate: 75\n  period: 1.0"), {"heart_rate or period"});
  expect_error(replace_once(yaml, "speed: 0.5", "speed: 0"), {"contraction.pacing.speed"});
  expect_error(replace_once(yaml, "{shape: sine, systole: 0.3}", "{tau1: 0.2, tau2: 0.1}"), {"contraction.twitch", "tau2_s"});
  expect_error(replace_once(yaml, "peak_tension: 60.0e3", "regions: {}"), {"contraction.regions", "non-empty"});
  expect_error(replace_once(yaml, "fibers:", "  - name: myocardium\n    select: all\n    material: {E: 1.0e4, nu: 0.3, density: 1000}\nfibers:"),
               {"regions[1].name", "'myocardium' names an earlier region too"});
  expect_error(std::string(kLv) + "contraction:\n  peak_tension: 1.0\n  heart_rate: 200\n  twitch: {tau1: 0.1, tau2: 0.9}\n",
               {"contraction", "two periods"});
}

// measure.cavities: named boundary parts whose enclosed volume the run reports.
TEST(Scene, MeasureCavities) {
  const std::string yaml = std::string(kLv) + "measure:\n  cavities:\n    lv: {node_set: endo}\n";
  const sc::Scene s = sc::parse_scene(yaml, "lv.yaml");
  ASSERT_EQ(s.cavities.size(), 1u);
  EXPECT_EQ(s.cavities[0].name, "lv");
  EXPECT_EQ(s.cavities[0].surface.rim_nodes.size(), 18u);  // the endocardial base ring
  expect_error(replace_once(yaml, "{node_set: endo}", "{node_set: apex_endo}"), {"measure.cavities.lv", "no boundary triangle"});
  expect_error(replace_once(yaml, "{node_set: endo}", "{node_set: heart}"), {"measure.cavities.lv.node_set", "no node set 'heart'"});
  // The outer wall's triangles point the other way: a negative "cavity".
  expect_error(replace_once(yaml, "{node_set: endo}", "{node_set: epi}"), {"measure.cavities.lv", "select the cavity's own wall"});
}

// The archive key: defaults, every field, each bad value named with its key path; it
// leaves the scene's hash alone (recording does not change the run), and yaml_text parses
// back into the same scene.
TEST(Scene, ArchiveKey) {
  const sc::Scene plain = sc::parse_scene(kExample, "test.yaml");
  EXPECT_FALSE(plain.archive.enabled);
  const std::string yaml = std::string(kExample) +
                           "archive: {path: run.h5, flush_frames: 5, flush_seconds: 0.5, every: 3, velocities: true,"
                           " displacement: false, checkpoint_every: 2.5, compression: 1}\n";
  const sc::Scene s = sc::parse_scene(yaml, "test.yaml");
  EXPECT_TRUE(s.archive.enabled);
  EXPECT_EQ(s.archive.path, "run.h5");
  EXPECT_EQ(s.archive.flush_frames, 5);
  EXPECT_EQ(s.archive.flush_seconds, 0.5);
  EXPECT_EQ(s.archive.every_steps, 3);
  EXPECT_TRUE(s.archive.velocities);
  EXPECT_FALSE(s.archive.displacement);
  EXPECT_EQ(s.archive.checkpoint_every_s, 2.5);
  EXPECT_EQ(s.archive.compression, 1);
  EXPECT_EQ(s.hash_sha256, plain.hash_sha256);
  EXPECT_EQ(s.yaml_text.find("archive"), std::string::npos);
  EXPECT_EQ(sc::parse_scene(s.yaml_text, "again.yaml").hash_sha256, plain.hash_sha256);
  const sc::Scene d = sc::parse_scene(std::string(kExample) + "archive: {path: r.h5}\n", "test.yaml");
  EXPECT_EQ(d.archive.flush_frames, 10);
  EXPECT_EQ(d.archive.flush_seconds, 1.0);
  EXPECT_EQ(d.archive.every_steps, 1);
  EXPECT_TRUE(d.archive.displacement);
  EXPECT_EQ(d.archive.checkpoint_every_s, 1.0);
  EXPECT_EQ(d.archive.compression, 0);
  expect_error(std::string(kExample) + "archive: {flush_frames: 5}\n", {"archive.path"});
  expect_error(replace_once(yaml, "flush_frames: 5", "flush_frames: 0"), {"archive.flush_frames", "[1, 100000]"});
  expect_error(replace_once(yaml, "flush_seconds: 0.5", "flush_seconds: -1"), {"archive.flush_seconds"});
  expect_error(replace_once(yaml, "every: 3", "every: 0"), {"archive.every"});
  expect_error(replace_once(yaml, "velocities: true", "velocities: maybe"), {"archive.velocities"});
  expect_error(replace_once(yaml, "checkpoint_every: 2.5", "checkpoint_every: -2"), {"archive.checkpoint_every"});
  expect_error(replace_once(yaml, "compression: 1", "compression: 12"), {"archive.compression"});
  expect_error(replace_once(yaml, "compression: 1", "gzip: 1"), {"archive.gzip", "unknown key"});
}
