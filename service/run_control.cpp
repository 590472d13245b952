// Commands against a running scene (docs/commands.md). Every command is checked whole
// before anything changes; the engine's setters validate before they change a cache, so
// a rejected command leaves the run as it was.

#include "service/run_control.hpp"

#include "io/scene_sections.hpp"
#include "service/command_args.hpp"
#include "service/engine_accurate.hpp"

#include <nlohmann/json.hpp>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace fiberfem::service {

using detail::Args;
using detail::join;
using detail::Reject;

RunControl::RunControl(io::Scene scene, const io::EmbeddedFiles* files)
    : scene_(std::move(scene)),
      scene_doc_(scene_.yaml_text),
      params_(scene_.parameters),
      engine_(make_engine(scene_)),
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
  return nlohmann::json{{"scene_yaml", scene_text()}, {"forces", forces}}.dump();
}

const std::string& RunControl::scene_text() const {
  if (scene_text_.empty()) scene_text_ = io::write_scene_parameters(scene_doc_, params_);
  return scene_text_;
}

io::Scene RunControl::running_scene() const {
  io::Scene s = io::parse_scene(scene_text(), scene_.name + " (running)", scene_.base_dir, {}, files_);
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
  auto engine = make_engine(s);
  engine_ = std::move(engine);
  base_loads_ = s.model.loads;
  forces_ = std::move(forces);
  scene_doc_ = doc;
  params_ = std::move(s.parameters);
  scene_text_.clear();
  refresh_loads();
  ++topology_version_;
}

// The commands: each kind with the arguments it allows and its handler (one file per
// family: run_control_flow.cpp, run_control_forces.cpp, run_control_parameters.cpp; the
// recording commands go to the handler the service sets).
const std::vector<RunControl::Entry>& RunControl::table() {
  static const std::vector<Entry> t = [] {
    std::vector<std::string> material = {"region", "density"};
    for (const std::string& k : io::material_keys())
      if (k != "density") material.push_back(k);
    for (const std::string& k : io::law_material_keys())
      if (std::find(material.begin(), material.end(), k) == material.end()) material.push_back(k);
    return std::vector<Entry>{
        {"pause", {}, &RunControl::on_pause, true},
        {"resume", {}, &RunControl::on_resume, true},
        {"step", {"count"}, &RunControl::on_step, true},
        {"reset", {"parameters"}, &RunControl::on_reset, true},
        {"shutdown", {}, &RunControl::on_shutdown, true},
        {"apply_force", {"name", "target", "force", "magnitude", "along", "duration"}, &RunControl::on_apply_force, true, false},
        {"clear_force", {"name"}, &RunControl::on_clear_force, true, false},
        {"set_material", material, &RunControl::on_set_material, true},
        {"set_damping", {"region", "mass", "stiffness"}, &RunControl::on_set_damping, true},
        {"set_contraction", {"mode", "peak_tension", "heart_rate", "period", "twitch", "regions", "pacing"},
         &RunControl::on_set_contraction, true},
        {"set_fibers", {"uniform", "rule", "strokes", "file"}, &RunControl::on_set_fibers, true},
        {"set_gravity", {"gravity"}, &RunControl::on_set_gravity, true},
        {"set_time_step", {"dt"}, &RunControl::on_set_time_step, true},
        {"set_solver", {"method", "tolerance", "max_iterations", "preconditioner", "rotation", "recycled_solutions"},
         &RunControl::on_set_solver, true},
        {"set_circulation", {"heart_rate", "chambers", "valves", "systemic", "pulmonary"}, &RunControl::on_set_circulation, true},
        {"checkpoint", {"name"}, &RunControl::on_checkpoint, true},
        {"restore", {"name"}, &RunControl::on_restore, true},
        {"start_recording", {}, nullptr, false},
        {"stop_recording", {}, nullptr, false},
    };
  }();
  return t;
}

const std::vector<std::string>& RunControl::kinds() {
  static const std::vector<std::string> k = [] {
    std::vector<std::string> names;
    for (const Entry& e : table()) names.push_back(e.kind);
    return names;
  }();
  return k;
}

core::Simulator& RunControl::simulator() {
  core::Simulator* sim = engine_->real_time();
  if (sim == nullptr) throw std::logic_error("scene '" + scene_.name + "' runs on the accurate tier: it has no real-time simulator");
  return *sim;
}

double RunControl::heart_rate_bpm() const {
  const auto& c = engine_->model().contraction;
  return c.enabled() ? 60.0 / c.period_s : 0.0;
}

double RunControl::peak_tension_pa() const {
  const auto& c = engine_->model().contraction;
  if (!c.enabled()) return 0.0;
  return *std::max_element(c.region_peak_pa.begin(), c.region_peak_pa.end());
}

CommandResult RunControl::apply(const std::string& kind, const std::string& args) {
  try {
    const auto& t = table();
    const auto entry = std::find_if(t.begin(), t.end(), [&](const Entry& e) { return e.kind == kind; });
    if (entry == t.end()) throw Reject("unknown command '" + kind + "' (commands: " + join(kinds()) + ")");
    if (!entry->handler) {  // start_recording / stop_recording: the service's
      if (!recording_) return {false, "this run does not record (" + kind + " is for a service)"};
      return recording_(kind, args);
    }
    const Args a(args, entry->args);
    if (entry->changes_parameters) scene_text_.clear();  // before: a handler may change params_ and then throw
    CommandResult r = (this->*entry->handler)(a);
    r.accepted = true;
    if (entry->changes_run) ++version_;
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
    if (engine_->time_s() >= it->second.until_s - 1e-12) {
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
  if (core::Simulator* sim = engine_->real_time()) sim->set_loads(loads);
  else engine_->accurate()->set_point_forces(loads.point_forces);
}

void RunControl::rebuild_accurate(io::SceneParameters before) {
  AccurateEngine* accurate = engine_->accurate();
  if (accurate == nullptr) return;
  scene_text_.clear();
  try {
    engine_ = accurate->rebuilt(running_scene());
  } catch (...) {
    params_ = std::move(before);
    scene_text_.clear();
    throw;
  }
}

}  // namespace fiberfem::service
