// The scene's parameter sections (io/scene_sections.hpp): every writer against its reader,
// read(write(x)) == x for every form a section takes, with values that need all 17
// digits; the readers' merge rules (what a command's arguments do to the running value);
// and a whole scene written back from its parameters builds the same engine model.

#include "io/scene_sections.hpp"

#include "core/lv_ellipsoid.hpp"
#include "io/scene.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>

namespace fiberfem::io {
namespace {

using core::Vec3;

// Values whose shortest exact decimal has 17 digits: a writer that rounds loses them.
constexpr double kThird = 1.0 / 3.0;
constexpr double kTenth = 0.1 + 0.2;

const Checks& checks() {
  static const Checks c("test");
  return c;
}

// Specs are compared through their writer, which writes every field at full precision
// (two specs are equal exactly when they write the same text); the engine objects built
// from them are compared besides.
template <class Spec>
std::string text(const Spec& s);
template <>
std::string text(const MaterialSpec& s) { return emit(write_material(s)); }
template <>
std::string text(const ContractionSpec& s) { return emit(write_contraction(s)); }
template <>
std::string text(const FiberSpec& s) { return emit(write_fibers(s)); }
template <>
std::string text(const SolverSpec& s) { return emit(write_solver(s)); }

core::TetMesh lv_mesh() {
  core::LvEllipsoidSpec spec;
  spec.circumferential = 12;
  spec.longitudinal = 4;
  spec.transmural = 1;
  return core::make_lv_ellipsoid(spec);
}

void expect_material_round_trip(const MaterialSpec& x) {
  MaterialSpec y;
  const core::Material built = read_material(checks(), write_material(x), "material", y);
  EXPECT_EQ(text(y), text(x));
  EXPECT_EQ(y.form.index(), x.form.index());
  EXPECT_EQ(y.density_kg_m3, x.density_kg_m3);
  MaterialSpec again;
  EXPECT_EQ(read_material(checks(), write_material(y), "material", again).stiffness(), built.stiffness());
}

TEST(SceneSections, MaterialRoundTripsInEveryForm) {
  MaterialSpec m;
  m.density_kg_m3 = 1000 + kThird;
  m.form = core::EngineeringConstants{60e3 + kThird, 20e3 + kTenth, 0.45, 0.25 + kThird / 10, 8e3};
  expect_material_round_trip(m);
  m.form = core::LameFiberConstants{40e3 + kThird, 10e3, 3 + kTenth, 1.5};
  expect_material_round_trip(m);
  m.form = core::StiffnessConstants{120e3 + kThird, 40e3, 40e3, 160e3 + kTenth, 30e3};
  expect_material_round_trip(m);
  m.form = IsotropicConstants{30e3 + kThird, 0.3 + kTenth / 10};
  expect_material_round_trip(m);
}

// A command's keys: the same form merges, another form starts afresh (its keys needed).
TEST(SceneSections, MaterialKeysMergeWithinAFormAndReplaceAcrossForms) {
  MaterialSpec m;
  read_material(checks(), YAML::Load("{E_L: 60.0e3, E_T: 20.0e3, nu_LT: 0.25, nu_T: 0.45, G_L: 8.0e3, density: 1000}"),
                "material", m);
  read_material(checks(), YAML::Load("{E_L: 90.0e3, region: all}"), "material", m, {"region"});
  ASSERT_EQ(m.form.index(), 1u);
  EXPECT_EQ(std::get<1>(m.form).E_L, 90e3);
  EXPECT_EQ(std::get<1>(m.form).G_L, 8e3);
  EXPECT_THROW(read_material(checks(), YAML::Load("{E: 5.0e4}"), "material", m), SceneError);
  EXPECT_EQ(std::get<1>(m.form).E_L, 90e3);  // a refused read leaves the value alone
  read_material(checks(), YAML::Load("{E: 5.0e4, nu: 0.3}"), "material", m);
  ASSERT_EQ(m.form.index(), 4u);
  EXPECT_EQ(m.density_kg_m3, 1000);
}

TEST(SceneSections, DampingRoundTrips) {
  const core::RayleighDamping d{40 + kThird, 1e-3 + kTenth / 1000};
  const core::RayleighDamping r = read_damping(checks(), write_damping(d), "damping");
  EXPECT_EQ(r.mass_1_s, d.mass_1_s);
  EXPECT_EQ(r.stiffness_s, d.stiffness_s);
}

void expect_contraction_round_trip(const ContractionSpec& x, const core::TetMesh& mesh, const std::vector<std::string>& names) {
  ContractionSpec y;
  const core::Contraction a = read_contraction(checks(), write_contraction(x), mesh, names, y);
  EXPECT_EQ(text(y), text(x));
  ContractionSpec z;
  const core::Contraction b = read_contraction(checks(), write_contraction(y), mesh, names, z);
  EXPECT_EQ(a.period_s, b.period_s);
  EXPECT_EQ(a.region_peak_pa, b.region_peak_pa);
  EXPECT_EQ(a.element_delay_s, b.element_delay_s);
}

TEST(SceneSections, ContractionRoundTripsByHeartRatePeriodAndRegion) {
  core::TetMesh mesh = lv_mesh();
  std::vector<int> regions(static_cast<size_t>(mesh.num_elements()), 0);
  for (size_t e = 0; e < regions.size(); e += 2) regions[e] = 1;
  core::TetMesh two(mesh.rest_positions(), mesh.tets(), regions);
  const std::vector<std::string> names = {"septum", "free_wall"};
  ContractionSpec c;
  c.heart_rate_bpm = 72 + kThird;
  c.peak_tension_pa = 60e3 + kTenth;
  expect_contraction_round_trip(c, two, names);
  c.heart_rate_bpm.reset();
  c.period_s = 0.8 + kTenth / 10;
  c.mode = core::ContractionMode::nodal_forces;
  c.twitch = {core::TwitchShape::sine, 0.05, 0.11, 0.3 + kThird / 10};
  c.peak_tension_pa.reset();
  c.region_peak_pa = {{"free_wall", 5e3 + kThird}, {"septum", 1e3}};
  expect_contraction_round_trip(c, two, names);
  c.peak_tension_pa = 2e3;
  c.region_peak_pa = {{"septum", kThird}};
  c.twitch = {core::TwitchShape::biexponential, 0.04 + kTenth / 100, 0.12, 0.3};
  c.pacing = PacingSpec{{0.001, kTenth / 100, -0.02}, 0.5 + kThird};
  expect_contraction_round_trip(c, two, names);
}

// A command's keys onto the running contraction: a rate form replaces the other, twitch
// keys merge, a peak_tension alone drops the per-region tensions.
TEST(SceneSections, ContractionKeysMergeAsCommandsDo) {
  const core::TetMesh mesh = lv_mesh();
  const std::vector<std::string> names = {"myocardium"};
  ContractionSpec c;
  read_contraction(checks(), YAML::Load("{regions: {myocardium: 5000}, period: 1.0, twitch: {shape: sine, systole: 0.3}}"),
                   mesh, names, c);
  const core::Contraction r = read_contraction(checks(), YAML::Load("{heart_rate: 120, twitch: {systole: 0.2}}"), mesh, names, c);
  EXPECT_FALSE(c.period_s);
  EXPECT_EQ(*c.heart_rate_bpm, 120);
  EXPECT_EQ(c.twitch.shape, core::TwitchShape::sine);
  EXPECT_EQ(c.twitch.systole_s, 0.2);
  EXPECT_EQ(r.region_peak_pa, std::vector<double>{5000});
  const core::Contraction p = read_contraction(checks(), YAML::Load("{peak_tension: 7000}"), mesh, names, c);
  EXPECT_TRUE(c.region_peak_pa.empty());
  EXPECT_EQ(p.region_peak_pa, std::vector<double>{7000});
  // The merged value is checked whole: a period the running systole does not fit in.
  EXPECT_THROW(read_contraction(checks(), YAML::Load("{period: 0.1}"), mesh, names, c), SceneError);
  EXPECT_EQ(*c.heart_rate_bpm, 120);
}

void expect_fibers_round_trip(const FiberSpec& x, const core::TetMesh& mesh, const std::string& dir = "") {
  FiberSpec y;
  const std::vector<Vec3> a = read_fibers(checks(), write_fibers(x), mesh, dir, y);
  EXPECT_EQ(text(y), text(x));
  FiberSpec z;
  EXPECT_EQ(read_fibers(checks(), write_fibers(y), mesh, dir, z), a);
}

TEST(SceneSections, FibersRoundTripByUniformRuleStrokesAndFile) {
  const core::TetMesh mesh = lv_mesh();
  FiberSpec f;
  f.uniform = {1, kThird, kTenth};
  expect_fibers_round_trip(f, mesh);
  f.kind = FiberSpec::Kind::rule;
  f.rule.endo_angle_deg = 60 + kThird;
  f.rule.epi_angle_deg = -60 - kTenth;
  f.rule.apex_to_base = {0, kTenth, 1};
  expect_fibers_round_trip(f, mesh);  // inner and outer by default: the node sets endo and epi
  NodeSelector endo, epi;
  endo.node_set = "endo";
  epi.node_set = "epi";
  f.inner = endo;
  f.outer = epi;
  expect_fibers_round_trip(f, mesh);
  f.kind = FiberSpec::Kind::strokes;
  f.stroke_lines = {{{0.0085, 0, -0.015}, {0.0085, kThird * 1e-3, 0.004}}, {{-0.0085, 0, -0.01}, {-0.0085, kTenth * 1e-3, 0.004}}};
  f.stroke_radius_m = 0.004 + kThird * 1e-3;
  expect_fibers_round_trip(f, mesh);
  f.stroke_radius_m.reset();
  expect_fibers_round_trip(f, mesh);

  const std::string dir = ::testing::TempDir();
  {
    std::ofstream out(dir + "/scene_sections_fibers.txt");
    for (int e = 0; e < mesh.num_elements(); ++e) out << "0 " << (e % 3) << " 1\n";
  }
  f = FiberSpec{};
  f.kind = FiberSpec::Kind::file;
  f.file = "scene_sections_fibers.txt";
  expect_fibers_round_trip(f, mesh, dir);
  f.kind = FiberSpec::Kind::strokes;
  f.stroke_file = "scene_sections_strokes.txt";
  {
    std::ofstream out(dir + "/" + f.stroke_file);
    out << "0.0085 0 -0.015\n0.0085 0 0.004\n";
  }
  expect_fibers_round_trip(f, mesh, dir);
  std::remove((dir + "/scene_sections_fibers.txt").c_str());
  std::remove((dir + "/" + f.stroke_file).c_str());
}

TEST(SceneSections, NodeSelectorsRoundTrip) {
  const core::TetMesh mesh = lv_mesh();
  NodeSelector plane;
  plane.kind = NodeSelector::Kind::plane;
  plane.axis = 2;
  plane.value_m = mesh.rest_positions().row(2).maxCoeff() - kThird * 1e-12;
  plane.tol_m = 1e-9 + kTenth * 1e-12;
  NodeSelector box;
  box.kind = NodeSelector::Kind::box;
  box.lo_m = {-1, -kThird, -1};
  box.hi_m = {1, 1, -0.015 + kTenth * 1e-3};
  NodeSelector set;
  set.node_set = "base";
  for (const NodeSelector& x : {plane, box, set}) {
    NodeSelector y;
    const std::vector<int> nodes = read_node_selector(checks(), write_node_selector(x), "on", mesh, &y);
    EXPECT_EQ(emit(write_node_selector(y)), emit(write_node_selector(x)));
    EXPECT_EQ(read_node_selector(checks(), write_node_selector(y), "on", mesh), nodes);
  }
}

TEST(SceneSections, SolverRoundTripsEveryKey) {
  SolverSpec s;
  EXPECT_EQ(text(s), "{}");
  s.mode = Mode::static_;
  s.dt_s = 1.0 / 60 + kThird * 1e-4;
  s.method = core::LinearSolverKind::direct;
  s.tolerance = 1e-6 + kTenth * 1e-9;
  s.max_iterations = 321;
  s.rotation = core::RotationMethod::svd;
  s.preconditioner = core::PreconditionerKind::amg;
  s.warm_start = false;
  s.max_energy_gain = std::numeric_limits<double>::infinity();
  s.until_s = 2 + kThird;
  s.recycled_solutions = 5;
  s.threads = 3;
  s.corotation = false;
  s.jacobi_first = 25;
  SolverSpec y;
  read_solver(checks(), write_solver(s), y);
  EXPECT_EQ(text(y), text(s));
  EXPECT_TRUE(std::isinf(*y.max_energy_gain));
  EXPECT_EQ(solver_settings(y, {}).solver.jacobi_first, 25);
  const core::SimulatorSettings a = solver_settings(s, {}), b = solver_settings(y, {});
  EXPECT_EQ(a.dt_s, b.dt_s);
  EXPECT_EQ(a.solver.tolerance, b.solver.tolerance);
  s.max_energy_gain = 1e-3 + kThird * 1e-6;
  s.method = core::LinearSolverKind::pcg;
  s.preconditioner = core::PreconditionerKind::block_jacobi;
  s.rotation = core::RotationMethod::polar;
  s.mode = Mode::dynamic;
  s.jacobi_first = core::kJacobiFirstAuto;
  read_solver(checks(), write_solver(s), y);
  EXPECT_EQ(text(y), text(s));
  EXPECT_NE(text(y).find("jacobi_first: auto"), std::string::npos) << text(y);
}

// solver.jacobi_first: `auto`, 0 (off) or a count of iterations; anything else is an error
// naming the key.
TEST(SceneSections, SolverJacobiFirstTakesAutoOffOrACount) {
  for (const auto& [yaml, expected] : std::vector<std::pair<std::string, int>>{
           {"{jacobi_first: auto}", core::kJacobiFirstAuto}, {"{jacobi_first: 0}", 0}, {"{jacobi_first: 40}", 40}}) {
    SolverSpec y;
    read_solver(checks(), YAML::Load(yaml), y);
    EXPECT_EQ(solver_settings(y, {}).solver.jacobi_first, expected) << yaml;
  }
  EXPECT_EQ(solver_settings(SolverSpec{}, {}).solver.jacobi_first, core::kJacobiFirstAuto) << "the default";
  for (const char* bad : {"{jacobi_first: -1}", "{jacobi_first: sometimes}", "{jacobi_first: 2.5}"}) {
    SolverSpec y;
    try {
      read_solver(checks(), YAML::Load(bad), y);
      ADD_FAILURE() << bad << " was accepted";
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find("solver.jacobi_first"), std::string::npos) << e.what();
    }
  }
}

// A whole scene written back from its own parameters builds the same engine model.
TEST(SceneSections, SceneWrittenFromItsParametersBuildsTheSameModel) {
  const std::string yaml = R"(name: lv
mesh: {generator: lv_ellipsoid, resolution: {circumferential: 12, longitudinal: 4, transmural: 1}}
regions:
  - name: myocardium
    material: {lame: [40.0e3, 10.0e3], fiber_factor: 3.3333333333333335, density: 1000}
    damping: {mass: 2.5}
fibers: {rule: {endo_angle: 60, epi_angle: -60}}
fixed: [{node_set: base}]
loads: {gravity: [0, 0, -9.81]}
solver: {dt: 0.01, rotation: svd}
contraction: {heart_rate: 72.5, peak_tension: 10.0e3, pacing: {at: [0, 0, -0.02], speed: 0.5}}
)";
  const Scene a = parse_scene(yaml, "lv.yaml");
  const Scene b = parse_scene(write_scene_parameters(a.yaml_text, a.parameters), "written.yaml");
  EXPECT_EQ(b.model.region_materials[0].stiffness(), a.model.region_materials[0].stiffness());
  EXPECT_EQ(b.model.region_damping[0].mass_1_s, 2.5);
  EXPECT_EQ(b.model.fibers, a.model.fibers);
  EXPECT_EQ(b.model.contraction.period_s, a.model.contraction.period_s);
  EXPECT_EQ(b.model.contraction.element_delay_s, a.model.contraction.element_delay_s);
  EXPECT_EQ(b.model.loads.gravity_m_s2, a.model.loads.gravity_m_s2);
  EXPECT_EQ(b.settings.dt_s, a.settings.dt_s);
  EXPECT_EQ(b.settings.rotation, a.settings.rotation);
  EXPECT_EQ(b.model.fixed_dofs, a.model.fixed_dofs);
  EXPECT_EQ(write_scene_parameters(b.yaml_text, b.parameters), write_scene_parameters(a.yaml_text, a.parameters));
}

}  // namespace
}  // namespace fiberfem::io
