#include "core/thread_governor.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace fiberfem::core {

ThreadGovernor::ThreadGovernor(int max_threads) : max_(max_threads), current_(max_threads) {
  if (max_threads < 1)
    throw std::invalid_argument("thread governor: max_threads must be >= 1, got " + std::to_string(max_threads));
}

int ThreadGovernor::lower(int n) const {
  if (n <= 1) return 1;
  int p = 1;
  while (2 * p < n) p *= 2;
  return p;
}

int ThreadGovernor::higher(int n) const {
  if (n >= max_) return max_;
  int p = 1;
  while (p <= n) p *= 2;
  return std::min(p, max_);
}

void ThreadGovernor::remember(int count, double mean_s) {
  if (count <= kRemembered) known_s_[static_cast<size_t>(count)] = mean_s;
}

double ThreadGovernor::known(int count) const { return count <= kRemembered ? known_s_[static_cast<size_t>(count)] : 0.0; }

void ThreadGovernor::longer_interval() { interval_ = std::min(kMaxInterval, 2 * interval_); }

void ThreadGovernor::start_probe(int count) {
  probing_ = true;
  pairing_ = false;
  probe_ = count;
  probe_sum_s_ = 0;
  probe_filled_ = 0;
  probe_skipped_ = 0;
}

void ThreadGovernor::end_probe(bool switch_to_probe) {
  probing_ = false;
  pairing_ = false;
  // After the first probe the periodic ones keep their schedule (the next at step
  // kMinInterval), so the early look costs no more probes than before it.
  const int next = first_probe_ ? std::max(1, kMinInterval - kFirstProbe - kFirstProbeSteps) : interval_;
  first_probe_ = false;
  if (probe_filled_ > 0) remember(probe_, probe_sum_s_ / probe_filled_);
  if (switch_to_probe) {
    remember(current_, mean_s_);
    current_ = probe_;
    mean_s_ = probe_sum_s_ / probe_filled_;  // the probe's steps start the new running mean
    measured_ = probe_filled_;
  }
  until_probe_ = next;
}

void ThreadGovernor::record(double step_s, bool comparable) {
  if (max_ == 1) return;
  if (!comparable || !(step_s >= 0)) {
    // A probe that meets only such steps ends undecided rather than holding its count.
    if (probing_ && ++probe_skipped_ > 4 * kProbeSteps) end_probe(false);
    return;
  }
  if (probing_ && pairing_) {
    // Steps in the order current, probe, probe, current, ... (each count first in every
    // other pair), so a drift of the work cancels to first order.
    if (base_turn_) {  // a step at the current count: also one of its running mean's
      pair_base_s_ += step_s;
      measured_ = std::min(measured_ + 1, kMeanSteps);
      mean_s_ += (step_s - mean_s_) / measured_;
    } else {
      pair_probe_s_ += step_s;
    }
    ++pair_steps_;
    base_turn_ = pair_steps_ % 4 == 0 || pair_steps_ % 4 == 3;
    if (pair_steps_ < 2 * kFirstProbePairs) return;
    probe_sum_s_ = pair_probe_s_;  // the probe's mean, as end_probe reads it
    probe_filled_ = kFirstProbePairs;
    end_probe(pair_probe_s_ < kFirstPairGain * pair_base_s_);
    return;
  }
  if (probing_) {
    probe_sum_s_ += step_s;
    ++probe_filled_;
    if (probe_filled_ == 1 && step_s > kStallFactor * mean_s_) {
      longer_interval();  // the probed count stalls at once: stop paying for it
      end_probe(false);
      return;
    }
    if (probe_filled_ < (first_probe_ ? kFirstProbeSteps : kProbeSteps)) return;
    const bool wins = probe_sum_s_ / probe_filled_ < (first_probe_ ? kFirstProbeGain : kSwitchGain) * mean_s_;
    if (!wins && first_probe_) {  // not by a factor of two: compare in pairs
      pairing_ = true;
      base_turn_ = true;
      pair_steps_ = 0;
      pair_probe_s_ = pair_base_s_ = 0;
      return;
    }
    if (!wins) longer_interval();
    end_probe(wins);
    return;
  }
  const bool stall = measured_ >= kSettleSteps && step_s > kStallFactor * mean_s_;
  measured_ = std::min(measured_ + 1, kMeanSteps);
  mean_s_ += (step_s - mean_s_) / measured_;
  const double fewer = known(lower(current_));
  if (stall && current_ > 1 && !(fewer > 0 && fewer >= kSwitchGain * mean_s_)) {
    // Compare fewer threads with the mean this stall raised, now rather than at the next
    // periodic probe (unless fewer threads were measured slower than that mean already).
    // Leaving a count because it stalls makes the probes back to it four times rarer.
    longer_interval();
    longer_interval();
    first_probe_ = false;  // judged as any later probe
    start_probe(lower(current_));
    return;
  }
  if (--until_probe_ > 0 || measured_ < kSettleSteps) return;
  // Periodic probe of a neighbour on the ladder (alternating down and up where both exist).
  const int down = lower(current_), up = higher(current_);
  int pick = probe_down_ ? down : up;
  if (pick == current_) pick = probe_down_ ? up : down;
  probe_down_ = !probe_down_;
  if (pick == current_) {
    until_probe_ = interval_;
    return;
  }
  start_probe(pick);
}

}  // namespace fiberfem::core
