#include "service/serve_status.hpp"
#include "service/median.hpp"

#include <algorithm>
#include <cstdio>
#include <ostream>

namespace fiberfem::service::detail {

ServeStatus::ServeStatus(const ServeOptions& options, const std::string& scene_name, double sim_t_s, std::ostream& out)
    : options_(options), scene_name_(scene_name), out_(out), period_start_sim_s_(sim_t_s) {}

void ServeStatus::add_step(const core::StepReport& r) {
  ++steps_in_period_;
  step_ms_.push_back(r.time.total_s * 1e3);
  rotations_ms_.push_back(r.time.rotations_s * 1e3);
  assembly_ms_.push_back(r.time.assembly_s * 1e3);
  solve_ms_.push_back(r.time.solve_s * 1e3);
  if (r.status == core::StepStatus::recovered) ++recovered_, step_state_ = "recovered", last_message_ = r.message;
  else if (r.status == core::StepStatus::failed) ++failed_, step_state_ = "failed", last_message_ = r.message;
  else step_state_ = "running";
}

void ServeStatus::publish(RunEndpoints& bus, RunDriver& run, const std::string& state) {
  const auto now = Clock::now();
  const double wall = std::max(1e-9, seconds_between(period_start_, now));
  const Engine& sim = run.engine();
  const RunControl& rc = run.control();
  const core::StepReport& last = run.last_step();
  StatusData st;
  st.scene_name = scene_name_;
  st.state = state;
  st.mode = options_.realtime ? "realtime" : "fast";
  st.frame = static_cast<unsigned long>(sim.step_count());
  st.time_s = sim.time_s();
  st.frames_per_second = static_cast<double>(steps_in_period_) / wall;
  st.real_time_factor = (sim.time_s() - period_start_sim_s_) / wall;
  st.step_ms = median(step_ms_);
  st.rotations_ms = median(rotations_ms_);
  st.assembly_ms = median(assembly_ms_);
  st.solve_ms = median(solve_ms_);
  st.publish_ms = median(publish_ms_);
  st.solver_iterations = last.solver_iterations;
  st.solver_residual = last.solver_residual;
  st.inverted_elements = last.inverted_elements;
  st.kinetic_energy_j = last.kinetic_energy_j;
  st.elastic_energy_j = last.elastic_energy_j;
  st.recovered_steps = recovered_;
  st.failed_steps = failed_;
  st.last_message = last_message_;
  st.parameter_version = rc.parameter_version();
  st.heart_rate_bpm = rc.heart_rate_bpm();
  st.peak_tension_pa = rc.peak_tension_pa();
  st.dt_s = sim.dt_s();
  const std::vector<double> record_ms = run.take_record_ms();
  if (run.recording()) {
    st.recording = run.recording_path();
    st.recorded_frames = static_cast<unsigned long>(run.recorded_frames());
    st.record_ms = median(record_ms);
  }
  bus.publish_status(st);
  print(st, now);
  step_ms_.clear(), rotations_ms_.clear(), assembly_ms_.clear(), solve_ms_.clear(), publish_ms_.clear();
  steps_in_period_ = 0;
  period_start_sim_s_ = sim.time_s();
  period_start_ = now;
}

// On a terminal the one live line redrawn; else a plain line a second.
void ServeStatus::print(const StatusData& st, Clock::time_point now) {
  if (options_.status_line) {
    std::fprintf(stderr, "\r%-8s t=%8.3f s  frame %7lu  %6.1f steps/s  x%.2f real time  step %.2f ms  iters %3d  v%u%s%s   ",
                 st.state.c_str(), st.time_s, static_cast<unsigned long>(st.frame), st.frames_per_second, st.real_time_factor,
                 st.step_ms, st.solver_iterations, st.parameter_version, st.recording.empty() ? "" : "  rec ",
                 st.recording.empty() ? "" : (std::to_string(st.recorded_frames) + " frames").c_str());
    std::fflush(stderr);
  } else if (seconds_between(last_plain_line_, now) >= 1.0) {
    char line[256];
    std::snprintf(line, sizeof line, "status: %s t=%.3f s frame %lu, %.1f steps/s, x%.2f real time, step %.2f ms, %d iterations%s%s\n",
                  st.state.c_str(), st.time_s, static_cast<unsigned long>(st.frame), st.frames_per_second, st.real_time_factor,
                  st.step_ms, st.solver_iterations, st.recording.empty() ? "" : ", recording ", st.recording.c_str());
    out_ << line << std::flush;
    last_plain_line_ = now;
  }
}

}  // namespace fiberfem::service::detail
