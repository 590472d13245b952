// The service loop (DESIGN.md section 2): drain commands -> apply at the step boundary ->
// step -> publish -> status, paced to the wall clock in real-time mode. The run itself
// (resume, recording, the step) is the RunDriver's.

#include "service/serve.hpp"

#include "service/run_endpoints.hpp"
#include "service/run_topology.hpp"
#include "service/serve_pacing.hpp"
#include "service/serve_recording.hpp"
#include "service/serve_status.hpp"
#include "service/stop_signals.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <ostream>
#include <stdexcept>

namespace fiberfem::service {
namespace {

using detail::Clock;
using detail::seconds_between;

std::chrono::nanoseconds wall_ns(double s) { return std::chrono::nanoseconds(static_cast<long long>(s * 1e9)); }

class ServeLoop {
 public:
  ServeLoop(const ServeOptions& o, RunDriver& run, RunEndpoints& bus, std::ostream& out)
      : o_(o), run_(run), bus_(bus), out_(out),
        status_(o, run.control().scene().name, run.engine().time_s(), out),
        recording_(run, o.source + " (served as " + bus.run_id() + ")", out),
        pacer_(o.realtime, o.real_time_factor, run.engine().time_s()),
        states_(o.publish_hz, Clock::now()) {
    const core::TetMesh& mesh = run.engine().model().mesh;
    if (o.surface_only) state_nodes_ = mesh.boundary_nodes();
    if (run_.circulation())
      if (const std::string refused = bus_.enable_circulation(); !refused.empty()) out_ << "fiberfem serve: " << refused << "\n";
    publish_topology();
  }

  // Until a shutdown command, a signal or until_s. @return why it stopped.
  std::string run(const StopSignals& stop_signals) {
    if (o_.archive.enabled && has_archive()) recording_.start_series(o_.archive);
    status_.publish(bus_, run_, "starting");
    // The starting state (the rest shape, or the resumed one) goes out before the first
    // step, which can take most of a second at 250,000 tets.
    publish_due(Clock::now());
    run_.control().set_recording_handler(
        [this](const std::string& kind, const std::string& args) { return recording_.command(kind, args); });
    for (;;) {
      if (take_commands() > 0) state_dirty_ = true;
      if (run_.control().topology_version() != topology_version_) publish_topology();
      if (run_.control().shutdown_requested()) return "shut down by command";
      if (stop_signals.caught()) return std::string("stopped by ") + stop_signals.name();
      if (o_.until_s > 0 && run_.engine().time_s() >= o_.until_s - 1e-9) return "reached t = " + std::to_string(o_.until_s) + " s";
      // Step unless paused, or in real time ahead of the wall clock (a command woke the
      // wait early, and the step is not due yet).
      const bool due = pacer_.due(run_.engine().time_s());
      const bool stepped = due && run_.control().take_step_permission();
      if (stepped) {
        status_.add_step(run_.step());
        state_dirty_ = true;
      }
      publish_due(Clock::now());
      pace(due, stepped);
    }
  }

  // The last state and status, and the summary line.
  void finish(const std::string& stop_reason, Clock::time_point start) {
    if (run_.recording()) recording_.stop();
    publish_state();
    status_.publish(bus_, run_, "stopped");
    if (o_.status_line) std::fprintf(stderr, "\n");
    const Engine& sim = run_.engine();
    out_ << "fiberfem serve: " << stop_reason << "; " << sim.step_count() << " steps, t = " << sim.time_s() << " s in "
         << seconds_between(start, Clock::now()) << " s wall, " << status_.recovered() << " steps recovered, " << status_.failed()
         << " failed";
    if (bus_.duplicate_commands() > 0) out_ << ", " << bus_.duplicate_commands() << " repeated commands answered again (not applied)";
    out_ << "\n";
  }

 private:
  void publish_topology() {
    const Engine& sim = run_.engine();
    const io::Scene& scene = run_.control().scene();
    TopologyData t = topology_record(sim.model().mesh, sim.model().fibers, sim.model().fixed_dofs, scene.region_names, state_nodes_);
    t.scene_name = scene.name;
    t.scene_hash = scene.hash_sha256;
    bus_.publish_topology(t);
    topology_version_ = run_.control().topology_version();
  }

  // Commands at the step boundary, within the command budget; each is logged in the
  // recording with the step it took effect at. @return how many were handled.
  int take_commands() {
    auto apply = [this](const std::string& kind, const std::string& args, const std::string& id) {
      const long step = run_.engine().step_count();
      const double time = run_.engine().time_s();
      CommandResult r = run_.control().apply(kind, args);  // the recording commands reach recording_ through it
      if (!r.accepted) status_.set_message("rejected " + kind + ": " + r.reason);
      recording_.after_command(step, time, id, kind, args, r);
      return CommandReply{r.accepted, r.reason};
    };
    auto stamp = [this] { return std::make_pair(static_cast<unsigned long>(run_.engine().step_count()), run_.control().parameter_version()); };
    return bus_.handle_commands(apply, stamp, wall_ns(o_.command_budget_ms * 1e-3));
  }

  // The state, and with it the circulation of the same frame (a run with one).
  void publish_state() {
    const Engine& sim = run_.engine();
    const unsigned long frame = static_cast<unsigned long>(sim.step_count());
    bus_.publish_state(frame, sim.time_s(), run_.control().parameter_version(), sim.positions(), state_nodes_, run_.activation());
    if (const core::circulation::Snapshot* c = run_.circulation()) bus_.publish_circulation(frame, *c);
  }

  // The state at most publish_hz (and at least every second, for the deadline); the
  // status every status period.
  void publish_due(Clock::time_point now) {
    if (states_.due(state_dirty_, now)) {
      const auto p0 = Clock::now();
      publish_state();
      status_.add_publish_ms(seconds_between(p0, Clock::now()) * 1e3);
      states_.published(now);
      state_dirty_ = false;
    }
    if (status_.due(now)) status_.publish(bus_, run_, status_.state(run_));
  }

  // Real time waits for the wall clock (listening for commands meanwhile); paused waits
  // for a command; behind by more than 0.25 s re-anchors (report, don't catch up).
  void pace(bool due, bool stepped) {
    const double sim_t = run_.engine().time_s();
    if (!due) {
      bus_.wait_for_command(wall_ns(std::max(0.0, pacer_.ahead_s(sim_t))));
    } else if (!stepped) {
      bus_.wait_for_command(std::chrono::milliseconds(20));
      pacer_.anchor(run_.engine().time_s());
    } else if (pacer_.realtime()) {
      const double ahead = pacer_.ahead_s(sim_t);
      if (ahead > 0) bus_.wait_for_command(wall_ns(ahead));
      else if (ahead < -0.25) pacer_.anchor(sim_t);
    }
  }

  const ServeOptions& o_;
  RunDriver& run_;
  RunEndpoints& bus_;
  std::ostream& out_;
  std::vector<int> state_nodes_;  // the nodes a state carries; empty: all
  unsigned topology_version_ = 0;
  detail::ServeStatus status_;
  detail::ServeRecording recording_;
  detail::WallClockPacer pacer_;
  detail::StateRateLimit states_;
  bool state_dirty_ = true;
};

}  // namespace

void ServeOptions::validate() const {
  if (!(real_time_factor > 0 && real_time_factor <= 100))
    throw std::invalid_argument("real_time_factor must be in (0, 100], got " + std::to_string(real_time_factor));
  if (!(publish_hz > 0 && publish_hz <= 1000)) throw std::invalid_argument("publish_hz must be in (0, 1000]");
  if (!(status_hz > 0 && status_hz <= 100)) throw std::invalid_argument("status_hz must be in (0, 100]");
  if (!(until_s >= 0 && std::isfinite(until_s))) throw std::invalid_argument("until_s must be >= 0");
  if (!(command_budget_ms > 0 && command_budget_ms <= 1e4))
    throw std::invalid_argument("command_budget_ms must be in (0, 1e4], got " + std::to_string(command_budget_ms));
}

int serve(const io::Scene& scene, const ServeOptions& options, std::ostream& out) {
  options.validate();
  // The endpoints first: the domain's discovery of them (a few hundred milliseconds on
  // loopback) goes on while the engine is set up, so a waiting client has matched them
  // by the time the first status and state go out.
  const std::string run_id = options.run_id.empty() ? default_run_id(scene.name) : options.run_id;
  std::unique_ptr<RunEndpoints> bus;
  try {
    bus = std::make_unique<RunEndpoints>(run_id);
  } catch (const dds::DdsError& e) {
    out << "fiberfem serve: " << e.what() << "\n";
    return 1;
  }
  RunDriver run(scene, Parameters::commanded, options.files);
  if (!options.resume.empty()) {
    run.resume(options.resume);
    out << "fiberfem serve: resumed from " << options.resume.path << " at t = " << run.engine().time_s() << " s (step "
        << run.engine().step_count() << ")\n";
  }
  if (options.start_paused) run.control().apply("pause", "{}");
  const auto start = Clock::now();
  const StopSignals stop_signals;  // until the last state and status are out
  ServeLoop loop(options, run, *bus, out);
  const core::TetMesh& mesh = run.engine().model().mesh;
  out << "fiberfem serve: run '" << run_id << "', scene '" << scene.name << "' (" << options.source << "), " << mesh.num_elements()
      << " tets, " << mesh.num_nodes() << " nodes, "
      << (options.realtime ? "real time x" + std::to_string(options.real_time_factor).substr(0, 4) : std::string("as fast as possible"))
      << ", states at up to " << options.publish_hz << " Hz\n"
      << std::flush;
  const std::string stop_reason = loop.run(stop_signals);
  loop.finish(stop_reason, start);
  return 0;
}

}  // namespace fiberfem::service
