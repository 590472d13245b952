#pragma once
/// @file What a dynamic batch run reports of the lumped circulation (docs/report-format.md,
/// section `circulation`): per-step pressures, volumes and flows, and per-beat figures
/// (EDV, ESV, stroke volume, EF, peak and end-diastolic pressures, arterial pressures).

#include "core/circulation/beat_metrics.hpp"
#include "service/engine.hpp"
#include "io/scene.hpp"

#include <nlohmann/json.hpp>

#include <iosfwd>
#include <map>
#include <string>
#include <vector>

namespace fiberfem::service::detail {

class CirculationSeries {
 public:
  /// Off (every call a no-op) unless the scene has a `circulation` key.
  CirculationSeries(const io::Scene& sc, const Engine& engine);
  /// After each accepted step.
  void add(const Engine& engine);
  /// Adds "circulation" to the report and prints a line per beat.
  void finish(nlohmann::ordered_json& report, std::ostream& out);

 private:
  bool enabled_;
  const io::Scene& sc_;
  core::circulation::BeatRecorder beats_;  // made at the first step, from the loop's beat origin then
  bool beats_started_ = false;
  std::map<std::string, std::vector<double>> series_;  // per-step columns, SI
  std::vector<std::string> order_;                     // column order of the report
  double initial_blood_m3_ = 0, max_drift_m3_ = 0;
  long iterations_ = 0;
  int max_iterations_ = 0;
  void push(const std::string& column, double value);
};

}  // namespace fiberfem::service::detail
