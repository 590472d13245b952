// The lumped circulation alone (core/circulation/circulation.hpp): conservation over many
// beats, the backward-Euler step's order, scaling, the external-chamber sensitivity and
// validation. The comparison with an independent implementation of the same model (the
// PyPI package `circulation`) is tests/core/circulation/regazzoni_reference_test.py.
#include "core/circulation/circulation.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

namespace cc = fiberfem::core::circulation;

namespace {

cc::State run(const cc::Parameters& p, cc::State s, double h, double until) {
  const int n = static_cast<int>(std::lround(until / h));
  for (int i = 0; i < n; ++i) s = cc::step(p, s, h);
  return s;
}

}  // namespace

TEST(Circulation, ConservesBloodVolumeToRoundOffOverManyBeats) {
  const cc::Parameters p;
  cc::State s = cc::State::regazzoni_initial();
  const double v0 = cc::total_volume(p, s);
  double worst = 0;
  for (int i = 0; i < 60 * 16; ++i) {  // 20 beats at 1/60 s
    s = cc::step(p, s, 1.0 / 60);
    worst = std::max(worst, std::abs(cc::total_volume(p, s) - v0));
  }
  // ~ 5e-4 m^3 of blood: round-off of the sums is ~1e-19 m^3 per step.
  EXPECT_LT(worst / v0, 1e-13);
  // And the loop did beat: the aortic valve opened and the left ventricle ejected.
  EXPECT_GT(s.pressure_pa[cc::ar_sys], 40 * cc::kPaPerMmHg);
}

TEST(Circulation, BackwardEulerConvergesAtFirstOrder) {
  // Pressures after one beat at h, h/2, h/4: the differences shrink by two each halving.
  const cc::Parameters p;
  const cc::State s0 = cc::State::regazzoni_initial();
  const cc::State a = run(p, s0, 1e-3, 0.8), b = run(p, s0, 5e-4, 0.8), c = run(p, s0, 2.5e-4, 0.8);
  const double dab = std::abs(a.pressure_pa[cc::ar_sys] - b.pressure_pa[cc::ar_sys]);
  const double dbc = std::abs(b.pressure_pa[cc::ar_sys] - c.pressure_pa[cc::ar_sys]);
  EXPECT_GT(dab / dbc, 1.6);
  EXPECT_LT(dab / dbc, 2.5);
  // And the engine's step, 1/60 s, stays within a few mmHg of the fine solution.
  const cc::State coarse = run(p, s0, 1.0 / 60, 0.8);
  EXPECT_LT(std::abs(coarse.pressure_pa[cc::ar_sys] - c.pressure_pa[cc::ar_sys]), 5 * cc::kPaPerMmHg);
}

TEST(Circulation, ScalingScalesPressuresAndVolumesAndKeepsTime) {
  const cc::Parameters p;
  cc::Parameters q = p;
  q.scale(0.1, 0.02);
  cc::State s = cc::State::regazzoni_initial(), t = s;
  for (int i = 0; i < 4; ++i) {
    t.volume_m3[static_cast<size_t>(i)] *= 0.02;
    t.pressure_pa[static_cast<size_t>(i)] *= 0.1;
  }
  s = run(p, s, 1.0 / 60, 1.6);
  t = run(q, t, 1.0 / 60, 1.6);
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR(t.volume_m3[static_cast<size_t>(i)], 0.02 * s.volume_m3[static_cast<size_t>(i)], 1e-9 * s.volume_m3[static_cast<size_t>(i)]);
    EXPECT_NEAR(t.pressure_pa[static_cast<size_t>(i)], 0.1 * s.pressure_pa[static_cast<size_t>(i)], 1e-7 * s.pressure_pa[static_cast<size_t>(i)]);
  }
}

TEST(Circulation, ValveFlowAndSlopeAgreeWithFiniteDifferences) {
  const cc::Valve v;
  for (double dp : {-500.0, -1.0, -0.2, 0.0, 0.3, 2.0, 800.0}) {
    double slope = 0;
    const double q = v.flow(dp, &slope);
    EXPECT_EQ(q >= 0, dp >= 0);
    const double e = 1e-4;
    const double fd = (v.flow(dp + e) - v.flow(dp - e)) / (2 * e);
    EXPECT_NEAR(slope, fd, 1e-5 * std::abs(fd) + 1e-20);
  }
  // Open: R_min; shut: R_max (the arctangent's slow tail leaves 0.2 % at 7.5 mmHg).
  EXPECT_NEAR(v.flow(1000.0), 1000.0 / v.r_min_pa_s_m3, 1e-2 * 1000.0 / v.r_min_pa_s_m3);
  EXPECT_NEAR(v.flow(-1000.0), -1000.0 / v.r_max_pa_s_m3, 1e-2 * 1000.0 / v.r_max_pa_s_m3);
}

TEST(Circulation, ExternalVentricleSensitivityAgreesWithFiniteDifferences) {
  cc::Parameters p;
  p.chambers[cc::lv].kind = cc::ChamberKind::external;
  p.chambers[cc::rv].kind = cc::ChamberKind::external;
  cc::State s = cc::State::regazzoni_initial();
  const double h = 1.0 / 60;
  for (std::array<double, 2> ext : {std::array<double, 2>{1000.0, 500.0}, std::array<double, 2>{14000.0, 3000.0}}) {
    Eigen::Matrix2d J;
    cc::step(p, s, h, ext, &J);
    for (int k = 0; k < 2; ++k) {
      const double e = 1e-3;
      auto hi = ext, lo = ext;
      hi[static_cast<size_t>(k)] += e;
      lo[static_cast<size_t>(k)] -= e;
      const cc::State a = cc::step(p, s, h, hi), b = cc::step(p, s, h, lo);
      EXPECT_NEAR(J(0, k), (a.volume_m3[cc::lv] - b.volume_m3[cc::lv]) / (2 * e), 1e-4 * std::abs(J(0, k)) + 1e-16);
      EXPECT_NEAR(J(1, k), (a.volume_m3[cc::rv] - b.volume_m3[cc::rv]) / (2 * e), 1e-4 * std::abs(J(1, k)) + 1e-16);
    }
  }
}

TEST(Circulation, ValidationNamesTheParameter) {
  cc::Parameters p;
  p.compartments[cc::ven_sys].compliance_m3_pa = -1e-8;
  try {
    p.validate();
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("systemic.veins.compliance"), std::string::npos) << e.what();
  }
  cc::Parameters q;
  q.valves[cc::aortic].r_min_pa_s_m3 = q.valves[cc::aortic].r_max_pa_s_m3;
  try {
    q.validate();
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("valves.aortic"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("never open"), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(cc::Parameters().validate());
}

// A new beat period keeps every chamber's activation where it is (the beat under way keeps
// the time since it began; a start still ahead in it last came round a whole old period
// before), and the next beat starts one new period after the one under way began. Checked
// against the activation of the schedule the chamber actually went through.
TEST(Circulation, ANewPeriodKeepsEveryChambersActivationWhereItIs) {
  cc::Parameters p;  // 0.8 s
  // Every contraction's start and end in the beat below both periods (the atria's 0.8 s
  // would wrap to another place in a beat of 0.6 s).
  for (cc::ChamberId c : {cc::la, cc::ra}) p.chambers[c].elastance.onset_s = 0.4;
  for (double new_period : {0.6, 1.1}) {
    int jumps_without = 0;
    for (double phase = 0.02; phase < std::min(0.8, new_period); phase += 0.04) {
      cc::State s;
      s.time_s = 2 * 0.8 + phase;  // in the third beat
      cc::State kept = s;
      cc::keep_beat_phase(kept, 0.8);
      EXPECT_NEAR(kept.beat_origin_s, 1.6, 1e-12);
      EXPECT_DOUBLE_EQ(kept.previous_period_s, 0.8);
      for (const cc::Chamber& ch : p.chambers) {
        const cc::Elastance& e = ch.elastance;
        const double before = e.activation(s.time_s, 0.8);
        EXPECT_NEAR(e.activation(kept.time_s - kept.beat_origin_s, new_period, kept.previous_period_s), before, 1e-12)
            << "phase " << phase << " new period " << new_period;
        // The schedule restarted at the run's time instead: the activation would jump.
        if (std::abs(e.activation(s.time_s, new_period) - before) > 1e-3) ++jumps_without;
        // One new period after the beat under way began, the next beat is where a beat
        // begins (plus 0.01 s): the activation of a run that always had the new period.
        const double next = 1.6 + new_period + 0.01;
        EXPECT_NEAR(e.activation(next - kept.beat_origin_s, new_period, kept.previous_period_s), e.activation(0.01, new_period), 1e-12);
      }
    }
    EXPECT_GT(jumps_without, 0) << "the test should see what keeping the phase avoids";
  }
  // A change in the first beat since the origin keeps the origin.
  cc::State first;
  first.time_s = 0.3;
  cc::keep_beat_phase(first, 0.8);
  EXPECT_EQ(first.beat_origin_s, 0.0);
  EXPECT_EQ(first.previous_period_s, 0.8);
}
