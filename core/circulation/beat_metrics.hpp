#pragma once
/// @file Per-beat figures of a run (EDV, ESV, stroke volume, ejection fraction, peak and
/// end-diastolic pressures, arterial pressures) from per-step samples.

#include <string>
#include <vector>

namespace fiberfem::core::circulation {

/// One step's sample of what the beat figures read. SI units.
struct Sample {
  double time_s = 0;
  double volume_m3[2] = {0, 0};        ///< lv, rv.
  double pressure_pa[2] = {0, 0};      ///< lv, rv.
  double arterial_pa[2] = {0, 0};      ///< systemic, pulmonary arteries.
};

struct VentricleBeat {
  double end_diastolic_m3 = 0;   ///< Largest volume of the beat.
  double end_systolic_m3 = 0;    ///< Smallest volume of the beat.
  double stroke_m3 = 0;          ///< Their difference.
  double ejection_fraction = 0;  ///< stroke / end-diastolic.
  double peak_pa = 0;            ///< Largest pressure.
  double end_diastolic_pa = 0;   ///< Pressure where filling ends (the first sample within 1e-3 of the stroke below the largest volume).
};

struct Beat {
  int index = 0;             ///< 0 for the first beat.
  double start_s = 0;        ///< When the beat began.
  int samples = 0;
  VentricleBeat ventricle[2];  ///< lv, rv.
  double arterial_max_pa[2] = {0, 0};  ///< Systolic pressure: systemic, pulmonary.
  double arterial_min_pa[2] = {0, 0};  ///< Diastolic pressure.
};

/// A beat's figures in the physiology literature's units, one line: "LV EDV 26.22 mL ESV
/// 14.04 mL SV 12.17 mL EF 0.464 peak 17.3 mmHg EDP 2.9 mmHg; RV SV 12.03 mL EF 0.668 peak
/// 6.6 mmHg; aortic 17/10 mmHg".
std::string describe(const Beat& b);

/// Splits samples into beats of `period_s` counted from `origin_s` and reduces each.
class BeatRecorder {
 public:
  BeatRecorder(double period_s, double origin_s) : period_s_(period_s), origin_s_(origin_s) {}
  /// Adds a sample (times increasing); closes the beat under way when one begins.
  void add(const Sample& s);
  /// Closes the beat under way (at the end of a run), if it has samples.
  void finish();
  /// The beats closed so far.
  const std::vector<Beat>& beats() const { return beats_; }

 private:
  int beat_of(double t) const;
  void close();
  double period_s_, origin_s_;
  std::vector<Sample> current_;
  int current_index_ = -1;
  std::vector<Beat> beats_;
};

}  // namespace fiberfem::core::circulation
