// set_circulation (docs/commands.md, docs/circulation.md): the lumped loop's parameters of a
// run with a `circulation` section, by the section's own keys and units (read by the
// scene's reader over the running section, so the same checks), replaced between steps
// with the loop's state carried over. The keys it sets are kept in the parameter state
// (SceneParameters::circulation), so a checkpoint's scene text resumes with them.

#include "service/run_control.hpp"

#include "io/scene_sections.hpp"
#include "service/command_args.hpp"

#include <yaml-cpp/yaml.h>

#include <optional>

namespace fiberfem::service {

using detail::Args;
using detail::Reject;

namespace {

namespace cc = core::circulation;

// The chamber keys of the coupled ventricles (their loop entries are the mesh's).
void refuse_coupled_chambers(const std::map<std::string, double>& given, const cc::Coupling& coupling) {
  for (const cc::CoupledCavity& cav : coupling.cavities) {
    const std::string key = cav.chamber == cc::lv ? "chambers.left_ventricle" : "chambers.right_ventricle";
    const auto it = given.lower_bound(key);
    if (it != given.end() && it->first.compare(0, key.size(), key) == 0)
      throw Reject("'" + it->first + "': this ventricle is the mesh's cavity '" + cav.name +
                   "' (its pressure is solved with the mesh; its contraction is set_contraction's)");
  }
}

}  // namespace

YAML::Node RunControl::circulation_section() const {
  YAML::Node section = YAML::Clone(YAML::Load(scene_doc_)["circulation"]);
  for (const auto& [path, value] : params_.circulation) io::set_key_path(section, path, value);
  return section;
}

CommandResult RunControl::on_set_circulation(const Args& a) {
  const core::Model& model = engine_->model();
  if (!model.circulation.enabled()) throw Reject("this run has no circulation (its scene has no circulation key)");
  std::map<std::string, double> given;
  io::collect_numbers(a.node(), "", given);
  if (given.empty()) throw Reject("give the keys to change: heart_rate, chambers, valves, systemic, pulmonary (docs/circulation.md)");
  refuse_coupled_chambers(given, model.circulation);
  YAML::Node section = circulation_section();
  for (const auto& [path, value] : given) io::set_key_path(section, path, value);
  cc::Parameters p = io::read_circulation_loop(io::CheckedMap(a.checks(), section, "", io::circulation_keys()), model);
  if (!section["heart_rate"]) p.period_s = model.circulation.parameters.period_s;  // the running beat, however it came
  // One heart rate: the ventricles' contraction beats with the loop, keeping its phase too.
  std::optional<core::Contraction> contraction;
  io::ContractionSpec spec = params_.contraction.value_or(io::ContractionSpec{});
  if (given.count("heart_rate") && model.contraction.enabled()) {
    YAML::Node rate;
    rate["heart_rate"] = given["heart_rate"];
    contraction = io::read_contraction(a.checks(), rate, model.mesh, scene_.region_names, spec);
  }
  if (engine_->accurate() != nullptr) {
    // The accurate tier is rebuilt from the running scene, which reads the steered keys;
    // the loop's state carries over (AccurateEngine::rebuilt), its beat phase kept.
    io::SceneParameters before = params_;
    if (contraction) params_.contraction = spec;
    for (const auto& [path, value] : given) params_.circulation[path] = value;
    rebuild_accurate(std::move(before));
    return {true, "circulation set (" + std::to_string(given.size()) + " key(s))"};
  }
  engine_->set_circulation_parameters(p);
  if (contraction) {
    simulator().set_contraction(std::move(*contraction));
    params_.contraction = spec;
  }
  for (const auto& [path, value] : given) params_.circulation[path] = value;
  return {true, "circulation set (" + std::to_string(given.size()) + " key(s))"};
}

void RunControl::follow_contraction_rate() {
  // The accurate tier is rebuilt from the running scene, whose loop reads the new rate.
  if (engine_->real_time() == nullptr) return;
  const core::Model& model = engine_->model();
  if (!model.circulation.enabled() || !model.contraction.enabled() || circulation_section()["heart_rate"]) return;
  cc::Parameters p = model.circulation.parameters;
  if (p.period_s == model.contraction.period_s) return;
  p.period_s = model.contraction.period_s;
  engine_->set_circulation_parameters(p);
}

}  // namespace fiberfem::service
