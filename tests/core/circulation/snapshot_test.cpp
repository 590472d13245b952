// The circulation as the outputs show it (core/circulation/snapshot.hpp): the columns
// round-trip by name, the report's per-step names lead, and the Monitor's last complete
// beat matches the figures of that beat computed here from the loop's own trajectory.
#include "core/circulation/snapshot.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

namespace cc = fiberfem::core::circulation;

TEST(Snapshot, ColumnsRoundTripByNameAndLeadWithThePerStepOnes) {
  const std::vector<std::string>& names = cc::snapshot_columns();
  ASSERT_EQ(names.size(), 41u);
  EXPECT_EQ(names.front(), "time_s");
  EXPECT_EQ(names[cc::kStepColumns - 1], "pressure_iterations");
  EXPECT_EQ(names[2], "la_volume_m3");
  EXPECT_EQ(names.back(), "pulmonary_arterial_min_pa");
  cc::Snapshot s;  // every number distinct
  s.time_s = 1.5;
  for (size_t i = 0; i < 4; ++i) {
    s.chamber_pressure_pa[i] = 100 + i, s.chamber_volume_m3[i] = 200 + i, s.compartment_pressure_pa[i] = 300 + i;
    s.compartment_flow_m3_s[i] = 400 + i, s.valve_flow_m3_s[i] = 500 + i;
  }
  s.pressure_iterations = 3, s.blood_volume_m3 = 6e-4;
  s.last_beat.index = 7, s.last_beat.start_s = 5.6;
  s.last_beat.ventricle[1].stroke_m3 = 1.25e-5, s.last_beat.arterial_min_pa[1] = 1234;
  const std::vector<double> v = cc::to_columns(s);
  ASSERT_EQ(v.size(), names.size());
  EXPECT_EQ(v[1], 100);  // la_pressure_pa
  EXPECT_EQ(v[6], 101);  // lv_pressure_pa
  const cc::Snapshot back = cc::from_columns(names, v.data());
  EXPECT_EQ(cc::to_columns(back), v);
  // By name: a reversed archive's columns give the same snapshot; unknown names are skipped.
  std::vector<std::string> rnames(names.rbegin(), names.rend());
  std::vector<double> rv(v.rbegin(), v.rend());
  rnames.push_back("something_newer"), rv.push_back(99);
  EXPECT_EQ(cc::to_columns(cc::from_columns(rnames, rv.data())), v);
  // Columns not given keep their defaults (no beat).
  EXPECT_EQ(cc::from_columns({"time_s"}, v.data()).last_beat.index, -1);
}

TEST(Monitor, LastBeatIsTheFiguresOfTheBeatJustCompleted) {
  // The loop alone (all four chambers lumped), 1/60 s steps, three beats.
  cc::Coupling coupling;
  const double h = 1.0 / 60, period = coupling.parameters.period_s;
  cc::State s = coupling.initial;
  cc::Monitor monitor;
  EXPECT_EQ(monitor.update(coupling, s, {}, 0, h, /*after_step=*/false).last_beat.index, -1);
  std::vector<double> lv_volume, lv_pressure, aortic;  // beat 1's, from the loop itself
  const int steps = static_cast<int>(std::lround(3 * period / h));
  for (int i = 1; i <= steps; ++i) {
    s = cc::step(coupling.parameters, s, h);
    const cc::Snapshot& snap = monitor.update(coupling, s, {}, 2, h, /*after_step=*/true);
    EXPECT_EQ(snap.time_s, s.time_s);
    EXPECT_EQ(snap.pressure_iterations, 2);
    EXPECT_NEAR(snap.blood_volume_m3, cc::total_volume(coupling.parameters, s), 1e-18);
    if (s.time_s > period + 1e-9 && s.time_s <= 2 * period + 1e-9) {
      lv_volume.push_back(s.volume_m3[cc::lv]);
      lv_pressure.push_back(cc::observe(coupling.parameters, s).chamber_pa[cc::lv]);
      aortic.push_back(s.pressure_pa[cc::ar_sys]);
    }
    // Beat k is reported from the first step of beat k + 1 on.
    const int expected = static_cast<int>(std::ceil(s.time_s / period - 1e-9)) - 2;
    EXPECT_EQ(snap.last_beat.index, std::max(-1, expected)) << "t = " << s.time_s;
    if (expected == 1) {
      const cc::VentricleBeat& lv = snap.last_beat.ventricle[0];
      const auto edv = std::max_element(lv_volume.begin(), lv_volume.end());
      EXPECT_EQ(lv.end_diastolic_m3, *edv);
      EXPECT_EQ(lv.end_systolic_m3, *std::min_element(lv_volume.begin(), lv_volume.end()));
      EXPECT_EQ(lv.peak_pa, *std::max_element(lv_pressure.begin(), lv_pressure.end()));
      // Where filling ends: the first sample within 1e-3 of the stroke below the largest.
      const double filled = *edv - 1e-3 * lv.stroke_m3;
      const auto end = std::find_if(lv_volume.begin(), lv_volume.end(), [&](double v) { return v >= filled; });
      EXPECT_EQ(lv.end_diastolic_pa, lv_pressure[static_cast<size_t>(end - lv_volume.begin())]);
      EXPECT_EQ(snap.last_beat.arterial_max_pa[0], *std::max_element(aortic.begin(), aortic.end()));
      EXPECT_GT(lv.stroke_m3, 30 * cc::kM3PerMl);  // the paper's loop ejects about 60 mL
    }
  }
  // A reset (time back to zero) starts the beats afresh: none complete.
  EXPECT_EQ(monitor.update(coupling, cc::step(coupling.parameters, coupling.initial, h), {}, 0, h, true).last_beat.index, -1);
}

// After a heart rate change the beat figures follow the loop's beats: the beat under way
// goes on and the next ones start one new period apart from its start (keep_beat_phase).
// Each complete beat the monitor reports starts at the loop's beat origin plus whole new
// periods, and its EDV and ESV are the extremes of the loop's own LV volume over that
// window. (Windows counted from time zero instead cut the loop's beats in two: the origin
// here is not a multiple of the new period.)
TEST(Monitor, AfterAHeartRateChangeTheBeatsFollowTheLoopsOrigin) {
  cc::Coupling coupling;
  const double h = 1.0 / 60, old_period = coupling.parameters.period_s, new_period = 0.75 * old_period;
  cc::State s = coupling.initial;
  cc::Monitor monitor;
  monitor.update(coupling, s, {}, 0, h, false);
  const int before = static_cast<int>(std::lround(1.4 * old_period / h));
  for (int i = 0; i < before; ++i) monitor.update(coupling, s = cc::step(coupling.parameters, s, h), {}, 1, h, true);
  cc::keep_beat_phase(s, old_period);  // what set_circulation_parameters does
  coupling.parameters.period_s = new_period;
  const double origin = s.beat_origin_s;
  ASSERT_GT(origin, 0.5 * old_period) << "the beat under way should have begun after the first";
  ASSERT_GT(std::abs(origin / new_period - std::round(origin / new_period)), 0.1) << "the origin should not fall on the old windows";
  std::vector<double> t, lv;
  int checked = 0, last_index = -1;
  const int after = static_cast<int>(std::lround(4.5 * new_period / h));
  for (int i = 0; i < after; ++i) {
    s = cc::step(coupling.parameters, s, h);
    t.push_back(s.time_s);
    lv.push_back(s.volume_m3[cc::lv]);
    const cc::Beat& b = monitor.update(coupling, s, {}, 1, h, true).last_beat;
    if (b.index < 0 || b.index == last_index) continue;
    last_index = b.index;
    const double start = origin + b.index * new_period;
    EXPECT_NEAR(b.start_s, start, 1e-12);
    double hi = -1, lo = 1;
    for (size_t k = 0; k < t.size(); ++k)
      if (t[k] > start + 1e-9 && t[k] <= start + new_period + 1e-9) {
        hi = std::max(hi, lv[k]);
        lo = std::min(lo, lv[k]);
      }
    EXPECT_EQ(b.ventricle[0].end_diastolic_m3, hi) << "beat " << b.index;
    EXPECT_EQ(b.ventricle[0].end_systolic_m3, lo) << "beat " << b.index;
    ++checked;
  }
  EXPECT_GE(checked, 3) << "complete beats after the change";
}

TEST(Snapshot, CoupledVentriclesTakeTheCavityVolumes) {
  cc::Coupling coupling;
  coupling.cavities.resize(1);
  coupling.cavities[0].chamber = cc::rv;
  const cc::State s = coupling.initial;
  const cc::Snapshot snap = cc::observe_snapshot(coupling, s, {1.25e-5}, 4);
  EXPECT_EQ(snap.chamber_volume_m3[cc::rv], 1.25e-5);
  EXPECT_EQ(snap.chamber_volume_m3[cc::lv], s.volume_m3[cc::lv]);
  EXPECT_EQ(snap.chamber_pressure_pa[cc::la], cc::observe(coupling.parameters, s).chamber_pa[cc::la]);
  EXPECT_EQ(snap.pressure_iterations, 4);
}
