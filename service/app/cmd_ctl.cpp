// `fiberfem ctl`: the command-line client (docs/ctl.md). List runs, watch a run's status,
// echo its frames, show its topology, and send any command (docs/commands.md), waiting
// for the acknowledgement: exit 0 when accepted, 3 when rejected, 4 on no answer, 5 when
// DDS Security does not permit this identity to send commands (docs/security.md).

#include "clients/ctl/client.hpp"
#include "clients/ctl/cycle.hpp"
#include "core/circulation/circulation.hpp"
#include "service/app/commands.hpp"
#include "service/stop_signals.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <csignal>
#include <fstream>
#include <cstdio>
#include <iostream>
#include <memory>
#include <numeric>
#include <unistd.h>

namespace fiberfem::app {
namespace {

using clients::Client;
using std::chrono::milliseconds;


struct CtlArgs {
  std::string run_id;
  double timeout_s = 10;
  // list
  double wait_s = 1.5;
  // status / echo
  bool watch = false, table = false;
  int count = 0;
  // send / flood
  std::string kind, args = "{}";
  int window = 8;
  // echo --follow, --circulation
  bool follow = false, circulation = false;
  double lost_after_s = 3;
  // play
  std::string script, log_file;
};

void print_status_line(const clients::RunStatus& s, bool same_line) {
  std::printf("%s%-24s %-9s t=%9.3f s  frame %8lu  %7.1f steps/s  x%5.2f real time  step %6.2f ms  iters %3d  res %.1e  inv %d  v%u%s",
              same_line ? "\r" : "", s.run_id.c_str(), s.state.c_str(), s.time_s, s.frame, s.frames_per_second,
              s.real_time_factor, s.step_ms, s.solver_iterations, s.solver_residual, s.inverted_elements, s.parameter_version,
              same_line ? "   " : "\n");
  std::fflush(stdout);
}

// echo --circulation: one line per circulation sample, in mmHg and mL (the wire's SI
// numbers converted), and the last complete beat's figures.
void print_circulation(const clients::Circulation& c) {
  namespace cc = core::circulation;
  const cc::Snapshot& s = c.snapshot;
  const auto mmhg = [](double pa) { return pa / cc::kPaPerMmHg; };
  const auto ml = [](double m3) { return m3 / cc::kM3PerMl; };
  std::printf("frame %lu t=%.4f s: LV %.2f mmHg %.3f mL, RV %.2f mmHg %.3f mL, LA %.2f mmHg, RA %.2f mmHg, aortic %.2f mmHg, "
              "pulmonary %.2f mmHg; flow aortic %.2f mL/s, pulmonary %.2f mL/s; %d iterations",
              static_cast<unsigned long>(c.frame), s.time_s, mmhg(s.chamber_pressure_pa[cc::lv]), ml(s.chamber_volume_m3[cc::lv]),
              mmhg(s.chamber_pressure_pa[cc::rv]), ml(s.chamber_volume_m3[cc::rv]), mmhg(s.chamber_pressure_pa[cc::la]),
              mmhg(s.chamber_pressure_pa[cc::ra]), mmhg(s.compartment_pressure_pa[cc::ar_sys]),
              mmhg(s.compartment_pressure_pa[cc::ar_pul]), ml(s.valve_flow_m3_s[cc::aortic]), ml(s.valve_flow_m3_s[cc::pulmonic]),
              s.pressure_iterations);
  if (s.last_beat.index >= 0) std::printf("; beat %d: %s", s.last_beat.index, cc::describe(s.last_beat).c_str());
  std::printf("\n");
}

// echo --circulation: every circulation sample of the run (a run without a circulation
// publishes none: exit 4 after --timeout).
int echo_circulation(Client& client, const std::string& run, const CtlArgs& a) {
  const service::StopSignals stop_signals(/*term_too=*/false);
  const std::chrono::milliseconds timeout(static_cast<long>(a.timeout_s * 1000));
  long last = -1;
  for (int shown = 0; !stop_signals.caught() && (a.count == 0 || shown < a.count);) {
    const auto samples = client.circulation(run, timeout, last);
    if (samples.empty()) {
      std::cerr << "fiberfem ctl: no circulation from '" << run << "' for " << a.timeout_s
                << " s (a run without a circulation publishes none)\n";
      return 4;
    }
    for (const clients::Circulation& c : samples) {
      if (a.count > 0 && shown >= a.count) break;
      print_circulation(c);
      last = static_cast<long>(c.frame), ++shown;
    }
    std::fflush(stdout);
  }
  return 0;
}

// echo --follow: frames of a run across service restarts and network cuts (the rule in
// clients/ctl/client.hpp, RunFollower); "lost" and "following" lines say what happened.
int follow_run(Client& client, const CtlArgs& a) {
  const service::StopSignals stop_signals(/*term_too=*/false);
  clients::RunFollower follower(client, a.run_id, milliseconds(static_cast<long>(a.lost_after_s * 1000)));
  const auto timeout = std::chrono::duration<double>(a.timeout_s);
  auto since_run = std::chrono::steady_clock::now();  // when a run was last followed
  for (int shown = 0; !stop_signals.caught() && (a.count == 0 || shown < a.count);) {
    const auto e = follower.next(milliseconds(200));
    if (!e) {
      if (follower.run_id().empty() && std::chrono::steady_clock::now() - since_run > timeout) {
        std::cerr << "fiberfem ctl: no run to follow for " << a.timeout_s << " s\n";
        return 4;
      }
      continue;
    }
    since_run = std::chrono::steady_clock::now();
    if (e->kind == clients::RunFollower::Event::Kind::lost) {
      std::printf("lost run %s: %s\n", e->run_id.c_str(), e->message.c_str());
    } else if (e->kind == clients::RunFollower::Event::Kind::found) {
      std::printf("following run %s: %s\n", e->run_id.c_str(), e->message.c_str());
    } else {
      const clients::State& st = *e->state;
      std::printf("frame %lu t=%.4f s v%u: %zu nodes, node 0 at [%.6g, %.6g, %.6g] m\n", st.frame, st.time_s, st.parameter_version,
                  st.positions.size() / 3, st.positions.size() ? st.positions[0] : 0.f, st.positions.size() ? st.positions[1] : 0.f,
                  st.positions.size() ? st.positions[2] : 0.f);
      ++shown;
    }
    std::fflush(stdout);
  }
  return 0;
}

int run_ctl(const std::string& what, CtlArgs& a) {
  const milliseconds timeout(static_cast<long>(a.timeout_s * 1000));
  // A bad script is reported before looking for a run (no run needed to learn it is bad).
  clients::CycleScript script;
  if (what == "play") script = clients::load_cycle(a.script);
  Client client;
  if (what == "echo" && a.circulation && !client.listen_circulation())  // matched while the run is resolved
    throw clients::NotPermitted(client.circulation_refused());
  if (what == "list") {
    const auto runs = client.discover(milliseconds(static_cast<long>(a.wait_s * 1000)));
    if (runs.empty()) {
      std::cerr << "fiberfem ctl: no runs seen in " << a.wait_s << " s\n";
      return 1;
    }
    std::printf("%-32s %-16s %-10s %-9s %10s %9s %8s %s\n", "run", "scene", "host", "state", "t (s)", "steps/s", "rt", "pid");
    for (const auto& [id, s] : runs)
      std::printf("%-32s %-16s %-10s %-9s %10.3f %9.1f %8.2f %d%s\n", id.c_str(), s.scene_name.c_str(), s.host.c_str(),
                  s.state.c_str(), s.time_s, s.frames_per_second, s.real_time_factor, s.pid, s.replay ? " replay" : "");
    return 0;
  }
  if (what == "echo" && a.follow) return follow_run(client, a);
  const std::string run = client.resolve_run(a.run_id, timeout);
  if (what == "flood") {
    const clients::FloodReport r = client.flood(run, a.kind, a.args, a.count, a.window, timeout);
    std::vector<double> lat = r.latencies_ms;
    std::sort(lat.begin(), lat.end());
    const auto pct = [&](double p) { return lat.empty() ? 0.0 : lat[std::min(lat.size() - 1, static_cast<size_t>(p * static_cast<double>(lat.size())))]; };
    std::string versions;
    for (unsigned v : r.versions) versions += (versions.empty() ? "" : ",") + std::to_string(v);
    std::printf("{\"run\": \"%s\", \"client\": \"%s\", \"sent\": %d, \"acked\": %d, \"accepted\": %d, \"duplicate_acks\": %d, \"resent\": %d, "
                "\"seconds\": %.4f, \"commands_per_s\": %.1f, \"latency_ms_median\": %.3f, \"latency_ms_p99\": %.3f, \"versions\": [%s]}\n",
                run.c_str(), client.client_id().c_str(), r.sent, r.acked, r.accepted, r.duplicate_acks, r.resent, r.seconds,
                r.seconds > 0 ? r.acked / r.seconds : 0.0, pct(0.5), pct(0.99), versions.c_str());
    return r.acked == r.sent && r.duplicate_acks <= r.resent ? 0 : 4;
  }
  if (what == "status") {
    const service::StopSignals stop_signals(/*term_too=*/false);
    const bool tty = isatty(fileno(stdout)) != 0;
    int shown = 0;
    do {
      const auto s = client.status(run, timeout);
      if (!s) {
        std::cerr << "\nfiberfem ctl: no status from '" << run << "' for " << a.timeout_s << " s\n";
        return 4;
      }
      if (a.table) {
        std::printf("run %s\n  scene %s on %s (pid %d), %s, %s\n  t %.4f s, frame %lu, dt %.4g s\n"
                    "  %.1f steps/s, real-time factor %.3f, step %.3f ms (solve %.3f ms), publish %.3f ms\n"
                    "  solver %d iterations, residual %.2e; %d inverted; %u recovered, %u failed steps\n"
                    "  energies: kinetic %.4e J, elastic %.4e J\n  heart rate %.1f /min, peak tension %.4g Pa, parameter version %u\n"
                    "  recording: %s\n  last message: %s\n",
                    s->run_id.c_str(), s->scene_name.c_str(), s->host.c_str(), s->pid, s->state.c_str(), s->mode.c_str(), s->time_s,
                    s->frame, s->dt_s, s->frames_per_second, s->real_time_factor, s->step_ms, s->solve_ms, s->publish_ms,
                    s->solver_iterations, s->solver_residual, s->inverted_elements, s->recovered_steps, s->failed_steps,
                    s->kinetic_energy_j, s->elastic_energy_j, s->heart_rate_bpm, s->peak_tension_pa, s->parameter_version,
                    s->recording.empty() ? "off" : s->recording.c_str(), s->last_message.empty() ? "-" : s->last_message.c_str());
      } else {
        print_status_line(*s, a.watch && tty);
      }
      ++shown;
    } while ((a.watch || a.count > shown) && !stop_signals.caught() && (a.count == 0 || shown < a.count));
    if (a.watch && tty) std::printf("\n");
    return 0;
  }
  if (what == "echo" && a.circulation) return echo_circulation(client, run, a);
  if (what == "echo") {
    const service::StopSignals stop_signals(/*term_too=*/false);
    long last = -1;
    for (int shown = 0; !stop_signals.caught() && (a.count == 0 || shown < a.count); ++shown) {
      const auto st = client.next_state(run, timeout, last);
      if (!st) {
        std::cerr << "fiberfem ctl: no state from '" << run << "' for " << a.timeout_s << " s\n";
        return 4;
      }
      last = static_cast<long>(st->frame);
      const double act = st->activation.empty() ? 0.0
                                                : std::accumulate(st->activation.begin(), st->activation.end(), 0.0) /
                                                      static_cast<double>(st->activation.size());
      std::printf("frame %lu t=%.4f s v%u: %zu nodes, node 0 at [%.6g, %.6g, %.6g] m, mean activation %.4f\n", st->frame,
                  st->time_s, st->parameter_version, st->positions.size() / 3, st->positions.size() ? st->positions[0] : 0.f,
                  st->positions.size() ? st->positions[1] : 0.f, st->positions.size() ? st->positions[2] : 0.f, act);
      std::fflush(stdout);
    }
    return 0;
  }
  if (what == "topology") {
    const auto t = client.topology(run, timeout);
    if (!t) {
      std::cerr << "fiberfem ctl: no topology from '" << run << "' for " << a.timeout_s << " s\n";
      return 4;
    }
    std::string regions;
    for (const auto& r : t->region_names) regions += (regions.empty() ? "" : ", ") + r;
    std::printf("run %s: scene %s (sha256 %.12s...), %u nodes, %u elements, %zu boundary triangles, regions [%s], %zu fixed nodes, "
                "states carry %s%s\n",
                t->run_id.c_str(), t->scene_name.c_str(), t->scene_hash.c_str(), t->num_nodes, t->num_elements,
                t->triangles.size() / 3, regions.c_str(), t->fixed_nodes.size(),
                t->state_nodes.empty() ? "all nodes" : (std::to_string(t->state_nodes.size()) + " surface nodes").c_str(),
                t->replay ? " (replay)" : "");
    return 0;
  }
  if (what == "play") {
    if (a.log_file.empty()) return clients::play_cycle(client, run, std::move(script), std::cout);
    std::ofstream log(a.log_file);
    if (!log) throw std::runtime_error("cannot write the log " + a.log_file);
    struct Tee : std::streambuf {
      std::streambuf *a, *b;
      int overflow(int c) override { return c == EOF ? !EOF : (a->sputc(static_cast<char>(c)), b->sputc(static_cast<char>(c))); }
      int sync() override { return a->pubsync() | b->pubsync(); }
    } tee;
    tee.a = std::cout.rdbuf(), tee.b = log.rdbuf();
    std::ostream both(&tee);
    return clients::play_cycle(client, run, std::move(script), both);
  }
  // send
  const clients::Ack ack = client.send(run, a.kind, a.args, timeout);
  std::printf("%s %s: %s (frame %lu, parameter version %u)\n", a.kind.c_str(), ack.accepted ? "accepted" : "rejected",
              ack.reason.c_str(), ack.frame, ack.parameter_version);
  return ack.accepted ? 0 : 3;
}

}  // namespace

void add_ctl_command(CLI::App& app, int& exit_code) {
  auto* ctl = app.add_subcommand("ctl", "Command-line client of running services (DDS)");
  ctl->require_subcommand(1);
  auto a = std::make_shared<CtlArgs>();
  ctl->add_option("--run", a->run_id, "Run id (default: the only run on the domain)");
  ctl->add_option("--timeout", a->timeout_s, "How long to wait for a service, state or acknowledgement, s")
      ->check(CLI::Range(0.01, 3600.0))
      ->capture_default_str();

  auto* list = ctl->add_subcommand("list", "List the runs on the domain");
  list->add_option("--wait", a->wait_s, "How long to listen for status, s")->check(CLI::Range(0.1, 600.0))->capture_default_str();
  auto* status = ctl->add_subcommand("status", "Show a run's status");
  status->add_flag("--watch", a->watch, "Keep refreshing one line until Ctrl-C");
  status->add_flag("--table", a->table, "All fields, one per line");
  status->add_option("--count", a->count, "Show this many status samples")->check(CLI::PositiveNumber);
  auto* echo = ctl->add_subcommand("echo", "Print the frames a run publishes");
  echo->add_option("--count", a->count, "Stop after this many frames (default: until Ctrl-C)")->check(CLI::PositiveNumber);
  echo->add_flag("--follow", a->follow,
                 "Follow the run across service restarts and network cuts (--run ID: that id; none: the only run, then the only run "
                 "of its scene); --timeout bounds the time with no run to follow");
  echo->add_flag("--circulation", a->circulation,
                 "Print the run's circulation instead (pressures in mmHg, volumes in mL, the last beat's figures; a run "
                 "with a circulation only)")
      ->excludes("--follow");
  echo->add_option("--lost-after", a->lost_after_s, "With --follow: a run is lost after this long without a status, s")
      ->check(CLI::Range(0.1, 600.0))
      ->capture_default_str();
  auto* topo = ctl->add_subcommand("topology", "Print a run's topology (mesh, regions, fibers)");
  auto* send = ctl->add_subcommand("send", "Send a command and wait for its acknowledgement (docs/commands.md)");
  send->add_option("kind", a->kind, "Command kind, e.g. pause, apply_force, set_contraction")->required();
  send->add_option("args", a->args, "Arguments as a JSON object")->capture_default_str();
  auto* flood = ctl->add_subcommand("flood", "Send COUNT commands with up to WINDOW unacknowledged; print a JSON report of the acks");
  flood->add_option("kind", a->kind, "Command kind, e.g. set_gravity")->required();
  flood->add_option("args", a->args, "Arguments as a JSON object")->capture_default_str();
  flood->add_option("--count", a->count, "Commands to send")->check(CLI::Range(1, 10000000))->required();
  flood->add_option("--window", a->window, "Commands in flight at most")->check(CLI::Range(1, 64))->capture_default_str();
  auto* play = ctl->add_subcommand("play", "Play a cycle script (docs/cycles.md) against a run");
  play->add_option("script", a->script, "Cycle script (YAML), e.g. configs/cycles/exercise.yaml")->required();
  play->add_option("--log", a->log_file, "Also write the log of actions here");
  for (CLI::App* sub : {list, status, echo, topo, send, flood, play}) {
    const std::string name = sub->get_name();
    sub->callback([a, name, &exit_code] {
      try {
        exit_code = run_ctl(name, *a);
      } catch (const clients::NotPermitted& e) {
        std::cerr << "fiberfem ctl: " << e.what() << "\n";
        exit_code = 5;
      } catch (const std::exception& e) {
        std::cerr << "fiberfem ctl: " << e.what() << "\n";
        exit_code = 4;
      }
    });
  }
}

}  // namespace fiberfem::app
