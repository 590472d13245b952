#include "service/batch_circulation.hpp"

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
  const cc::Parameters& p = engine.model().circulation.parameters;
  const cc::State& s = *engine.circulation_state();
  const cc::Observables o = cc::observe(p, s);
  // The coupled ventricles' volumes are the mesh's (equal to the loop's to the coupling's
  // tolerance); the other chambers' are the loop's.
  double volume[4] = {s.volume_m3[0], s.volume_m3[1], s.volume_m3[2], s.volume_m3[3]};
  const auto& cavities = engine.model().circulation.cavities;
  for (size_t k = 0; k < cavities.size(); ++k) volume[cavities[k].chamber] = engine.coupled_cavity_volumes()[k];
  static const char* const chambers[4] = {"la", "lv", "ra", "rv"};  // by ChamberId
  static const char* const compartments[4] = {"systemic_arterial", "systemic_venous", "pulmonary_arterial",
                                              "pulmonary_venous"};  // by CompartmentId
  static const char* const valves[4] = {"mitral", "aortic", "tricuspid", "pulmonary_valve"};  // by ValveId
  push("time_s", s.time_s);
  for (int i = 0; i < 4; ++i) {
    push(std::string(chambers[i]) + "_pressure_pa", o.chamber_pa[static_cast<size_t>(i)]);
    push(std::string(chambers[i]) + "_volume_m3", volume[i]);
    push(std::string(compartments[i]) + "_pressure_pa", s.pressure_pa[static_cast<size_t>(i)]);
    push(std::string(compartments[i]) + "_flow_m3_s", s.flow_m3_s[static_cast<size_t>(i)]);
    push(std::string(valves[i]) + "_flow_m3_s", o.valve_m3_s[static_cast<size_t>(i)]);
  }
  push("pressure_iterations", s.time_s > 0 ? engine.circulation_iterations() : 0);
  iterations_ += engine.circulation_iterations();
  max_iterations_ = std::max(max_iterations_, engine.circulation_iterations());
  max_drift_m3_ = std::max(max_drift_m3_, std::abs(cc::total_volume(p, s) - initial_blood_m3_));
  cc::Sample sample;
  sample.time_s = s.time_s;
  sample.volume_m3[0] = volume[cc::lv];
  sample.volume_m3[1] = volume[cc::rv];
  sample.pressure_pa[0] = o.chamber_pa[cc::lv];
  sample.pressure_pa[1] = o.chamber_pa[cc::rv];
  sample.arterial_pa[0] = s.pressure_pa[cc::ar_sys];
  sample.arterial_pa[1] = s.pressure_pa[cc::ar_pul];
  beats_.add(sample);
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
    const cc::VentricleBeat &l = b.ventricle[0], &r = b.ventricle[1];
    std::snprintf(line, sizeof line,
                  "circulation: beat %d%s: LV EDV %.4g mL ESV %.4g mL SV %.4g mL EF %.3f peak %.1f mmHg EDP %.1f mmHg; RV SV "
                  "%.4g mL EF %.3f peak %.1f mmHg; aortic %.0f/%.0f mmHg\n",
                  b.index, complete ? "" : " (partial)", l.end_diastolic_m3 / cc::kM3PerMl, l.end_systolic_m3 / cc::kM3PerMl,
                  l.stroke_m3 / cc::kM3PerMl, l.ejection_fraction, l.peak_pa / cc::kPaPerMmHg,
                  l.end_diastolic_pa / cc::kPaPerMmHg, r.stroke_m3 / cc::kM3PerMl, r.ejection_fraction,
                  r.peak_pa / cc::kPaPerMmHg, b.arterial_max_pa[0] / cc::kPaPerMmHg, b.arterial_min_pa[0] / cc::kPaPerMmHg);
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
