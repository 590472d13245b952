// Commands against a running scene (docs/commands.md). Every command is checked whole
// before anything changes; the engine's setters validate before they change a cache, so
// a rejected command leaves the run as it was.

#include "service/run_control.hpp"

#include <nlohmann/json.hpp>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace fiberfem::service {
namespace {

using core::Vec3;

// A rejected command: the message is the reason sent back in the ack.
struct Reject : std::runtime_error {
  using std::runtime_error::runtime_error;
};

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

std::string emit(const YAML::Node& n) {
  YAML::Emitter e;
  e << n;
  return e.c_str();
}

// The arguments of one command: a mapping whose keys are checked.
class Args {
 public:
  Args(const std::string& text, std::vector<std::string> allowed) : allowed_(std::move(allowed)) {
    try {
      node_ = YAML::Load(text.empty() ? "{}" : text);
    } catch (const YAML::Exception& e) {
      throw Reject("arguments are not valid JSON: " + e.msg);
    }
    if (node_.IsNull()) node_ = YAML::Node(YAML::NodeType::Map);
    if (!node_.IsMap()) throw Reject("arguments must be a JSON object");
    for (const auto& kv : node_) {
      if (!kv.first.IsScalar()) throw Reject("argument names must be words, not lists or objects");
      const std::string key = kv.first.as<std::string>();
      if (std::find(allowed_.begin(), allowed_.end(), key) == allowed_.end())
        throw Reject("unknown argument '" + key + "'" +
                     (allowed_.empty() ? " (this command takes none)" : " (allowed: " + join(allowed_) + ")"));
    }
  }
  bool has(const std::string& k) const { return node_[k].IsDefined() && !node_[k].IsNull(); }
  YAML::Node operator[](const std::string& k) const { return node_[k]; }
  const YAML::Node& node() const { return node_; }

  double number(const std::string& k, double lo, double hi) const { return as_number(node_[k], k, lo, hi); }
  int integer(const std::string& k, long lo, long hi) const {
    const double v = number(k, static_cast<double>(lo), static_cast<double>(hi));
    if (v != std::floor(v)) throw Reject("'" + k + "' must be a whole number");
    return static_cast<int>(v);
  }
  std::string text(const std::string& k) const {
    if (!node_[k].IsScalar()) throw Reject("'" + k + "' must be a string");
    return node_[k].as<std::string>();
  }
  bool boolean(const std::string& k) const {
    try {
      return node_[k].as<bool>();
    } catch (const YAML::Exception&) {
      throw Reject("'" + k + "' must be true or false");
    }
  }
  Vec3 vec3(const std::string& k) const { return as_vec3(node_[k], k); }

  static double as_number(const YAML::Node& n, const std::string& k, double lo, double hi) {
    double v = 0;
    try {
      if (!n.IsScalar()) throw Reject("");
      v = n.as<double>();
    } catch (const std::exception&) {
      throw Reject("'" + k + "' must be a number");
    }
    if (!std::isfinite(v)) throw Reject("'" + k + "' is not finite");
    if (v < lo || v > hi) {
      std::ostringstream os;
      os << "'" << k << "' = " << v << " is out of range [" << lo << ", " << hi << "]";
      throw Reject(os.str());
    }
    return v;
  }
  /// A node index: a whole number in [0, num_nodes).
  static int as_node(const YAML::Node& n, const std::string& k, int num_nodes) {
    const double v = as_number(n, k, 0, num_nodes - 1);
    if (v != std::floor(v)) throw Reject("'" + k + "' must be a whole number (a node index)");
    return static_cast<int>(v);
  }
  static std::string as_text(const YAML::Node& n, const std::string& k) {
    if (!n.IsScalar()) throw Reject("'" + k + "' must be a string");
    return n.as<std::string>();
  }
  static Vec3 as_vec3(const YAML::Node& n, const std::string& k) {
    if (!n.IsSequence() || n.size() != 3) throw Reject("'" + k + "' must be a list of three numbers");
    return {as_number(n[0], k + "[0]", -1e12, 1e12), as_number(n[1], k + "[1]", -1e12, 1e12),
            as_number(n[2], k + "[2]", -1e12, 1e12)};
  }

 private:
  std::vector<std::string> allowed_;
  YAML::Node node_;
};

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

// Material keys by form (io/scene.cpp): a command in one form replaces the others.
const std::vector<std::vector<std::string>> kMaterialForms = {
    {"E_L", "E_T", "nu_LT", "nu_T", "G_L"}, {"lame", "fiber_factor", "shear_factor"}, {"C"}, {"E", "nu"}};

}  // namespace

RunControl::RunControl(io::Scene scene, const io::EmbeddedFiles* files)
    : scene_(std::move(scene)),
      scene_doc_(scene_.yaml_text),
      sim_(std::make_unique<core::Simulator>(scene_.model, scene_.settings)),
      base_loads_(scene_.model.loads) {
  files_ = files;
}

std::string RunControl::parameter_state_json() const {
  nlohmann::json forces = nlohmann::json::array();
  for (const auto& [name, f] : forces_) {
    nlohmann::json fn = nlohmann::json::array();
    for (const core::Vec3& v : f.force_n) fn.push_back({v.x(), v.y(), v.z()});
    forces.push_back({{"name", name}, {"nodes", f.nodes}, {"force_n", fn},
                      {"until_s", std::isfinite(f.until_s) ? nlohmann::json(f.until_s) : nlohmann::json()}});
  }
  return nlohmann::json{{"scene_yaml", scene_doc_}, {"forces", forces}}.dump();
}

io::Scene RunControl::running_scene() const {
  io::Scene s = io::parse_scene(scene_doc_, scene_.name + " (running)", scene_.base_dir, {}, files_);
  s.archive = scene_.archive;
  return s;
}

void RunControl::restore_parameter_state(const std::string& text) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw std::invalid_argument(std::string("parameter state is not JSON: ") + e.what());
  }
  if (!j.is_object() || !j.contains("scene_yaml")) throw std::invalid_argument("parameter state has no scene_yaml");
  const std::string doc = j["scene_yaml"].get<std::string>();
  io::Scene s = io::parse_scene(doc, "parameter state", scene_.base_dir, {}, files_);
  std::map<std::string, AppliedForce> forces;
  for (const auto& f : j.value("forces", nlohmann::json::array())) {
    AppliedForce a;
    a.nodes = f.at("nodes").get<std::vector<int>>();
    for (const auto& v : f.at("force_n")) a.force_n.emplace_back(v.at(0).get<double>(), v.at(1).get<double>(), v.at(2).get<double>());
    if (f.contains("until_s") && !f["until_s"].is_null()) a.until_s = f["until_s"].get<double>();
    for (int n : a.nodes)
      if (n < 0 || n >= s.model.mesh.num_nodes()) throw std::invalid_argument("parameter state: force node out of range");
    forces[f.at("name").get<std::string>()] = a;
  }
  auto sim = std::make_unique<core::Simulator>(s.model, s.settings);
  sim_ = std::move(sim);
  base_loads_ = s.model.loads;
  forces_ = std::move(forces);
  scene_doc_ = doc;
  refresh_loads();
  ++topology_version_;
}

const std::vector<std::string>& RunControl::kinds() {
  static const std::vector<std::string> k = {
      "pause",       "resume",          "step",       "reset",         "shutdown",      "apply_force",
      "clear_force", "set_material",    "set_damping", "set_contraction", "set_fibers", "set_gravity",
      "set_time_step", "set_solver", "checkpoint", "restore"};
  return k;
}

double RunControl::heart_rate_bpm() const {
  const auto& c = sim_->model().contraction;
  return c.enabled() ? 60.0 / c.period_s : 0.0;
}

double RunControl::peak_tension_pa() const {
  const auto& c = sim_->model().contraction;
  if (!c.enabled()) return 0.0;
  return *std::max_element(c.region_peak_pa.begin(), c.region_peak_pa.end());
}

CommandResult RunControl::apply(const std::string& kind, const std::string& args) {
  try {
    CommandResult r = dispatch(kind, args);
    r.accepted = true;
    ++version_;
    return r;
  } catch (const Reject& e) {
    return {false, e.what()};
  } catch (const YAML::Exception& e) {  // a conversion no check above foresaw
    return {false, "arguments of '" + kind + "': " + e.msg};
  } catch (const std::exception& e) {  // the engine's or the scene parser's refusal
    return {false, e.what()};
  }
}

void RunControl::before_step() {
  bool changed = false;
  for (auto it = forces_.begin(); it != forces_.end();) {
    if (sim_->time_s() >= it->second.until_s - 1e-12) {
      it = forces_.erase(it);
      changed = true;
    } else {
      ++it;
    }
  }
  if (changed) refresh_loads();
}

bool RunControl::take_step_permission() {
  if (!paused_) return true;
  if (ordered_steps_ > 0) {
    --ordered_steps_;
    return true;
  }
  return false;
}

void RunControl::refresh_loads() {
  core::Loads loads = base_loads_;
  for (const auto& [name, f] : forces_)
    for (size_t i = 0; i < f.nodes.size(); ++i) loads.point_forces.push_back({f.nodes[i], f.force_n[i]});
  sim_->set_loads(loads);
}

CommandResult RunControl::dispatch(const std::string& kind, const std::string& text) {
  core::Simulator& sim = *sim_;
  const core::TetMesh& mesh = sim.model().mesh;
  const auto& names = scene_.region_names;

  if (kind == "pause") {
    Args a(text, {});
    paused_ = true;
    ordered_steps_ = 0;
    return {true, "paused"};
  }
  if (kind == "resume") {
    Args a(text, {});
    paused_ = false;
    ordered_steps_ = 0;
    return {true, "running"};
  }
  if (kind == "step") {
    Args a(text, {"count"});
    const int n = a.has("count") ? a.integer("count", 1, 1000000) : 1;
    paused_ = true;
    ordered_steps_ += n;
    return {true, std::to_string(n) + " steps ordered, then paused"};
  }
  if (kind == "shutdown") {
    Args a(text, {});
    shutdown_ = true;
    return {true, "shutting down"};
  }
  if (kind == "reset") {
    Args a(text, {"parameters"});
    const bool parameters = a.has("parameters") && a.boolean("parameters");
    if (parameters) {
      auto fresh = std::make_unique<core::Simulator>(scene_.model, scene_.settings);
      sim_ = std::move(fresh);
      scene_doc_ = scene_.yaml_text;
      base_loads_ = scene_.model.loads;
      forces_.clear();
      ++topology_version_;
      return {true, "reset to rest with the scene's parameters"};
    }
    sim.reset();
    return {true, "reset to rest"};
  }
  if (kind == "checkpoint") {
    Args a(text, {"name"});
    const std::string name = a.has("name") ? a.text("name") : "default";
    if (name.empty()) throw Reject("'name' must not be empty");
    checkpoints_[name] = Saved{sim.checkpoint(), parameter_state_json()};
    return {true, "checkpoint '" + name + "' at t = " + std::to_string(sim.time_s()) + " s"};
  }
  if (kind == "restore") {
    Args a(text, {"name"});
    const std::string name = a.has("name") ? a.text("name") : "default";
    const auto it = checkpoints_.find(name);
    if (it == checkpoints_.end()) {
      std::vector<std::string> names;
      for (const auto& kv : checkpoints_) names.push_back(kv.first);
      throw Reject("no checkpoint '" + name + "'" + (names.empty() ? " (none saved)" : " (saved: " + join(names) + ")"));
    }
    // Parameters changed since: rebuild for the saved ones first (the state only fits them).
    if (it->second.parameters != parameter_state_json()) restore_parameter_state(it->second.parameters);
    sim_->restore(it->second.state);
    return {true, "restored '" + name + "' (t = " + std::to_string(sim_->time_s()) + " s)"};
  }
  if (kind == "apply_force") {
    Args a(text, {"name", "target", "force", "magnitude", "along", "duration"});
    if (!a.has("target")) throw Reject("needs 'target': {node | nodes | node_set | region | point}");
    const YAML::Node t = a["target"];
    if (!t.IsMap() || t.size() != 1)
      throw Reject("'target' must be an object with exactly one of node, nodes, node_set, region, point");
    const std::string how = Args::as_text(t.begin()->first, "target's key");
    const YAML::Node v = t.begin()->second;
    std::vector<int> nodes;
    const int nn = mesh.num_nodes();
    if (how == "node") {
      nodes = {Args::as_node(v, "target.node", nn)};
    } else if (how == "nodes") {
      if (!v.IsSequence() || v.size() == 0) throw Reject("'target.nodes' must be a non-empty list of node indices");
      std::vector<char> seen(static_cast<size_t>(nn), 0);
      for (size_t i = 0; i < v.size(); ++i) {
        const std::string key = "target.nodes[" + std::to_string(i) + "]";
        nodes.push_back(Args::as_node(v[i], key, nn));
        if (seen[static_cast<size_t>(nodes.back())]++)
          throw Reject("'" + key + "' = " + std::to_string(nodes.back()) + " is listed twice (the force is shared among distinct nodes)");
      }
    } else if (how == "node_set") {
      const std::string s = Args::as_text(v, "target.node_set");
      const auto it = mesh.node_sets().find(s);
      if (it == mesh.node_sets().end()) {
        std::vector<std::string> sets;
        for (const auto& kv : mesh.node_sets()) sets.push_back(kv.first);
        throw Reject("no node set '" + s + "' (node sets: " + join(sets) + ")");
      }
      nodes = it->second;
    } else if (how == "region") {
      const std::string s = Args::as_text(v, "target.region");
      const auto it = std::find(names.begin(), names.end(), s);
      if (it == names.end()) throw Reject("no region '" + s + "' (regions: " + join(names) + ")");
      const int r = static_cast<int>(it - names.begin());
      std::vector<char> in(static_cast<size_t>(nn), 0);
      for (int e = 0; e < mesh.num_elements(); ++e)
        if (mesh.regions()[static_cast<size_t>(e)] == r)
          for (int n : mesh.tets()[static_cast<size_t>(e)]) in[static_cast<size_t>(n)] = 1;
      for (int n = 0; n < nn; ++n)
        if (in[static_cast<size_t>(n)]) nodes.push_back(n);
    } else if (how == "point") {
      // The node nearest the point in the current (deformed) configuration: what a user
      // who clicks on the drawn mesh means.
      const Vec3 p = Args::as_vec3(v, "target.point");
      const auto x = sim.positions();
      int best = 0;
      double best_d = HUGE_VAL;
      for (int n = 0; n < nn; ++n) {
        const double d = (x.col(n) - p).squaredNorm();
        if (d < best_d) best_d = d, best = n;
      }
      nodes = {best};
    } else {
      throw Reject("unknown target '" + how + "' (node, nodes, node_set, region, point)");
    }
    AppliedForce f;
    f.nodes = nodes;
    const double share = 1.0 / static_cast<double>(nodes.size());
    if (a.has("force") == a.has("magnitude")) throw Reject("give exactly one of 'force' [N, N, N] and 'magnitude' (N, with along)");
    if (a.has("force")) {
      if (a.has("along")) throw Reject("'along' goes with 'magnitude'");
      const Vec3 total = a.vec3("force");
      f.force_n.assign(nodes.size(), total * share);
    } else {
      const double mag = a.number("magnitude", -1e9, 1e9);
      if (!a.has("along") || a.text("along") != "fibers") throw Reject("'magnitude' needs along: fibers");
      // Along the fibers: each node's direction is the sum of the rest fibers of the
      // elements around it, sign-aligned to the first (a fiber has no sign).
      std::vector<Vec3> dir(static_cast<size_t>(nn), Vec3::Zero());
      const auto& fib = sim.model().fibers;
      for (int e = 0; e < mesh.num_elements(); ++e) {
        const Vec3 fe = fib.empty() ? Vec3(1, 0, 0) : fib[static_cast<size_t>(e)];
        for (int n : mesh.tets()[static_cast<size_t>(e)]) {
          Vec3& d = dir[static_cast<size_t>(n)];
          d += d.dot(fe) < 0 ? -fe : fe;
        }
      }
      for (int n : nodes) {
        Vec3 d = dir[static_cast<size_t>(n)];
        if (d.norm() == 0) throw Reject("node " + std::to_string(n) + " has no element to take a fiber from");
        f.force_n.push_back(d.normalized() * mag * share);
      }
    }
    if (a.has("duration")) f.until_s = sim.time_s() + a.number("duration", 1e-9, 1e9);
    const std::string name = a.has("name") ? a.text("name") : "force-" + std::to_string(++force_counter_);
    if (name.empty()) throw Reject("'name' must not be empty");
    auto saved = forces_;
    forces_[name] = f;
    try {
      refresh_loads();
    } catch (...) {
      forces_ = std::move(saved);
      refresh_loads();
      throw;
    }
    return {true, "force '" + name + "' on " + std::to_string(nodes.size()) + " node(s)"};
  }
  if (kind == "clear_force") {
    Args a(text, {"name"});
    if (a.has("name")) {
      const std::string name = a.text("name");
      if (!forces_.erase(name)) throw Reject("no force named '" + name + "'");
    } else {
      forces_.clear();
    }
    refresh_loads();
    return {true, "cleared"};
  }

  // Parameter commands: merged into the running scene's document, parsed as a scene file's
  // section is, applied, and only then written back into the document.
  YAML::Node doc = YAML::Load(scene_doc_);
  if (kind == "set_material") {
    std::vector<std::string> allowed = {"region", "density"};
    for (const auto& form : kMaterialForms) allowed.insert(allowed.end(), form.begin(), form.end());
    Args a(text, allowed);
    const std::vector<int> regions = regions_of(a, names);
    std::vector<std::pair<int, core::Material>> changes;
    std::vector<YAML::Node> merged_nodes;
    for (int r : regions) {
      YAML::Node m = YAML::Clone(doc["regions"][static_cast<size_t>(r)]["material"]);
      for (const auto& form : kMaterialForms) {
        const bool given = std::any_of(form.begin(), form.end(), [&](const std::string& k) { return a.has(k); });
        if (!given) continue;
        for (const auto& other : kMaterialForms)  // switching form drops the old one's keys
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
  if (kind == "set_damping") {
    Args a(text, {"region", "mass", "stiffness"});
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
  if (kind == "set_contraction") {
    Args a(text, {"mode", "peak_tension", "heart_rate", "period", "twitch", "regions", "pacing"});
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
  if (kind == "set_fibers") {
    Args a(text, {"uniform", "rule", "strokes", "file"});
    sim.set_fibers(io::parse_fibers(text, mesh, scene_.base_dir, "set_fibers"));
    doc["fibers"] = YAML::Clone(a.node());
    scene_doc_ = emit(doc);
    ++topology_version_;
    return {true, "fibers set"};
  }
  if (kind == "set_gravity") {
    Args a(text, {"gravity"});
    if (!a.has("gravity")) throw Reject("needs 'gravity': [gx, gy, gz] in m/s^2");
    const Vec3 g = a.vec3("gravity");
    if (g.norm() > 1e4) throw Reject("'gravity' is larger than 1e4 m/s^2");
    sim.set_gravity(g);
    base_loads_.gravity_m_s2 = g;
    doc["loads"]["gravity"] = std::vector<double>{g.x(), g.y(), g.z()};
    scene_doc_ = emit(doc);
    return {true, "gravity set"};
  }
  if (kind == "set_time_step") {
    Args a(text, {"dt"});
    if (!a.has("dt")) throw Reject("needs 'dt' in s");
    const double dt = a.number("dt", 1e-6, 10);
    sim.set_time_step(dt);
    doc["solver"]["dt"] = dt;
    scene_doc_ = emit(doc);
    return {true, "time step set"};
  }
  if (kind == "set_solver") {
    Args a(text, {"method", "tolerance", "max_iterations", "preconditioner", "rotation", "recycled_solutions"});
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
  throw Reject("unknown command '" + kind + "' (commands: " + join(kinds()) + ")");
}

}  // namespace fiberfem::service
