// A scene file (docs/scenes.md) into the engine's model and settings: the sections in the
// order they depend on each other (the mesh, then the regions on it, then what lives on
// regions and nodes), each read by its own file (io/scene_*.cpp).

#include "io/scene.hpp"

#include "io/scene_accurate.hpp"

#include "io/input_file.hpp"
#include "io/scene_internal.hpp"
#include "io/sha256.hpp"

#include <fstream>
#include <sstream>

namespace fiberfem::io {

namespace {

using detail::Fidelity;
using detail::SceneFiles;

const std::vector<std::string> kTopKeys = {"name",   "mesh",        "regions", "fibers",  "fixed",   "loads",
                                           "solver", "probes",      "contraction", "measure", "archive", "fidelity",
                                           "circulation"};

// The mesh with each element's region, the regions' materials and damping.
core::Model regions_model(const CheckedMap& top, SceneFiles& files, double refine, std::vector<std::string>& names,
                          SceneParameters& parameters, detail::MeshExtras& extras) {
  core::TetMesh mesh = detail::read_scene_mesh(top, files, refine, extras);
  detail::Regions regions = detail::read_regions(top, mesh);
  mesh.set_regions(std::move(regions.region_of));
  core::Model model(std::move(mesh));
  model.region_materials = std::move(regions.materials);
  std::vector<core::RayleighDamping> damping;
  bool any_damping = false;
  for (const RegionParameters& p : regions.parameters) {
    damping.push_back(p.damping.value_or(core::RayleighDamping{}));
    any_damping = any_damping || !damping.back().is_zero();
  }
  if (any_damping) model.region_damping = std::move(damping);
  names = std::move(regions.names);
  parameters.regions = std::move(regions.parameters);
  return model;
}

// fibers and contraction, on the regions' mesh.
void fibers_and_contraction(const CheckedMap& top, SceneFiles& files, Scene& scene) {
  core::Model& model = scene.model;
  model.set_uniform_fiber(core::Vec3::UnitX());
  if (top.has("fibers")) {
    FiberSpec spec;
    model.fibers = read_fibers(top.checks(), top["fibers"], model.mesh, files.base_dir, spec, &files.others, &scene.sheets);
    scene.parameters.fibers = spec;
  }
  if (top.has("contraction")) {
    ContractionSpec spec;
    model.contraction = read_contraction(top.checks(), top["contraction"], model.mesh, scene.region_names, spec);
    scene.parameters.contraction = spec;
  }
}

// solver over the fidelity preset's settings; mode and until.
void solver(const CheckedMap& top, const std::optional<Fidelity>& fidelity, Scene& scene) {
  core::SimulatorSettings base;
  if (fidelity) {
    base.dt_s = fidelity->dt_s;
    base.solver.tolerance = fidelity->tolerance;
    if (fidelity->cost_refresh) base.solver = core::with_cost_refresh(base.solver);
  }
  SolverSpec& spec = scene.parameters.solver;
  if (top.has("solver")) read_solver(top.checks(), top["solver"], spec);
  scene.settings = solver_settings(spec, base);
  scene.mode = spec.mode.value_or(Mode::dynamic);
  scene.until_s = spec.until_s.value_or(2.0);
  // A step larger than the requested fidelity's: the accuracy asked for is not what runs.
  if (fidelity && scene.mode == Mode::dynamic && scene.settings.dt_s > fidelity->dt_s * (1 + 1e-9)) {
    const YAML::Node s = top["solver"];
    const YAML::Node at = spec.dt_s && s.IsMap() ? YAML::Node(s["dt"]) : top["fidelity"];
    std::ostringstream w;
    w << "step " << scene.settings.dt_s << " s is larger than the '" << fidelity->name << "' preset's " << fidelity->dt_s
      << " s: the run will be less accurate than that preset (measured error against the step: docs/speed-accuracy.md)";
    top.checks().warn(at, "solver.dt", w.str());
  }
}

// The hash covers what determines the run: the scene as parsed (after overrides; comments
// and layout do not count) and the bytes of the files it reads (mesh, fibers, strokes).
// Recording (the archive key) does not change the run.
void text_and_hash(const YAML::Node& root, const SceneFiles& files, Scene& scene) {
  YAML::Node run_root = YAML::Clone(root);
  run_root.remove("archive");
  scene.yaml_text = emit(run_root);
  std::string hashed = scene.yaml_text;
  std::vector<std::string> hashed_files = files.others;
  if (!files.mesh_file.empty()) hashed_files.insert(hashed_files.begin(), files.mesh_file);
  for (const std::string& file : hashed_files) {
    std::string bytes;
    if (files.embedded && files.embedded->count(file)) {
      bytes = files.embedded->at(file);
    } else {
      std::ifstream mf(file, std::ios::binary);
      std::stringstream ss;
      ss << mf.rdbuf();
      bytes = ss.str();
    }
    hashed += "\n--- " + file.substr(file.rfind('/') + 1) + " ---\n" + bytes;
  }
  scene.hash_sha256 = sha256_hex(hashed);
}

}  // namespace

Scene parse_scene(const std::string& yaml_text, const std::string& origin, const std::string& base_dir,
                  const std::vector<std::string>& overrides, const EmbeddedFiles* embedded) {
  std::vector<std::string> overridden;
  for (const std::string& o : overrides) overridden.push_back(o.substr(0, o.find('=')));
  const Checks checks(origin, Dialect::scene, overridden);
  YAML::Node root = detail::load_document(yaml_text, origin);
  for (const std::string& o : overrides) detail::apply_override(root, o);
  const CheckedMap top(checks, root, "", kTopKeys);
  const std::optional<Fidelity> fidelity = detail::read_fidelity(top);

  SceneFiles files{base_dir, embedded, {}, {}};
  std::vector<std::string> region_names;
  SceneParameters parameters;
  detail::MeshExtras extras;
  Scene scene(regions_model(top, files, fidelity ? fidelity->refine : 1.0, region_names, parameters, extras));
  scene.mesh_order = extras.order;
  scene.lv_ellipsoid = extras.lv_ellipsoid;
  scene.file_elements = extras.file_elements;
  scene.region_names = std::move(region_names);
  scene.parameters = std::move(parameters);
  core::Model& model = scene.model;
  fibers_and_contraction(top, files, scene);
  detail::read_fixed(top, model);
  detail::read_loads(top, model, scene.parameters.gravity_m_s2);
  solver(top, fidelity, scene);
  scene.name = top.has("name") ? top.text("name") : origin;
  check_accurate(scene);
  scene.probes = detail::read_probes(top, model.mesh);
  try {
    model.validate();
    scene.settings.validate();
  } catch (const std::invalid_argument& e) {
    throw SceneError(origin + ": " + e.what());
  }
  scene.cavities = detail::read_cavities(top, model.mesh);
  if (top.has("circulation")) detail::read_circulation(top, scene.cavities, scene.accurate(), model);
  if (top.has("archive")) scene.archive = detail::read_archive(checks, top["archive"]);
  text_and_hash(root, files, scene);
  scene.base_dir = base_dir;
  scene.mesh_file = files.mesh_file;
  scene.warnings = checks.warnings();
  return scene;
}

std::string write_scene_parameters(const std::string& scene_yaml, const SceneParameters& p) {
  YAML::Node doc = YAML::Load(scene_yaml);
  YAML::Node regions = doc["regions"];
  for (size_t r = 0; r < p.regions.size(); ++r) {
    YAML::Node region = regions[r];
    region["material"] = write_material(p.regions[r].material);
    if (p.regions[r].damping) region["damping"] = write_damping(*p.regions[r].damping);
  }
  if (p.fibers) doc["fibers"] = write_fibers(*p.fibers);
  if (p.contraction) doc["contraction"] = write_contraction(*p.contraction);
  if (p.gravity_m_s2) doc["loads"]["gravity"] = detail::flow_vec3(*p.gravity_m_s2);
  const YAML::Node solver = write_solver(p.solver);
  if (solver.size() > 0) doc["solver"] = solver;
  for (const auto& [path, value] : p.circulation) set_key_path(doc["circulation"], path, value);
  return emit(doc);
}

Scene load_scene(const std::string& path, const std::vector<std::string>& overrides) {
  if (const std::string bad = input_file_problem(path); !bad.empty()) throw SceneError(path + ": cannot open the scene file: " + bad);
  std::ifstream f(path);
  if (!f) throw SceneError(path + ": cannot open the scene file");
  std::stringstream ss;
  ss << f.rdbuf();
  const size_t slash = path.rfind('/');
  return parse_scene(ss.str(), path, slash == std::string::npos ? "." : path.substr(0, slash), overrides);
}

}  // namespace fiberfem::io
