// ThreadGovernor: the thread count it settles on, fed with synthetic step times of a
// machine whose speed per thread count the test sets (the governor reads no clock).

#include "core/thread_governor.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>

namespace fiberfem {
namespace {

using core::ThreadGovernor;

struct Tally {
  int steps = 0;
  int steps_off_settled = 0;  // steps run on a count other than the one finally settled
  int changes = 0;            // how often settled() changed
  int steps_on_one = 0;       // steps run on one thread
  double wall_s = 0;          // the steps' times added up
};

// Steps `n` times; `time(threads, step)` is the wall time of a step.
Tally drive(ThreadGovernor& g, int n, const std::function<double(int, int)>& time, int first_step = 0) {
  Tally r;
  int settled = g.settled();
  for (int i = 0; i < n; ++i) {
    const int t = g.threads();
    EXPECT_GE(t, 1);
    EXPECT_LE(t, g.max_threads());
    const double step_s = time(t, first_step + i);
    r.wall_s += step_s;
    r.steps_on_one += t == 1;
    g.record(step_s, true);
    if (g.settled() != settled) ++r.changes;
    settled = g.settled();
    ++r.steps;
  }
  return r;
}

// A machine where two threads take 0.7 of one thread's time, with +-5 % noise.
double two_pay(int threads, int step) {
  const double noise = 1.0 + 0.05 * ((step * 7919) % 11 - 5) / 5.0;
  return (threads == 1 ? 1.0e-3 : 0.7e-3) * noise;
}

TEST(ThreadGovernor, KeepsEveryCoreWhereTheyPayAndProbesLessAndLess) {
  ThreadGovernor g(2);
  EXPECT_EQ(g.threads(), 2);
  int one_thread_steps = 0;
  for (int i = 0; i < 5000; ++i) {
    const int t = g.threads();
    one_thread_steps += t == 1;
    g.record(two_pay(t, i), true);
    EXPECT_EQ(g.settled(), 2) << "step " << i;
  }
  // Probes of one thread, the interval doubling from kMinInterval to kMaxInterval steps:
  // at most eight probes in 5,000 steps, the first one with its pairs.
  EXPECT_GT(one_thread_steps, 0) << "never probed: a machine that changes would not be noticed";
  EXPECT_LE(one_thread_steps, 8 * ThreadGovernor::kProbeSteps + ThreadGovernor::kFirstProbePairs)
      << "probes should become rare while two threads keep winning";
}

TEST(ThreadGovernor, SettlesOnOneThreadWhereTwoDoNotPay) {
  ThreadGovernor g(2);
  // Two threads 1.3 times slower than one (a small mesh: the loops' fork and join cost
  // more than the halved work).
  const auto slow_two = [](int t, int step) { return (t == 1 ? 1.0e-3 : 1.3e-3) * (1.0 + 0.01 * (step % 3)); };
  const Tally r = drive(g, 200, slow_two);
  EXPECT_EQ(g.settled(), 1);
  EXPECT_EQ(r.changes, 1);
  // And keeps it: the later probes of two threads lose.
  drive(g, 3000, slow_two, 200);
  EXPECT_EQ(g.settled(), 1);
}

// One core taken by another process: steps on two threads become 100 times slower (each
// parallel loop waits for the descheduled thread). The governor leaves two threads after
// a few such steps, and returns to them once the core is free again.
TEST(ThreadGovernor, LeavesABusyCoreAndComesBackWhenItIsFree) {
  ThreadGovernor g(2);
  const auto quiet = [](int t, int) { return t == 1 ? 1.0e-3 : 0.6e-3; };
  drive(g, 400, quiet);
  ASSERT_EQ(g.settled(), 2);
  const auto busy = [](int t, int) { return t == 1 ? 1.0e-3 : 60e-3; };
  int slow_steps = 0, step = 0;
  while (g.settled() == 2 && step < 50) {
    slow_steps += g.threads() == 2;
    g.record(busy(g.threads(), step++), true);
  }
  EXPECT_EQ(g.settled(), 1);
  // Each stall starts a probe of one thread against the running mean it raised; the first
  // stalls raise it by stall / 128 only, so a few are needed before one thread wins.
  EXPECT_LE(slow_steps, 4) << "stalls of 100 times the step should move to one thread within a few";
  // While the core stays busy, the probes of two threads each cost one step (a probe step
  // three times the running mean ends the probe) and back off.
  int probe_steps = 0;
  for (int i = 0; i < 4000; ++i) {
    probe_steps += g.threads() == 2;
    g.record(busy(g.threads(), i), true);
    EXPECT_EQ(g.settled(), 1);
  }
  EXPECT_LE(probe_steps, 12) << "each probe of the busy core should be cut after its first step";
  // The core is free again: back to two threads by the next probe (at most kMaxInterval
  // steps plus the window).
  const Tally back = drive(g, ThreadGovernor::kMaxInterval + 40, quiet);
  EXPECT_EQ(g.settled(), 2);
  EXPECT_EQ(back.changes, 1);
}

// Beside a busy core measured here, two threads ran most steps at full speed but stalled
// for about 190 ms now and then (the median step stayed at 0.93 ms, the mean did not).
// The governor counts the stalls (a running mean, not a median) and settles on one thread,
// with probes of two threads ever rarer.
TEST(ThreadGovernor, SporadicStallsOutweighTheSecondThread) {
  ThreadGovernor g(2);
  const auto stalling = [](int t, int step) {
    if (t == 1) return 1.5e-3;
    return step % 60 == 59 ? 190e-3 : 0.93e-3;
  };
  const Tally r = drive(g, 20000, stalling);
  const double wall = r.wall_s;
  // Mostly on one thread (a probe of two that wins runs until its next stall, so the
  // count at the last step is the phase's luck).
  EXPECT_GT(r.steps_on_one, 0.8 * r.steps);
  const double one_thread = 20000 * 1.5e-3, two_threads = 20000 * (0.93e-3 + 190e-3 / 60);
  // The price of noticing when the core is free again: a probe of two threads every 1,024
  // steps, which runs until its next stall (about 11 % here).
  EXPECT_LT(wall, 1.15 * one_thread) << "two threads throughout: " << two_threads << " s";
}

// Beside a client process that takes some of a core (the service publishing every step to
// a subscriber, measured with bench_service): two threads stall now and then for a few
// times their step, but their mean is still well below one thread's. Two stay.
TEST(ThreadGovernor, SmallStallsThatCostLessThanTheSecondThreadGainsKeepIt) {
  ThreadGovernor g(2);
  const auto shared = [](int t, int step) {
    if (t == 1) return 2.2e-3;
    return step % 50 == 49 ? 15e-3 : 1.25e-3;
  };
  const double wall = drive(g, 20000, shared).wall_s;
  EXPECT_EQ(g.settled(), 2);
  const double two_threads = 20000 * (1.25e-3 + 13.75e-3 / 50);
  EXPECT_LT(wall, 1.05 * two_threads) << "one thread throughout: " << 20000 * 2.2e-3 << " s";
}

// Work that grows for every count alike (a harder phase of the beat) is not a busy core:
// after a probe or two the governor stays on the faster count.
TEST(ThreadGovernor, WorkThatGrowsEverywhereDoesNotChangeTheCount) {
  ThreadGovernor g(2);
  const auto base = [](int t, int) { return t == 1 ? 1.0e-3 : 0.6e-3; };
  drive(g, 200, base);
  ASSERT_EQ(g.settled(), 2);
  const auto harder = [](int t, int) { return 5 * (t == 1 ? 1.0e-3 : 0.6e-3); };
  drive(g, 500, harder);
  EXPECT_EQ(g.settled(), 2);
}

// Other processes take the cores from the first step on: every step on two threads is
// 100 times slower than on one, alike, so no stall stands out against the running mean.
// The first probe comes early enough that a 60-step run spends most of it on one thread.
TEST(ThreadGovernor, AMachineBusyFromTheStartIsLeftWithinTheFirstSteps) {
  ThreadGovernor g(2);
  const auto overloaded = [](int t, int) { return t == 1 ? 2.0e-3 : 200e-3; };
  const Tally r = drive(g, 60, overloaded);
  EXPECT_EQ(g.settled(), 1);
  EXPECT_EQ(r.changes, 1);
  // Its steps on two threads: the ones before the first probe, nothing after.
  EXPECT_LE(r.wall_s, (ThreadGovernor::kFirstProbe + 0.5) * 200e-3 + 60 * 2.0e-3);
}

// The first probe takes a count that does not work at all at once; otherwise it compares
// the two counts in neighbouring pairs of steps, so the drift of the first steps' work
// does not pass for a difference: on a machine whose steps grow 4 % per step (a body
// released from rest) with equal speed on both counts it keeps two threads, where a
// comparison with the running mean of the earlier, cheaper steps would see one thread
// 20-30 % slower. One thread 12 % faster, on the same drift, is taken within the first
// kFirstProbe + kFirstProbeSteps + 2 kFirstProbePairs steps (a 60-step run then spends
// the rest on it); two threads 5 % faster are kept.
TEST(ThreadGovernor, TheFirstProbeComparesNeighbouringSteps) {
  const int decided = ThreadGovernor::kFirstProbe + ThreadGovernor::kFirstProbeSteps + 2 * ThreadGovernor::kFirstProbePairs;
  const auto drifting = [](double one, double two) {
    return [one, two](int t, int step) { return (t == 1 ? one : two) * std::pow(1.04, step); };
  };
  ThreadGovernor equal(2);
  drive(equal, decided, drifting(1.0e-3, 1.0e-3));
  EXPECT_EQ(equal.settled(), 2) << "the drift of the work passed for a difference";
  EXPECT_EQ(equal.threads(), 2) << "the first probe should be over";
  ThreadGovernor one_wins(2);
  const Tally r = drive(one_wins, 60, drifting(0.88e-3, 1.0e-3));
  EXPECT_EQ(one_wins.settled(), 1);
  EXPECT_GE(r.steps_on_one, 60 - ThreadGovernor::kFirstProbe - ThreadGovernor::kFirstProbePairs);
  ThreadGovernor two_win(2);
  drive(two_win, decided, drifting(1.0e-3, 0.95e-3));
  EXPECT_EQ(two_win.settled(), 2);
  // A plain 20 % difference, no drift: taken at the first probe as well.
  ThreadGovernor g(2);
  drive(g, decided, [](int t, int) { return t == 1 ? 0.8e-3 : 1.0e-3; });
  EXPECT_EQ(g.settled(), 1);
}

TEST(ThreadGovernor, StepsThatAreNotComparableAreLeftOut) {
  ThreadGovernor g(2);
  // Steps with other work (factorisations, retries) are not comparable: here they are slow
  // on two threads only, and must not drive the governor to one thread.
  for (int i = 0; i < 300; ++i) {
    const int t = g.threads();
    const bool factorises = i % 2 == 0;
    g.record(factorises && t == 2 ? 1.0 : (t == 1 ? 1.0e-3 : 0.6e-3), !factorises);
    EXPECT_EQ(g.settled(), 2) << "step " << i;
  }
  // A probe that meets only steps left out ends undecided instead of holding its count.
  ThreadGovernor h(2);
  drive(h, ThreadGovernor::kFirstProbe, [](int t, int) { return t == 1 ? 1.0e-3 : 0.6e-3; });
  ASSERT_EQ(h.threads(), 1) << "the first probe should have started";
  for (int i = 0; i < 4 * ThreadGovernor::kProbeSteps + 1; ++i) h.record(1.0, false);
  EXPECT_EQ(h.threads(), 2);
  EXPECT_EQ(h.settled(), 2);
}

TEST(ThreadGovernor, ManyCoresClimbTheLadder) {
  ThreadGovernor g(8);
  EXPECT_EQ(g.threads(), 8);
  // Four threads best (say, the other four cores are busy).
  const auto four_best = [](int t, int) { return t == 4 ? 1.0e-3 : t == 8 ? 50e-3 : 1.0e-3 * 4 / t; };
  drive(g, 3000, four_best);
  EXPECT_EQ(g.settled(), 4);
}

TEST(ThreadGovernor, OneCoreIsAConstant) {
  ThreadGovernor g(1);
  drive(g, 100, [](int, int step) { return 1e-3 * (1 + step % 5); });
  EXPECT_EQ(g.threads(), 1);
  EXPECT_EQ(g.settled(), 1);
  testing::expect_invalid([] { ThreadGovernor bad(0); }, {"max_threads", "got 0"});
}

}  // namespace
}  // namespace fiberfem
