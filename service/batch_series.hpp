#pragma once
/// @file What a dynamic batch run measures step by step for its report
/// (docs/report-format.md): step and solver totals, and per-beat series of the cavity
/// volumes (the ejection fraction), each probe's displacement (the apex excursion) and,
/// when contracting, the volume-weighted mean fiber stretch |F f| (the peak shortening).

#include "service/run_driver.hpp"

#include "core/simulator.hpp"
#include "io/scene.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <iosfwd>
#include <vector>

namespace fiberfem::service::detail {

using json = nlohmann::ordered_json;

/// Sums and extremes of the step reports of a run.
struct StepTotals {
  std::vector<double> step_s;  ///< Engine time of each step, s.
  core::PhaseTimes total;
  long iterations = 0, factorizations = 0, substeps = 0;
  int max_iterations = 0, recovered = 0, max_inverted = 0;
  double max_residual = 0, max_kinetic_j = 0, max_speed_m_s = 0;
  void add(const core::StepReport& r);
  /// Report sections "steps", "timing", "solver", "energies" (from `initial` to the final
  /// state of `sim`) and "state" for `done` of `requested` steps in `wall_s`.
  void report(const io::Scene& sc, const core::Simulator& sim, const core::Energies& initial, int requested, int done,
              double wall_s, json& out) const;
};

/// A quantity sampled every step: its extremes over the run and per beat. The first beat
/// starts from the rest sample, and the sample at a beat's boundary belongs to both beats.
class BeatSeries {
 public:
  struct Range {
    double min = HUGE_VAL, max = -HUGE_VAL;
    long count = 0;
    void add(double v) { min = std::min(min, v), max = std::max(max, v), ++count; }
  };
  explicit BeatSeries(double rest);
  void add(double v);
  const Range& run() const { return run_; }
  /// Ends beat `index`: its entry is {beat, complete} plus what `describe(range, entry)` adds.
  template <class Describe>
  void close(long index, bool complete, Describe&& describe) {
    json entry = {{"beat", index}, {"complete", complete}};
    describe(beat_, entry);
    beats_.push_back(entry);
    beat_ = Range{};
    beat_.add(last_);
  }
  const json& beats() const { return beats_; }

 private:
  Range run_, beat_;
  double last_;
  json beats_ = json::array();
};

/// The per-beat series of a run. A beat is the contraction's period (the whole run
/// without one).
class RunSeries {
 public:
  /// From the rest state of `engine` (before any resume). On the accurate tier the
  /// probes and cavities are read on the corner nodes, and the fiber shortening is not
  /// recorded.
  RunSeries(const io::Scene& sc, const Engine& engine);
  /// After each accepted step, with the state's cavity volumes.
  void add(const Engine& engine, const CavityVolumes& volumes);
  /// Closes the last beat; adds the probes' series, "contraction" and "cavities" to the
  /// report and prints their summaries.
  void finish(const Engine& engine, json& report, std::ostream& out);

 private:
  long beat_of(double t) const;
  void close_beat(long beat, double now_s);
  double mean_fiber_stretch(const core::Simulator& sim) const;

  const io::Scene& sc_;
  double beat_period_s_, dt_s_, total_volume_m3_;
  bool contracting_;
  bool fiber_stretch_;  ///< The mean fiber shortening is recorded (the real-time tier's contracting runs).
  std::vector<core::Mat3> dm_inv_;  ///< Rest-shape inverse per element, with fiber_stretch_.
  std::vector<BeatSeries> volumes_, probe_u_;
  std::vector<double> rest_volume_m3_;
  BeatSeries stretch_{1.0};
  long current_beat_ = 0, steps_in_beat_ = 0;
};

}  // namespace fiberfem::service::detail
