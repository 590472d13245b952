#pragma once
/// @file The service's status (docs/dds.md ServiceStatus): the step timings and counts
/// of one status period, published with the run's state and printed as a live line on a
/// terminal or a plain line a second.

#include "service/run_driver.hpp"
#include "service/run_endpoints.hpp"
#include "service/serve.hpp"
#include "service/serve_pacing.hpp"

#include <iosfwd>
#include <string>
#include <vector>

namespace fiberfem::service::detail {

class ServeStatus {
 public:
  ServeStatus(const ServeOptions& options, const std::string& scene_name, double sim_t_s, std::ostream& out);
  /// After each step.
  void add_step(const core::StepReport& r);
  /// After each state published, with the time it took.
  void add_publish_ms(double ms) { publish_ms_.push_back(ms); }
  /// Why the last command was refused, or the last step recovered or failed.
  void set_message(std::string m) { last_message_ = std::move(m); }
  /// Whether a status period has passed.
  bool due(Clock::time_point now) const { return seconds_between(period_start_, now) >= 1.0 / options_.status_hz; }
  /// "running", "recovered" or "failed" (the last step's), or "paused".
  std::string state(const RunDriver& run) const { return run.control().paused() ? "paused" : step_state_; }
  /// Publishes the status of the period as `state` and starts the next period.
  void publish(RunEndpoints& bus, RunDriver& run, const std::string& state);
  unsigned recovered() const { return recovered_; }
  unsigned failed() const { return failed_; }

 private:
  void print(const StatusData& st, Clock::time_point now);

  const ServeOptions& options_;
  std::string scene_name_;
  std::ostream& out_;
  std::vector<double> step_ms_, rotations_ms_, assembly_ms_, solve_ms_, publish_ms_;
  unsigned recovered_ = 0, failed_ = 0;
  std::string last_message_, step_state_ = "running";
  long steps_in_period_ = 0;
  double period_start_sim_s_;
  Clock::time_point period_start_ = Clock::now(), last_plain_line_ = period_start_;
};

}  // namespace fiberfem::service::detail
