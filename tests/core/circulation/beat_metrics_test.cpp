// Per-beat figures from samples of a known volume and pressure curve.
#include "core/circulation/beat_metrics.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace cc = fiberfem::core::circulation;

TEST(BeatRecorder, ReducesEachBeatOfAKnownCurve) {
  constexpr double kPi = 3.14159265358979323846;
  const double period = 0.8, h = 0.01;
  cc::BeatRecorder rec(period, 0.0);
  for (int i = 1; i <= 240; ++i) {  // three beats
    const double t = i * h;
    cc::Sample s;
    s.time_s = t;
    const double phase = 2 * kPi * t / period;
    const double beat = std::floor((t - 1e-9) / period);
    s.volume_m3[0] = (100 + 30 * std::cos(phase) + 5 * beat) * 1e-6;   // EDV 130 + 5k, ESV 70 + 5k
    s.pressure_pa[0] = 8000 - 6000 * std::cos(phase);                   // peak 14000, at EDV 2000
    s.volume_m3[1] = (110 + 30 * std::cos(phase)) * 1e-6;
    s.pressure_pa[1] = 2000 - 1000 * std::cos(phase);
    s.arterial_pa[0] = 13000 + 2500 * std::sin(phase);
    s.arterial_pa[1] = 3000;
    rec.add(s);
  }
  rec.finish();
  ASSERT_EQ(rec.beats().size(), 3u);
  for (int k = 0; k < 3; ++k) {
    const cc::Beat& b = rec.beats()[static_cast<size_t>(k)];
    EXPECT_EQ(b.index, k);
    EXPECT_EQ(b.samples, 80);
    EXPECT_NEAR(b.ventricle[0].end_diastolic_m3, (130 + 5 * k) * 1e-6, 1e-12);
    EXPECT_NEAR(b.ventricle[0].end_systolic_m3, (70 + 5 * k) * 1e-6, 1e-12);
    EXPECT_NEAR(b.ventricle[0].ejection_fraction, 60.0 / (130 + 5 * k), 1e-9);
    EXPECT_NEAR(b.ventricle[0].peak_pa, 14000, 1e-6);
    EXPECT_NEAR(b.ventricle[0].end_diastolic_pa, 2000, 1e-6);
    EXPECT_NEAR(b.arterial_max_pa[0], 15500, 1.0);
    EXPECT_NEAR(b.arterial_min_pa[0], 10500, 1.0);
    EXPECT_NEAR(b.ventricle[1].stroke_m3, 60e-6, 1e-12);
  }
}

// The end-diastolic pressure is where filling ends, not at the largest volume: in the
// isovolumic contraction after it the volume is held to the coupling's tolerance (here it
// creeps up by 1e-9 of itself) while the pressure rises to the aortic one.
TEST(BeatRecorder, EndDiastolicPressureIsWhereFillingEnds) {
  const double period = 1.0, h = 0.01;
  cc::BeatRecorder rec(period, 0.0);
  for (int i = 1; i <= 100; ++i) {
    const double t = i * h;
    cc::Sample s;
    s.time_s = t;
    if (t <= 0.5) {  // filling: 60 -> 120 mL at 1 kPa
      s.volume_m3[0] = (60 + 120 * t) * 1e-6;
      s.pressure_pa[0] = 1000;
    } else if (t <= 0.6) {  // isovolumic contraction: pressure to 11 kPa
      s.volume_m3[0] = 120e-6 * (1 + 1e-9 * (t - 0.5));
      s.pressure_pa[0] = 1000 + 1e5 * (t - 0.5);
    } else {  // ejection
      s.volume_m3[0] = (120 - 150 * (t - 0.6)) * 1e-6;
      s.pressure_pa[0] = 11000;
    }
    rec.add(s);
  }
  rec.finish();
  ASSERT_EQ(rec.beats().size(), 1u);
  const cc::VentricleBeat& v = rec.beats()[0].ventricle[0];
  EXPECT_NEAR(v.end_diastolic_m3, 120e-6, 1e-12);
  EXPECT_NEAR(v.end_diastolic_pa, 1000, 1e-9);  // at the largest volume it would be 11 kPa
}
