#include "service/batch_circulation.hpp"

#include "core/circulation/snapshot.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ostream>

namespace fiberfem::service::detail {
namespace {

namespace cc = core::circulation;
using json = nlohmann::ordered_json;

json ventricle_json(const cc::VentricleBeat& v) {
  return {{"end_diastolic_volume_m3", v.end_diastolic_m3}, {"end_systolic_volume_m3", v.end_systolic_m3},
          {"stroke_volume_m3", v.stroke_m3},              {"ejection_fraction", v.ejection_fraction},
          {"peak_pressure_pa", v.peak_pa},                {"end_diastolic_pressure_pa", v.end_diastolic_pa}};
}

}  // namespace

CirculationSeries::CirculationSeries(const io::Scene& sc, const Engine& engine)
    : enabled_(sc.model.circulation.enabled()), sc_(sc), beats_(sc.model.circulation.parameters.period_s, 0.0) {
  if (enabled_) initial_blood_m3_ = cc::total_volume(engine.model().circulation.parameters, *engine.circulation_state());
}

void CirculationSeries::push(const std::string& column, double value) {
  auto [it, fresh] = series_.try_emplace(column);
  if (fresh) order_.push_back(column);
  it->second.push_back(value);
}

void CirculationSeries::add(const Engine& engine) {
  if (!enabled_) return;
  const cc::Coupling& coupling = engine.model().circulation;
  const cc::State& s = *engine.circulation_state();
  if (!beats_started_) {
    // Beats counted from where the loop counts them: a run resumed from a served run whose
    // heart rate was changed continues from a moved origin (keep_beat_phase).
    beats_ = cc::BeatRecorder(coupling.parameters.period_s, s.beat_origin_s);
    beats_started_ = true;
  }
  const int iterations = s.time_s > 0 ? engine.circulation_iterations() : 0;
  const cc::Snapshot snap = cc::observe_snapshot(coupling, s, engine.coupled_cavity_volumes(), iterations);
  const std::vector<double> numbers = cc::to_columns(snap);
  for (size_t c = 0; c < cc::kStepColumns; ++c) push(cc::snapshot_columns()[c], numbers[c]);
  iterations_ += engine.circulation_iterations();
  max_iterations_ = std::max(max_iterations_, engine.circulation_iterations());
  max_drift_m3_ = std::max(max_drift_m3_, std::abs(snap.blood_volume_m3 - initial_blood_m3_));
  beats_.add(cc::beat_sample(snap));
}

void CirculationSeries::finish(json& report, std::ostream& out) {
  if (!enabled_) return;
  beats_.finish();
  const double period = sc_.model.circulation.parameters.period_s;
  json beats = json::array();
  char line[512];
  for (const cc::Beat& b : beats_.beats()) {
    // A beat is complete when its samples span the period (to half a step).
    const double dt = sc_.settings.dt_s;
    const bool complete = b.samples > 0 && b.samples * dt > period - 0.5 * dt;
    beats.push_back({{"beat", b.index},
                     {"complete", complete},
                     {"start_s", b.start_s},
                     {"lv", ventricle_json(b.ventricle[0])},
                     {"rv", ventricle_json(b.ventricle[1])},
                     {"systemic_arterial_max_pa", b.arterial_max_pa[0]},
                     {"systemic_arterial_min_pa", b.arterial_min_pa[0]},
                     {"pulmonary_arterial_max_pa", b.arterial_max_pa[1]},
                     {"pulmonary_arterial_min_pa", b.arterial_min_pa[1]}});
    std::snprintf(line, sizeof line, "circulation: beat %d%s: %s\n", b.index, complete ? "" : " (partial)", cc::describe(b).c_str());
    out << line;
  }
  json steps = json::object();
  for (const std::string& c : order_) steps[c] = series_[c];
  const long n = static_cast<long>(series_["time_s"].size());
  std::snprintf(line, sizeof line,
                "circulation: blood volume %.6g mL, largest drift %.3g mL; %.2f pressure iterations/step (at most %d)\n",
                initial_blood_m3_ / cc::kM3PerMl, max_drift_m3_ / cc::kM3PerMl, n > 0 ? static_cast<double>(iterations_) / n : 0.0,
                max_iterations_);
  out << line;
  json cavities = json::object();
  for (const cc::CoupledCavity& c : sc_.model.circulation.cavities) cavities[c.chamber == cc::lv ? "lv" : "rv"] = c.name;
  report["circulation"] = {{"period_s", period},
                           {"coupled_cavities", cavities},
                           {"blood_volume_m3", initial_blood_m3_},
                           {"max_blood_volume_drift_m3", max_drift_m3_},
                           {"pressure_iterations_per_step", n > 0 ? static_cast<double>(iterations_) / n : 0.0},
                           {"steps", steps},
                           {"beats", beats}};
}

}  // namespace fiberfem::service::detail
