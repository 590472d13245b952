#include "core/circulation/beat_metrics.hpp"

#include "core/circulation/circulation.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace fiberfem::core::circulation {

std::string describe(const Beat& b) {
  const VentricleBeat &l = b.ventricle[0], &r = b.ventricle[1];
  char line[320];
  std::snprintf(line, sizeof line,
                "LV EDV %.4g mL ESV %.4g mL SV %.4g mL EF %.3f peak %.1f mmHg EDP %.1f mmHg; RV SV %.4g mL EF %.3f peak %.1f mmHg; "
                "aortic %.0f/%.0f mmHg",
                l.end_diastolic_m3 / kM3PerMl, l.end_systolic_m3 / kM3PerMl, l.stroke_m3 / kM3PerMl, l.ejection_fraction,
                l.peak_pa / kPaPerMmHg, l.end_diastolic_pa / kPaPerMmHg, r.stroke_m3 / kM3PerMl, r.ejection_fraction,
                r.peak_pa / kPaPerMmHg, b.arterial_max_pa[0] / kPaPerMmHg, b.arterial_min_pa[0] / kPaPerMmHg);
  return line;
}

int BeatRecorder::beat_of(double t) const {
  // A sample at the end of a step that ends a beat (t = k T up to round-off) belongs to it.
  return static_cast<int>(std::ceil((t - origin_s_) / period_s_ - 1e-9)) - 1;
}

void BeatRecorder::add(const Sample& s) {
  const int b = std::max(0, beat_of(s.time_s));
  if (b != current_index_ && !current_.empty()) close();
  current_index_ = b;
  current_.push_back(s);
}

void BeatRecorder::finish() {
  if (!current_.empty()) close();
}

void BeatRecorder::close() {
  Beat beat;
  beat.index = current_index_;
  beat.start_s = origin_s_ + current_index_ * period_s_;
  beat.samples = static_cast<int>(current_.size());
  for (int k = 0; k < 2; ++k) {
    VentricleBeat& v = beat.ventricle[k];
    const auto by_volume = [k](const Sample& a, const Sample& b) { return a.volume_m3[k] < b.volume_m3[k]; };
    const auto [lo, hi] = std::minmax_element(current_.begin(), current_.end(), by_volume);
    v.end_diastolic_m3 = hi->volume_m3[k];
    v.end_systolic_m3 = lo->volume_m3[k];
    v.stroke_m3 = v.end_diastolic_m3 - v.end_systolic_m3;
    v.ejection_fraction = v.end_diastolic_m3 > 0 ? v.stroke_m3 / v.end_diastolic_m3 : 0;
    // End-diastolic pressure: where filling ends, the first sample within 1e-3 of the
    // stroke below the largest volume; not at the largest volume itself, which may fall
    // anywhere in the isovolumic contraction after it (the volume held there to the
    // coupling's tolerance while the pressure rises).
    const double filled = v.end_diastolic_m3 - 1e-3 * v.stroke_m3;
    v.end_diastolic_pa = std::find_if(current_.begin(), current_.end(), [&](const Sample& a) {
                           return a.volume_m3[k] >= filled;
                         })->pressure_pa[k];
    v.peak_pa = std::max_element(current_.begin(), current_.end(), [k](const Sample& a, const Sample& b) {
                  return a.pressure_pa[k] < b.pressure_pa[k];
                })->pressure_pa[k];
    const auto by_arterial = [k](const Sample& a, const Sample& b) { return a.arterial_pa[k] < b.arterial_pa[k]; };
    const auto [alo, ahi] = std::minmax_element(current_.begin(), current_.end(), by_arterial);
    beat.arterial_max_pa[k] = ahi->arterial_pa[k];
    beat.arterial_min_pa[k] = alo->arterial_pa[k];
  }
  beats_.push_back(beat);
  current_.clear();
}

}  // namespace fiberfem::core::circulation
