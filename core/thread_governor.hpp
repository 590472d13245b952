#pragma once
/// @file How many threads the next step uses when the user left it to the engine
/// (SimulatorSettings::threads = 0): chosen from the measured wall time of recent steps,
/// not from the core count alone.
///
/// Why: the threads of a parallel loop wait for each other at its end, so a thread that the
/// operating system has descheduled (another busy process on its core) stalls the loop.
/// Measured here beside one busy core, the paper-size beam on two threads ran most steps
/// at full speed but stalled for 100-200 ms every few dozen steps, which cost more than the
/// second thread gained. And below about 10,000 elements two threads can be slower than
/// one even on a quiet machine.
///
/// The governor keeps a running mean of the step time of the count it runs over about the
/// last 128 steps (stalls included, at their rate: a mean, not a median), probes a
/// neighbouring count for a few steps now and then, and moves to the probe's count when its
/// mean beats the running mean by 10 %. A step far slower than the running mean (a stall)
/// starts a probe of fewer threads at once, judged against the mean that stall raised. The
/// first probe, early in a run, compares neighbouring steps in pairs instead
/// (kFirstProbePairs).
/// Probes become rarer each time one loses and (faster) each time a stall starts one, so
/// a machine that keeps stalling one count settles on the other. Switching has no other
/// effect: the engine's sums round the same on any thread count (core/parallel.hpp).

#include <array>

namespace fiberfem::core {

class ThreadGovernor {
 public:
  /// Steps of a probe; their mean decides.
  static constexpr int kProbeSteps = 6;
  /// Steps between probes: the first interval and the most it grows to (it doubles after a
  /// probe that loses, and grows four times when a stall starts a probe of fewer threads). On a quiet machine
  /// where the current count wins, probes cost about 2 % of a 130-step run and 1 % of a
  /// 1,000-step one (one slower count for kProbeSteps steps each time).
  static constexpr int kMinInterval = 64;
  /// Steps before the first probe: soon, so that a machine whose other cores are taken
  /// from the start (every step slow alike, no stall to notice) is left within a short
  /// run; once, at the cost of kFirstProbeSteps steps on fewer threads on a quiet machine.
  static constexpr int kFirstProbe = 8;
  /// Steps of the first probe: enough to see a count that does not work at all.
  static constexpr int kFirstProbeSteps = 3;
  /// The first probe takes over at once when its mean is below this fraction of the
  /// running mean (a count that does not work at all).
  static constexpr double kFirstProbeGain = 0.5;
  /// Otherwise it goes on in pairs of neighbouring steps, one at the current count and one
  /// at the probe's (each first in every other pair), and takes over when the probe's
  /// steps sum to under kFirstPairGain of the current count's. Pairs cancel the drift of
  /// the first steps' work (a body released from rest takes more iterations each step),
  /// which a comparison with the running mean of earlier steps would take for a difference
  /// between the counts, so a 60-step run leaves a count 10 % slower than the other (two
  /// threads on a small mesh in the machine's slow state) at its 20th step instead of
  /// running on it throughout.
  static constexpr int kFirstProbePairs = 4;
  /// Neighbouring steps differ by little besides the count (+-2.5 % on four pairs of steps
  /// that vary by 5 %), so the pairs decide a 5 % difference: on the 5,663-tet beam in
  /// the machine's slow state one thread took 0.90 of two threads' time, which the 10 % of
  /// kSwitchGain would have left. Taking a count that is not faster costs nothing (the
  /// periodic probes return to a faster one).
  static constexpr double kFirstPairGain = 0.95;
  /// Comparable steps at a count before its running mean is trusted (stalls and probes
  /// wait for them).
  static constexpr int kSettleSteps = 8;
  static constexpr int kMaxInterval = 1024;
  /// A probe must beat the running mean by this factor to take over.
  static constexpr double kSwitchGain = 0.9;
  /// A step (or a probe's first step) this many times the running mean is a stall: it
  /// starts a probe of fewer threads (or ends a probe at once).
  static constexpr double kStallFactor = 3.0;
  /// Steps the running mean spans (an exponential mean with weight 1/kMeanSteps, a plain
  /// mean until that many): long enough that a stall counts at its rate, not at its size
  /// (one 15 ms stall in 50 steps of 1.25 ms costs less than one thread's 2.2 ms steps).
  static constexpr int kMeanSteps = 128;

  /// @param max_threads the most threads to use (>= 1; 1 makes the governor a constant).
  /// @throws std::invalid_argument for max_threads < 1.
  explicit ThreadGovernor(int max_threads = 1);

  /// Threads for the next step.
  int threads() const { return probing_ && !(pairing_ && base_turn_) ? probe_ : current_; }
  /// The count the governor has settled on (not a probe's).
  int settled() const { return current_; }
  int max_threads() const { return max_; }
  /// Reports the wall time of the step just made with threads(), seconds. `comparable`:
  /// false for a step whose work was not that of a usual step (a factorisation, a retry
  /// with substeps), which is left out.
  void record(double step_s, bool comparable);

 private:
  int lower(int n) const;   // next count down the ladder 1, 2, 4, ..., max
  int higher(int n) const;  // next count up, or max
  void start_probe(int count);
  void end_probe(bool switch_to_probe);
  void longer_interval();

  int max_ = 1;
  int current_ = 1;
  double mean_s_ = 0;  // running mean of the comparable step times at current_
  int measured_ = 0;   // comparable steps at current_ since it became current (capped)
  int until_probe_ = kFirstProbe;
  int interval_ = kMinInterval;
  bool probe_down_ = true;  // which neighbour the next periodic probe tries
  bool probing_ = false;
  bool first_probe_ = true;  // the next (or running) probe is the first
  int probe_ = 1;
  double probe_sum_s_ = 0;
  int probe_filled_ = 0;
  int probe_skipped_ = 0;  // steps left out during the probe
  // The first probe's pairs (kFirstProbePairs): whether they are under way, whether the
  // next step is the current count's, the pairs' steps so far and the two counts' sums.
  bool pairing_ = false;
  bool base_turn_ = false;
  int pair_steps_ = 0;
  double pair_probe_s_ = 0, pair_base_s_ = 0;
  // The last mean measured at each count (a probe's, or the running mean when a count was
  // left), 0 when never measured: a stall starts no probe of a count already known to be
  // slower than the raised running mean. Counts above kRemembered are not remembered.
  static constexpr int kRemembered = 64;
  std::array<double, kRemembered + 1> known_s_{};
  void remember(int count, double mean_s);
  double known(int count) const;
};

}  // namespace fiberfem::core
