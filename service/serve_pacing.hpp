#pragma once
/// @file The service's clocks: real-time pacing of the steps and the rate limit of the
/// published states (docs/dds.md).

#include <algorithm>
#include <chrono>

namespace fiberfem::service::detail {

using Clock = std::chrono::steady_clock;

inline double seconds_between(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double>(b - a).count(); }

/// Real time: simulated time advances `factor` times as fast as the wall clock from an
/// anchor (the start, the end of a pause, or the moment the run fell too far behind).
class WallClockPacer {
 public:
  WallClockPacer(bool realtime, double factor, double sim_t_s) : realtime_(realtime), factor_(factor) { anchor(sim_t_s); }
  /// How far the simulation at `sim_t_s` is ahead of the wall clock, wall s (> 0: wait).
  double ahead_s(double sim_t_s) const { return (sim_t_s - anchor_sim_s_) / factor_ - seconds_between(anchor_wall_, Clock::now()); }
  /// Whether the next step is due (always, when not in real time).
  bool due(double sim_t_s) const { return !realtime_ || ahead_s(sim_t_s) <= 0; }
  bool realtime() const { return realtime_; }
  /// Pacing starts again from now at `sim_t_s`.
  void anchor(double sim_t_s) {
    anchor_wall_ = Clock::now();
    anchor_sim_s_ = sim_t_s;
  }

 private:
  bool realtime_;
  double factor_;
  Clock::time_point anchor_wall_;
  double anchor_sim_s_ = 0;
};

/// States are rate-limited by a token bucket (`hz` tokens a second, at most two kept),
/// and sent at least once a second (the state's deadline). A strict minimum interval
/// lost every other frame when the steps came at the publish rate (real time at 60
/// steps/s and 60 Hz: a step a little early by the wall clock was held back to the next
/// one, 30 frames/s measured).
class StateRateLimit {
 public:
  StateRateLimit(double hz, Clock::time_point start) : hz_(hz), last_state_(start - std::chrono::hours(1)), last_refill_(start) {}
  /// Whether to publish now a state that is `changed` since the last one.
  bool due(bool changed, Clock::time_point now) {
    tokens_ = std::min(2.0, tokens_ + seconds_between(last_refill_, now) * hz_);
    last_refill_ = now;
    return (changed && tokens_ >= 1.0) || seconds_between(last_state_, now) >= 1.0;
  }
  void published(Clock::time_point now) {
    last_state_ = now;
    tokens_ = std::max(0.0, tokens_ - 1.0);
  }

 private:
  double hz_;
  double tokens_ = 1.0;
  Clock::time_point last_state_, last_refill_;
};

}  // namespace fiberfem::service::detail
