// The service loop (DESIGN.md section 2): drain commands -> apply at the step boundary ->
// step -> publish -> status, paced to the wall clock in real-time mode.

#include "service/serve.hpp"
#include "service/stop_signals.hpp"

#include "service/run_endpoints.hpp"
#ifdef FIBERFEM_HAVE_ARCHIVE
#include "core/cavity.hpp"
#include "service/archive/archive.hpp"
#endif
#include "service/run_control.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <ostream>
#include <stdexcept>
#include <thread>
#include <unistd.h>

namespace fiberfem::service {
namespace {

using Clock = std::chrono::steady_clock;


double seconds_between(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double>(b - a).count(); }

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  const size_t m = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(m), v.end());
  return v[m];
}

// The topology of the running scene, as published.
TopologyData topology_of(const RunControl& rc, const std::vector<int>& state_nodes) {
  const core::Simulator& sim = rc.simulator();
  const core::TetMesh& m = sim.model().mesh;
  TopologyData t;
  t.scene_name = rc.scene().name;
  t.scene_hash = rc.scene().hash_sha256;
  t.num_nodes = m.num_nodes();
  t.num_elements = m.num_elements();
  const int nn = m.num_nodes(), ne = m.num_elements();
  t.rest_positions.resize(3 * static_cast<size_t>(nn));
  for (int n = 0; n < nn; ++n)
    for (int d = 0; d < 3; ++d) t.rest_positions[3 * static_cast<size_t>(n) + d] = static_cast<float>(m.rest_positions()(d, n));
  for (const auto& e : m.tets()) t.tets.insert(t.tets.end(), e.begin(), e.end());
  for (const auto& f : m.boundary_triangles()) t.triangles.insert(t.triangles.end(), f.begin(), f.end());
  t.triangle_elements.assign(m.boundary_triangle_elements().begin(), m.boundary_triangle_elements().end());
  t.element_regions.assign(m.regions().begin(), m.regions().end());
  t.region_names = rc.scene().region_names;
  t.fibers.resize(3 * static_cast<size_t>(ne));
  const auto& f = sim.model().fibers;
  for (int e = 0; e < ne; ++e)
    for (int d = 0; d < 3; ++d)
      t.fibers[3 * static_cast<size_t>(e) + d] = f.empty() ? (d == 0 ? 1.f : 0.f) : static_cast<float>(f[static_cast<size_t>(e)](d));
  t.state_nodes.assign(state_nodes.begin(), state_nodes.end());
  const auto& fixed = sim.model().fixed_dofs;
  if (!fixed.empty())
    for (int n = 0; n < nn; ++n)
      if (fixed[3 * static_cast<size_t>(n)] || fixed[3 * static_cast<size_t>(n) + 1] || fixed[3 * static_cast<size_t>(n) + 2])
        t.fixed_nodes.push_back(n);
  return t;
}

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
  RunControl rc(scene, options.files);
  if (!options.resume_path.empty()) {
#ifdef FIBERFEM_HAVE_ARCHIVE
    // The archived checkpoint and the parameters it ran with (a served run's checkpoints
    // carry the running scene and forces; a batch run's, none: the archived scene).
    const archive::ArchiveReader from(options.resume_path);
    const size_t k = from.checkpoint_at_or_before(options.resume_time_s);  // inf: the last
    std::string params;
    const core::SimulatorCheckpoint cp = from.read_checkpoint(k, &params);
    try {
      if (params.find("scene_yaml") != std::string::npos) rc.restore_parameter_state(params);
      rc.simulator().restore(cp);
    } catch (const std::invalid_argument& e) {  // another scene's archive, or its parameters
      throw std::invalid_argument("--resume " + options.resume_path + ": " + e.what() + " (the archive is of another scene or mesh)");
    }
    out << "fiberfem serve: resumed from " << options.resume_path << " at t = " << rc.simulator().time_s() << " s (step "
        << rc.simulator().step_count() << ")\n";
#else
    throw std::runtime_error("--resume: this fiberfem was built without HDF5 (FIBERFEM_WITH_HDF5)");
#endif
  }
  if (options.start_paused) rc.apply("pause", "{}");
  const std::string run_id = options.run_id.empty() ? default_run_id(scene.name) : options.run_id;
#ifdef FIBERFEM_HAVE_ARCHIVE
  std::unique_ptr<archive::ArchiveWriter> recorder;  // while recording
  std::string recording_path;
  std::vector<double> rec_ms;  // recording time of each frame in the status period, ms
  io::ArchiveSettings recording_settings;  // of the first file of the current series
  int recording_part = 1;
#endif
  std::unique_ptr<RunEndpoints> bus;
  try {
    bus = std::make_unique<RunEndpoints>(run_id);
  } catch (const dds::DdsError& e) {
    out << "fiberfem serve: " << e.what() << "\n";
    return 1;
  }
  const core::TetMesh& mesh = rc.simulator().model().mesh;
  const std::vector<int> state_nodes = options.surface_only ? mesh.boundary_nodes() : std::vector<int>{};
  bus->publish_topology(topology_of(rc, state_nodes));
  unsigned topology_version = rc.topology_version();

  std::vector<float> pos_buf, act_buf;
  auto publish_state = [&] {
    const core::Simulator& sim = rc.simulator();
    const auto x = sim.positions();
    if (state_nodes.empty()) {
      pos_buf.resize(static_cast<size_t>(x.size()));
      for (Eigen::Index i = 0; i < x.size(); ++i) pos_buf[static_cast<size_t>(i)] = static_cast<float>(x.data()[i]);
    } else {
      pos_buf.resize(3 * state_nodes.size());
      for (size_t k = 0; k < state_nodes.size(); ++k)
        for (int d = 0; d < 3; ++d) pos_buf[3 * k + d] = static_cast<float>(x(d, state_nodes[k]));
    }
    // Activation: tension over its region's peak, 0..1 (empty when contraction is off).
    act_buf.clear();
    if (!sim.active_tension().empty())
      for (double a : sim.model().contraction.activation(sim.model().mesh.regions(), sim.active_tension()))
        act_buf.push_back(static_cast<float>(a));
    bus->publish_state(static_cast<unsigned long>(sim.step_count()), sim.time_s(), rc.parameter_version(), pos_buf, act_buf);
  };

  const StopSignals stop_signals;

  out << "fiberfem serve: run '" << run_id << "', scene '" << scene.name << "' (" << options.source << "), "
      << mesh.num_elements() << " tets, " << mesh.num_nodes() << " nodes, "
      << (options.realtime ? "real time x" + std::to_string(options.real_time_factor).substr(0, 4) : std::string("as fast as possible"))
      << ", states at up to " << options.publish_hz << " Hz\n"
      << std::flush;

  // Status bookkeeping over one status period.
  std::vector<double> step_ms, rot_ms, asm_ms, solve_ms, pub_ms;
  core::StepReport last{};
  unsigned recovered = 0, failed = 0;
  std::string last_message, state_name = "running";
  long steps_in_period = 0;
  double sim_t_period = rc.simulator().time_s();
  const auto t_start = Clock::now();
  auto t_period = t_start, t_last_state = t_start - std::chrono::hours(1), t_tokens = t_start;
  // States are rate-limited by a token bucket (publish_hz tokens a second, at most two
  // kept): a strict minimum interval lost every other frame when the steps came at the
  // publish rate (real time at 60 steps/s and 60 Hz: a step a little early by the wall
  // clock was held back to the next one, 30 frames/s measured).
  double state_tokens = 1.0;
  auto pace_wall = t_start;
  double pace_sim = rc.simulator().time_s();
  bool state_dirty = true;

  auto t_plain_status = t_start;
  auto publish_status = [&](const std::string& state) {
    const auto now = Clock::now();
    const double wall = std::max(1e-9, seconds_between(t_period, now));
    const core::Simulator& sim = rc.simulator();
    StatusData st;
    st.scene_name = scene.name;
    st.state = state;
    st.mode = options.realtime ? "realtime" : "fast";
    st.frame = static_cast<unsigned long>(sim.step_count());
    st.time_s = sim.time_s();
    st.frames_per_second = static_cast<double>(steps_in_period) / wall;
    st.real_time_factor = (sim.time_s() - sim_t_period) / wall;
    st.step_ms = median(step_ms);
    st.rotations_ms = median(rot_ms);
    st.assembly_ms = median(asm_ms);
    st.solve_ms = median(solve_ms);
    st.publish_ms = median(pub_ms);
    st.solver_iterations = last.solver_iterations;
    st.solver_residual = last.solver_residual;
    st.inverted_elements = last.inverted_elements;
    st.kinetic_energy_j = last.kinetic_energy_j;
    st.elastic_energy_j = last.elastic_energy_j;
    st.recovered_steps = recovered;
    st.failed_steps = failed;
    st.last_message = last_message;
    st.parameter_version = rc.parameter_version();
    st.heart_rate_bpm = rc.heart_rate_bpm();
    st.peak_tension_pa = rc.peak_tension_pa();
    st.dt_s = sim.settings().dt_s;
#ifdef FIBERFEM_HAVE_ARCHIVE
    if (recorder) {
      st.recording = recording_path;
      st.recorded_frames = static_cast<unsigned long>(recorder->frames());
      st.record_ms = median(rec_ms);
    }
    rec_ms.clear();
#endif
    bus->publish_status(st);
    if (options.status_line) {
      std::fprintf(stderr, "\r%-8s t=%8.3f s  frame %7ld  %6.1f steps/s  x%.2f real time  step %.2f ms  iters %3d  v%u%s%s   ",
                   state.c_str(), sim.time_s(), sim.step_count(), st.frames_per_second, st.real_time_factor, st.step_ms,
                   last.solver_iterations, rc.parameter_version(), st.recording.empty() ? "" : "  rec ",
                   st.recording.empty() ? "" : (std::to_string(st.recorded_frames) + " frames").c_str());
      std::fflush(stderr);
    } else if (seconds_between(t_plain_status, now) >= 1.0) {  // not a terminal: a plain line a second
      char line[256];
      std::snprintf(line, sizeof line, "status: %s t=%.3f s frame %ld, %.1f steps/s, x%.2f real time, step %.2f ms, %d iterations%s%s\n",
                    state.c_str(), sim.time_s(), sim.step_count(), st.frames_per_second, st.real_time_factor, st.step_ms,
                    last.solver_iterations, st.recording.empty() ? "" : ", recording ", st.recording.c_str());
      out << line << std::flush;
      t_plain_status = now;
    }
    step_ms.clear(), rot_ms.clear(), asm_ms.clear(), solve_ms.clear(), pub_ms.clear();
    steps_in_period = 0;
    sim_t_period = sim.time_s();
    t_period = now;
  };
  // Recording (docs/archive.md): from the start, or by start_recording / stop_recording.
#ifdef FIBERFEM_HAVE_ARCHIVE
  auto record = [&](const core::StepReport& r) {
    const auto t0 = Clock::now();
    std::vector<std::pair<std::string, double>> cav;
    for (const io::CavityMeasure& c : scene.cavities) cav.emplace_back(c.name, core::cavity_volume(c.surface, rc.simulator().positions()));
    recorder->record_frame(rc.simulator(), r, {cav});
    rec_ms.push_back(seconds_between(t0, Clock::now()) * 1e3);
  };
  auto start_recording = [&](const io::ArchiveSettings& a) {
    archive::ArchiveOptions ao;
    ao.path = a.path;
    ao.flush_frames = a.flush_frames;
    ao.flush_seconds = a.flush_seconds;
    ao.every_steps = a.every_steps;
    ao.velocities = a.velocities;
    ao.displacement = a.displacement;
    ao.checkpoint_every_s = a.checkpoint_every_s;
    ao.compression = a.compression;
    ao.validate();
    const io::Scene running = rc.parameter_version() == 0 ? scene : rc.running_scene();
    recorder = std::make_unique<archive::ArchiveWriter>(ao, running, rc.simulator(), options.source + " (served as " + run_id + ")");
    recorder->set_parameter_state(rc.parameter_state_json());
    recorder->checkpoint(rc.simulator(), rc.parameter_state_json());
    core::StepReport initial;
    initial.time_s = rc.simulator().time_s();
    record(initial);
    recording_path = a.path;
  };
  auto start_series = [&](const io::ArchiveSettings& a) {
    recording_settings = a;
    recording_part = 1;
    start_recording(a);
  };
  auto stop_recording = [&] {
    recorder->checkpoint(rc.simulator(), rc.parameter_state_json());
    const long frames = recorder->frames();
    recorder->close();
    recorder.reset();
    out << "fiberfem serve: recorded " << frames << " frames to " << recording_path << "\n" << std::flush;
    const std::string done = recording_path;
    recording_path.clear();
    return std::make_pair(done, frames);
  };
  if (options.archive.enabled) start_series(options.archive);
#endif
  publish_status("starting");

  // start_recording {path, flush_frames, flush_seconds, every, velocities, checkpoint_every,
  // compression} and stop_recording {} (docs/commands.md): the keys of the scene's archive.
  auto recording_command = [&](const std::string& kind, const std::string& args) -> CommandResult {
#ifdef FIBERFEM_HAVE_ARCHIVE
    try {
      if (kind == "stop_recording") {
        if (!recorder) return {false, "not recording"};
        if (!args.empty() && args.find_first_not_of(" {}\n\t") != std::string::npos) return {false, "stop_recording takes no arguments"};
        const auto [path, frames] = stop_recording();
        return {true, "recorded " + std::to_string(frames) + " frames to " + path};
      }
      if (recorder) return {false, "already recording to " + recording_path + " (stop_recording first)"};
      const io::ArchiveSettings a = io::parse_archive_settings(args.empty() ? "{}" : args, "start_recording");
      start_series(a);
      return {true, "recording to " + a.path};
    } catch (const std::exception& e) {
      recorder.reset();
      recording_path.clear();
      return {false, e.what()};
    }
#else
    (void)kind, (void)args;
    return {false, "this fiberfem was built without HDF5 (FIBERFEM_WITH_HDF5): no recording"};
#endif
  };

  rc.set_recording_handler(recording_command);

  std::string stop_reason = "shut down by command";
  for (;;) {
    // 1. Commands, at the step boundary.
    const int handled = bus->handle_commands(
        [&](const std::string& kind, const std::string& args, const std::string& id) {
          CommandResult r;
          const long step = rc.simulator().step_count();
          const double time = rc.simulator().time_s();
          r = rc.apply(kind, args);  // the recording commands reach recording_command through rc
          if (!r.accepted) last_message = "rejected " + kind + ": " + r.reason;
#ifdef FIBERFEM_HAVE_ARCHIVE
          if (recorder) {  // every command, with the step it took effect at and its ack
            recorder->record_command({step, time, id, kind, args, r.accepted, r.accepted ? "" : r.reason});
            if (r.accepted) recorder->set_parameter_state(rc.parameter_state_json());
            // An archive's frames run forward in time: a restore or reset ends it and
            // recording goes on in the next file (RUN-2.h5, RUN-3.h5, ...).
            if (r.accepted && (kind == "restore" || kind == "reset")) {
              io::ArchiveSettings next = recording_settings;
              const std::string base = next.path.size() > 3 && next.path.substr(next.path.size() - 3) == ".h5"
                                           ? next.path.substr(0, next.path.size() - 3) : next.path;
              next.path = base + "-" + std::to_string(++recording_part) + ".h5";
              stop_recording();
              start_recording(next);
              r.reason += "; recording continues in " + next.path;
            }
          }
#else
          (void)step, (void)time, (void)id;
#endif
          return CommandReply{r.accepted, r.reason};
        },
        [&] { return std::make_pair(static_cast<unsigned long>(rc.simulator().step_count()), rc.parameter_version()); },
        std::chrono::nanoseconds(static_cast<long long>(options.command_budget_ms * 1e6)));
    if (handled) state_dirty = true;
    if (rc.topology_version() != topology_version) {
      bus->publish_topology(topology_of(rc, state_nodes));
      topology_version = rc.topology_version();
    }
    if (rc.shutdown_requested()) break;
    if (stop_signals.caught()) {
      stop_reason = std::string("stopped by ") + stop_signals.name();
      break;
    }
    if (options.until_s > 0 && rc.simulator().time_s() >= options.until_s - 1e-9) {
      stop_reason = "reached t = " + std::to_string(options.until_s) + " s";
      break;
    }

    // 2. Step (unless paused, or in real time ahead of the wall clock: a command woke the
    // wait early, and the step is not due yet).
    auto ahead_s = [&] {
      return (rc.simulator().time_s() - pace_sim) / options.real_time_factor - seconds_between(pace_wall, Clock::now());
    };
    const bool due = !options.realtime || ahead_s() <= 0;
    bool stepped = false;
    if (due && rc.take_step_permission()) {
      rc.before_step();
      last = rc.simulator().step();
#ifdef FIBERFEM_HAVE_ARCHIVE
      if (recorder) record(last);
#endif
      stepped = true;
      ++steps_in_period;
      step_ms.push_back(last.time.total_s * 1e3);
      rot_ms.push_back(last.time.rotations_s * 1e3);
      asm_ms.push_back(last.time.assembly_s * 1e3);
      solve_ms.push_back(last.time.solve_s * 1e3);
      if (last.status == core::StepStatus::recovered) ++recovered, state_name = "recovered", last_message = last.message;
      else if (last.status == core::StepStatus::failed) ++failed, state_name = "failed", last_message = last.message;
      else state_name = "running";
      state_dirty = true;
    }
    const auto now = Clock::now();

    // 3. Publish the state at most publish_hz (and at least every second, for the deadline).
    const double since_state = seconds_between(t_last_state, now);
    state_tokens = std::min(2.0, state_tokens + seconds_between(t_tokens, now) * options.publish_hz);
    t_tokens = now;
    if ((state_dirty && state_tokens >= 1.0) || since_state >= 1.0) {
      const auto p0 = Clock::now();
      publish_state();
      pub_ms.push_back(seconds_between(p0, Clock::now()) * 1e3);
      t_last_state = now;
      state_dirty = false;
      state_tokens = std::max(0.0, state_tokens - 1.0);
    }
    if (seconds_between(t_period, now) >= 1.0 / options.status_hz) publish_status(rc.paused() ? "paused" : state_name);

    // 4. Pace: real time waits for the wall clock (listening for commands meanwhile);
    // paused waits for a command.
    if (!due) {
      bus->wait_for_command(std::chrono::nanoseconds(static_cast<long long>(std::max(0.0, ahead_s()) * 1e9)));
    } else if (!stepped) {
      bus->wait_for_command(std::chrono::milliseconds(20));
      pace_wall = Clock::now();
      pace_sim = rc.simulator().time_s();
    } else if (options.realtime) {
      const double ahead = ahead_s();
      if (ahead > 0) {
        bus->wait_for_command(std::chrono::nanoseconds(static_cast<long long>(ahead * 1e9)));
      } else if (ahead < -0.25) {  // behind by more than 0.25 s: re-anchor (report, don't catch up)
        pace_wall = Clock::now();
        pace_sim = rc.simulator().time_s();
      }
    }
  }
#ifdef FIBERFEM_HAVE_ARCHIVE
  if (recorder) stop_recording();
#endif
  publish_state();
  publish_status("stopped");
  if (options.status_line) std::fprintf(stderr, "\n");
  const double wall = seconds_between(t_start, Clock::now());
  out << "fiberfem serve: " << stop_reason << "; " << rc.simulator().step_count() << " steps, t = " << rc.simulator().time_s()
      << " s in " << wall << " s wall, " << recovered << " steps recovered, " << failed << " failed";
  if (bus->duplicate_commands() > 0) out << ", " << bus->duplicate_commands() << " repeated commands answered again (not applied)";
  out << "\n";
  return 0;
}

}  // namespace fiberfem::service
