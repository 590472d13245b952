// Parameter commands (docs/commands.md): merged into the running scene's document, parsed
// as a scene file's section is (same keys, units and checks), applied to the engine, and
// only then written back into the document.

#include "service/run_control.hpp"

#include "service/command_args.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>

namespace fiberfem::service {

using detail::Args;
using detail::join;
using detail::Reject;
using detail::emit;
using core::Vec3;

namespace {

// Region ids named by an optional `region` argument (every region when absent).
std::vector<int> regions_of(const Args& a, const std::vector<std::string>& names) {
  if (!a.has("region")) {
    std::vector<int> all(names.size());
    for (size_t r = 0; r < names.size(); ++r) all[r] = static_cast<int>(r);
    return all;
  }
  const std::string name = a.text("region");
  const auto it = std::find(names.begin(), names.end(), name);
  if (it == names.end()) throw Reject("no region '" + name + "' (regions: " + join(names) + ")");
  return {static_cast<int>(it - names.begin())};
}

}  // namespace

const std::vector<std::vector<std::string>>& material_forms() {
  static const std::vector<std::vector<std::string>> forms = {
      {"E_L", "E_T", "nu_LT", "nu_T", "G_L"}, {"lame", "fiber_factor", "shear_factor"}, {"C"}, {"E", "nu"}};
  return forms;
}

CommandResult RunControl::on_set_material(const Args& a) {
  core::Simulator& sim = *sim_;
  const auto& names = scene_.region_names;
  YAML::Node doc = YAML::Load(scene_doc_);
  const std::vector<int> regions = regions_of(a, names);
  std::vector<std::pair<int, core::Material>> changes;
  std::vector<YAML::Node> merged_nodes;
  for (int r : regions) {
    YAML::Node m = YAML::Clone(doc["regions"][static_cast<size_t>(r)]["material"]);
    for (const auto& form : material_forms()) {
      const bool given = std::any_of(form.begin(), form.end(), [&](const std::string& k) { return a.has(k); });
      if (!given) continue;
      for (const auto& other : material_forms())  // switching form drops the old one's keys
        if (&other != &form)
          for (const auto& k : other) m.remove(k);
    }
    for (const auto& kv : a.node())
      if (kv.first.as<std::string>() != "region") m[kv.first.as<std::string>()] = kv.second;
    changes.emplace_back(r, io::parse_material(emit(m), "set_material(" + names[static_cast<size_t>(r)] + ")"));
    merged_nodes.push_back(m);
  }
  for (const auto& [r, mat] : changes) sim.set_region_material(r, mat);
  for (size_t i = 0; i < regions.size(); ++i) doc["regions"][static_cast<size_t>(regions[i])]["material"] = merged_nodes[i];
  scene_doc_ = emit(doc);
  return {true, "material of " + std::to_string(regions.size()) + " region(s) set"};
}

CommandResult RunControl::on_set_damping(const Args& a) {
  core::Simulator& sim = *sim_;
  const auto& names = scene_.region_names;
  YAML::Node doc = YAML::Load(scene_doc_);
  if (!a.has("mass") && !a.has("stiffness")) throw Reject("give mass (1/s) and/or stiffness (s)");
  const std::vector<int> regions = regions_of(a, names);
  std::vector<core::RayleighDamping> d(regions.size());
  for (size_t i = 0; i < regions.size(); ++i) {
    const auto& cur = sim.model().region_damping;
    if (!cur.empty()) d[i] = cur[static_cast<size_t>(regions[i])];
    if (a.has("mass")) d[i].mass_1_s = a.number("mass", 0, 1e6);
    if (a.has("stiffness")) d[i].stiffness_s = a.number("stiffness", 0, 10);
    d[i].validate();
  }
  for (size_t i = 0; i < regions.size(); ++i) {
    sim.set_region_damping(regions[i], d[i]);
    YAML::Node dn = doc["regions"][static_cast<size_t>(regions[i])]["damping"];
    dn["mass"] = d[i].mass_1_s;
    dn["stiffness"] = d[i].stiffness_s;
  }
  scene_doc_ = emit(doc);
  return {true, "damping of " + std::to_string(regions.size()) + " region(s) set"};
}

CommandResult RunControl::on_set_contraction(const Args& a) {
  core::Simulator& sim = *sim_;
  const core::TetMesh& mesh = sim_->model().mesh;
  const auto& names = scene_.region_names;
  YAML::Node doc = YAML::Load(scene_doc_);
  YAML::Node c = doc["contraction"].IsDefined() ? YAML::Clone(doc["contraction"]) : YAML::Node(YAML::NodeType::Map);
  if (a.has("heart_rate")) c.remove("period");
  if (a.has("period")) c.remove("heart_rate");
  if (a.has("peak_tension") && !a.has("regions")) c.remove("regions");
  for (const auto& kv : a.node()) {
    const std::string k = kv.first.as<std::string>();
    if (k == "twitch" && c["twitch"].IsMap() && kv.second.IsMap()) {
      for (const auto& t : kv.second) c["twitch"][t.first.as<std::string>()] = t.second;
    } else {
      c[k] = kv.second;
    }
  }
  sim.set_contraction(io::parse_contraction(emit(c), mesh, names, "set_contraction"));
  doc["contraction"] = c;
  scene_doc_ = emit(doc);
  return {true, "contraction set"};
}

CommandResult RunControl::on_set_fibers(const Args& a) {
  core::Simulator& sim = *sim_;
  const core::TetMesh& mesh = sim_->model().mesh;
  YAML::Node doc = YAML::Load(scene_doc_);
  sim.set_fibers(io::parse_fibers(emit(a.node()), mesh, scene_.base_dir, "set_fibers"));
  doc["fibers"] = YAML::Clone(a.node());
  scene_doc_ = emit(doc);
  ++topology_version_;
  return {true, "fibers set"};
}

CommandResult RunControl::on_set_gravity(const Args& a) {
  core::Simulator& sim = *sim_;
  YAML::Node doc = YAML::Load(scene_doc_);
  if (!a.has("gravity")) throw Reject("needs 'gravity': [gx, gy, gz] in m/s^2");
  const Vec3 g = a.vec3("gravity");
  if (g.norm() > 1e4) throw Reject("'gravity' is larger than 1e4 m/s^2");
  sim.set_gravity(g);
  base_loads_.gravity_m_s2 = g;
  doc["loads"]["gravity"] = std::vector<double>{g.x(), g.y(), g.z()};
  scene_doc_ = emit(doc);
  return {true, "gravity set"};
}

CommandResult RunControl::on_set_time_step(const Args& a) {
  core::Simulator& sim = *sim_;
  YAML::Node doc = YAML::Load(scene_doc_);
  if (!a.has("dt")) throw Reject("needs 'dt' in s");
  const double dt = a.number("dt", 1e-6, 10);
  sim.set_time_step(dt);
  doc["solver"]["dt"] = dt;
  scene_doc_ = emit(doc);
  return {true, "time step set"};
}

CommandResult RunControl::on_set_solver(const Args& a) {
  core::Simulator& sim = *sim_;
  YAML::Node doc = YAML::Load(scene_doc_);
  core::SolverSettings s = sim.settings().solver;
  if (a.has("method")) {
    const std::string m = a.text("method");
    if (m != "pcg" && m != "direct") throw Reject("'method' must be pcg or direct");
    s.method = m == "direct" ? core::LinearSolverKind::direct : core::LinearSolverKind::pcg;
  }
  if (a.has("preconditioner")) {
    const std::string p = a.text("preconditioner");
    if (p != "cholesky" && p != "block_jacobi" && p != "amg") throw Reject("'preconditioner' must be cholesky, block_jacobi or amg");
    s.preconditioner = p == "cholesky" ? core::PreconditionerKind::cholesky
                       : p == "amg"    ? core::PreconditionerKind::amg
                                       : core::PreconditionerKind::block_jacobi;
  }
  if (a.has("tolerance")) s.tolerance = a.number("tolerance", 1e-14, 0.5);
  if (a.has("max_iterations")) s.max_iterations = a.integer("max_iterations", 1, 1000000);
  if (a.has("recycled_solutions")) s.recycled_solutions = a.integer("recycled_solutions", 0, 64);
  core::RotationMethod rot = sim.settings().rotation;
  if (a.has("rotation")) {
    const std::string r = a.text("rotation");
    if (r != "polar" && r != "svd") throw Reject("'rotation' must be polar or svd");
    rot = r == "svd" ? core::RotationMethod::svd : core::RotationMethod::polar;
  }
  s.validate();
  sim.set_solver_settings(s);
  sim.set_rotation_method(rot);
  for (const auto& kv : a.node()) doc["solver"][kv.first.as<std::string>()] = kv.second;
  scene_doc_ = emit(doc);
  return {true, "solver settings set"};
}

}  // namespace fiberfem::service
