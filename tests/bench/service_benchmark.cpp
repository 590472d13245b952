// Figures of the service on DDS (docs/service-performance.md), on loopback:
//   frames   steps per second the service sustains while publishing every step (--fast,
//            publish rate unbounded), and the states a client receives per second, for
//            the default heart and a ~100,000-node box;
//   latency  command-to-effect: a command sent until the first state that reflects it
//            (its DDS source timestamp), median and 99th percentile, on the heart in real time;
//   throughput  states of N nodes published back to back with the service's type and
//            QoS, received per second by another process; compare with ddsperf's output
//            for the same payload size in the same run (printed by this program);
//   first-frames  a large scene's start: from spawning `fiberfem serve --fast` to the first
//            state, to the first stepped state (t > 0), and to steps 10 and 60, with the
//            first factorisation made beside the steps and waited for, alternated
//            (--scene FILE, repeatable; --repeat N runs of each; --against OLD_FIBERFEM
//            runs each case with another binary too, alternated);
//   security the cost of DDS Security (docs/security.md): the heart's frames, the command
//            latencies and the state throughput with the plain profile (CYCLONEDDS_URI)
//            and with the secure profiles of --secure-dir (scripts/make_security.sh), in
//            one run, case by case, and their ratios.
// Run: CYCLONEDDS_URI=file://$PWD/configs/dds/loopback-large.xml build/release/tests/bench/bench_service all

#include "clients/ctl/client.hpp"
#include "process_support.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <sys/wait.h>
#include <thread>

using namespace std::chrono_literals;
using fiberfem::clients::Client;
using fiberfem::testing::BackgroundProcess;
using Clock = std::chrono::steady_clock;

namespace {

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(p * static_cast<double>(v.size())))];
}

double now_epoch_s() { return static_cast<double>(dds_time()) * 1e-9; }

// The DDS profiles (CYCLONEDDS_URI values) of each party; empty: this process's own.
// Cyclone reads CYCLONEDDS_URI when a process creates its first participant (again once
// all are gone), so each case sets it before it makes its participants.
struct Profiles {
  std::string service;     ///< the `fiberfem serve` process
  std::string client;      ///< this process as a client (frames, latency): commands and states
  std::string publisher;   ///< this process as the state writer (throughput)
  std::string subscriber;  ///< the forked state reader (throughput)
};
Profiles profiles;

void use_profile(const std::string& uri) {
  if (!uri.empty()) setenv("CYCLONEDDS_URI", uri.c_str(), 1);
}
std::vector<std::string> service_env() {
  if (profiles.service.empty()) return {};
  return {"CYCLONEDDS_URI=" + profiles.service};
}

struct FramesResult {
  double steps_per_s = 0, received_per_s = 0;
};
struct LatencyResult {
  double effect_median_ms = 0, effect_p99_ms = 0, ack_median_ms = 0, ack_p99_ms = 0;
};

FramesResult frames(const std::string& label, std::vector<std::string> serve_args, double seconds) {
  const std::string run = "bench-" + label + "-" + std::to_string(getpid());
  std::vector<std::string> args = {FIBERFEM_BIN, "serve", "--run-id", run, "--fast", "--publish-hz", "1000", "--status-hz", "1"};
  args.insert(args.end(), serve_args.begin(), serve_args.end());
  BackgroundProcess service(args, "/tmp/bench-service-" + run + ".log", service_env());
  use_profile(profiles.client);
  Client client;
  client.resolve_run(run, 600s);
  const auto topo = client.topology(run, 60s);
  long last = -1, received = 0;
  const auto first = client.next_state(run, 600s);  // past set-up
  last = static_cast<long>(first->frame);
  const auto t0 = Clock::now();
  const long frame0 = last;
  while (std::chrono::duration<double>(Clock::now() - t0).count() < seconds) {
    const auto s = client.next_state(run, 60s, last);
    if (!s) break;
    last = static_cast<long>(s->frame);
    ++received;
  }
  const double wall = std::chrono::duration<double>(Clock::now() - t0).count();
  const auto st = client.status(run, 5s);
  std::printf("| %s | %u | %u | %.1f | %.1f | %.2f | %.3f | %.2f |\n", label.c_str(), topo ? topo->num_nodes : 0,
              topo ? topo->num_elements : 0, static_cast<double>(last - frame0) / wall, static_cast<double>(received) / wall,
              st ? st->step_ms : 0.0, st ? st->publish_ms : 0.0,
              topo ? 12.0 * topo->num_nodes / 1e6 + 4.0 * topo->num_elements / 1e6 : 0.0);
  std::fflush(stdout);
  client.send(run, "shutdown", "{}");
  service.wait(30);
  return {static_cast<double>(last - frame0) / wall, static_cast<double>(received) / wall};
}

// Seconds from spawning the service of `scene` (with solver.first_factorisation=`first`)
// to its first state, its first stepped state and its states of steps 10 and 60.
std::array<double, 4> first_frames(const std::string& scene, const std::string& first, const std::string& binary) {
  const std::string run = "bench-first-" + std::to_string(getpid());
  const auto t0 = Clock::now();
  BackgroundProcess service({binary, "serve", scene, "--run-id", run, "--fast", "--publish-hz", "1000", "--status-hz", "1",
                             "--set", "solver.first_factorisation=" + first},
                            "/tmp/bench-first-frames.log", service_env());
  use_profile(profiles.client);
  Client client;
  // A client already listening for states (as the web view or `ctl echo` started before
  // the service): its reader matches the service's writer while the engine is set up, so
  // the starting state, published before the first step, reaches it.
  client.next_state(run, 0s);
  client.resolve_run(run, 600s);
  std::array<double, 4> at{};
  const double marks[4] = {-1.0, 0.5, 9.5, 59.5};  // in steps, against time_s / dt
  double dt = 0;
  long last = -1;
  for (int k = 0; k < 4;) {
    const auto s = client.next_state(run, 600s, last);
    if (!s) break;
    last = static_cast<long>(s->frame);
    const double since = std::chrono::duration<double>(Clock::now() - t0).count();
    if (dt == 0 && s->time_s > 0) dt = s->time_s / std::max(1.0, static_cast<double>(s->frame));
    const double step = dt > 0 ? s->time_s / dt : 0;
    while (k < 4 && step > marks[k]) at[static_cast<size_t>(k++)] = since;
  }
  client.send(run, "shutdown", "{}");
  service.wait(60);
  return at;
}

// With `against` (another fiberfem binary, e.g. an older build): each case run with both,
// alternated, the rows labelled by binary.
void first_frames_table(const std::vector<std::string>& scenes, int repeat, const std::string& against) {
  std::vector<std::pair<std::string, std::string>> binaries = {{"this", FIBERFEM_BIN}};
  if (!against.empty()) binaries.insert(binaries.begin(), {"against", against});
  std::printf("| scene | binary | first factorisation | first state s | first step s | step 10 s | step 60 s |\n|---|---|---|---|---|---|---|\n");
  for (const std::string& scene : scenes) {
    const size_t cases = 2 * binaries.size();
    std::vector<std::array<std::vector<double>, 4>> by(cases);
    for (int r = 0; r < repeat; ++r)
      for (size_t c = 0; c < cases; ++c) {
        const size_t k = (static_cast<size_t>(r) + c) % cases;  // alternated
        const auto at = first_frames(scene, k % 2 ? "beside" : "wait", binaries[k / 2].second);
        for (size_t m = 0; m < 4; ++m) by[k][m].push_back(at[m]);
      }
    for (size_t k = 0; k < cases; ++k)
      std::printf("| %s | %s | %s | %.2f | %.2f | %.2f | %.2f |\n", std::filesystem::path(scene).filename().c_str(),
                  binaries[k / 2].first.c_str(), k % 2 ? "beside" : "wait", percentile(by[k][0], 0.5), percentile(by[k][1], 0.5),
                  percentile(by[k][2], 0.5), percentile(by[k][3], 0.5));
    std::fflush(stdout);
  }
}

// `scene`: serve's scene arguments (default: the built-in heart).
LatencyResult latency(int n, const std::string& label = "", const std::vector<std::string>& scene = {}) {
  const std::string run = "bench-latency-" + std::to_string(getpid());
  std::vector<std::string> args = {FIBERFEM_BIN, "serve", "--run-id", run, "--status-hz", "1"};
  args.insert(args.end(), scene.begin(), scene.end());
  BackgroundProcess service(args, "/tmp/bench-latency.log", service_env());
  use_profile(profiles.client);
  Client client;
  client.resolve_run(run, 600s);
  client.next_state(run, 60s);
  std::vector<double> ms, ack_ms;
  for (int i = 0; i < n; ++i) {
    const double t_send = now_epoch_s();
    const auto ack = client.send(run, "set_gravity", i % 2 ? R"({"gravity": [0, 0, 0]})" : R"({"gravity": [0, 0, -0.1]})");
    ack_ms.push_back((now_epoch_s() - t_send) * 1e3);
    long after = static_cast<long>(ack.frame) - 1;
    for (;;) {
      const auto s = client.next_state(run, 10s, after);
      if (!s) break;
      if (s->parameter_version >= ack.parameter_version) {
        ms.push_back((s->source_time_s - t_send) * 1e3);
        break;
      }
      after = static_cast<long>(s->frame);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50 + (i * 37) % 60));  // not phase-locked to the step
  }
  std::printf("%scommand-to-effect latency, %s in real time (%zu commands): median %.2f ms, 99th percentile %.2f ms, max %.2f ms\n",
              label.c_str(), scene.empty() ? "default heart" : "the given scene", ms.size(), percentile(ms, 0.5), percentile(ms, 0.99), percentile(ms, 1.0));
  std::printf("%scommand round trip (send to acknowledgement): median %.2f ms, 99th percentile %.2f ms, max %.2f ms\n", label.c_str(),
              percentile(ack_ms, 0.5), percentile(ack_ms, 0.99), percentile(ack_ms, 1.0));
  std::fflush(stdout);
  client.send(run, "shutdown", "{}");
  service.wait(30);
  return {percentile(ms, 0.5), percentile(ms, 0.99), percentile(ack_ms, 0.5), percentile(ack_ms, 0.99)};
}

// ddsperf (Cyclone's own tool, Debian's cyclonedds-tools) with the same payload, in the
// same run: the median of its per-second receive rates.
void ddsperf(int nodes, double seconds) {
  const std::string dur = std::to_string(static_cast<int>(seconds) + 1);
  BackgroundProcess sub({"/usr/bin/ddsperf", "-D", std::to_string(static_cast<int>(seconds) + 3), "sub"}, "/tmp/bench-ddsperf-sub.log");
  std::this_thread::sleep_for(500ms);
  BackgroundProcess pub({"/usr/bin/ddsperf", "-D", dur, "pub", "size", std::to_string(12 * nodes)}, "/tmp/bench-ddsperf-pub.log");
  pub.wait(seconds + 30);
  sub.wait(10);
  std::vector<double> ks, mbs;
  std::istringstream in(sub.output());
  for (std::string line; std::getline(in, line);) {
    const size_t r = line.find(" rate ");
    if (r == std::string::npos) continue;
    double k = 0, mb = 0;
    if (std::sscanf(line.c_str() + r, " rate %lf kS/s %lf Mb/s", &k, &mb) == 2 && k > 0) ks.push_back(k * 1e3), mbs.push_back(mb / 8);
  }
  if (ks.size() > 2) ks.erase(ks.begin()), ks.pop_back(), mbs.erase(mbs.begin()), mbs.pop_back();  // partial first and last seconds
  std::printf("| ddsperf pub/sub, reliable, size %d B | %d | %.1f | %.1f |\n", 12 * nodes, nodes, percentile(ks, 0.5), percentile(mbs, 0.5));
}

// States/s received (the child's figure, through a pipe).
double throughput(int nodes, double seconds, const std::string& label = "fiberfem MeshState, reliable keep-last-1") {
  std::fflush(stdout);
  int fds[2];
  if (pipe(fds) != 0) return 0;
  const pid_t child = fork();
  if (child == 0) {  // subscriber
    close(fds[0]);
    use_profile(profiles.subscriber);
    fiberfem::dds::Participant pp;
    fiberfem::dds::Reader<fiberfem_MeshState> reader(pp);
    long count = 0;
    double bytes = 0;
    Clock::time_point t0{};
    while (count == 0 || std::chrono::duration<double>(Clock::now() - t0).count() < seconds) {
      reader.wait(2s);
      reader.take([&](const fiberfem_MeshState& s, const dds_sample_info_t&) {
        if (count++ == 0) t0 = Clock::now();
        bytes += 4.0 * s.positions._length;
      });
    }
    const double wall = std::chrono::duration<double>(Clock::now() - t0).count();
    const double rate = static_cast<double>(count - 1) / wall;
    std::printf("| %s | %d | %.1f | %.1f |\n", label.c_str(), nodes, rate, bytes / wall / 1e6);
    std::fflush(stdout);
    (void)!write(fds[1], &rate, sizeof rate);
    _exit(0);
  }
  close(fds[1]);
  use_profile(profiles.publisher);
  double rate = 0;
  {  // the participant goes before the next case, so that case reads its own profile
    fiberfem::dds::Participant pp;
    fiberfem::dds::Writer<fiberfem_MeshState> writer(pp);
    while (writer.matched() == 0) std::this_thread::sleep_for(10ms);
    std::vector<float> pos(3 * static_cast<size_t>(nodes), 0.5f), act;
    std::string run = "throughput";
    fiberfem_MeshState s{};
    s.run_id = run.data();
    s.positions = fiberfem::dds::borrow<dds_sequence_float>(pos);
    s.activation = fiberfem::dds::borrow<dds_sequence_float>(act);
    int status = 0;
    while (waitpid(child, &status, WNOHANG) == 0) {
      ++s.frame;
      writer.write(s);
    }
  }
  if (read(fds[0], &rate, sizeof rate) != sizeof rate) rate = 0;
  close(fds[0]);
  return rate;
}

// Plain against secure in one run (docs/security.md): each case measured plain then
// secure (secure first in odd rounds, so a drift in the machine's load favours neither),
// `rounds` times; the medians over rounds and the median of the per-round ratios.
// `dir`: the output of scripts/make_security.sh (profiles service, operator, observer).
void security(const std::string& dir, double seconds, int commands, int nodes, int rounds) {
  const char* env = std::getenv("CYCLONEDDS_URI");
  const std::string plain = env ? env : "";
  const auto profile = [&](const char* who) { return "file://" + dir + "/profiles/" + who + ".xml"; };
  const Profiles none{plain, plain, plain, plain};
  const Profiles secure{profile("service"), profile("operator"), profile("service"), profile("observer")};
  std::printf("plain: %s\nsecure: %s/profiles/{service,operator,observer}.xml\n", plain.c_str(), dir.c_str());
  // States of the heart's size (its 2,061 nodes) and of --nodes.
  std::vector<int> sizes = {2061};
  if (nodes != 2061) sizes.push_back(nodes);
  std::vector<std::string> names = {"heart: steps/s while publishing every step", "heart: states received/s",
                                    "command round trip, median ms", "command round trip, p99 ms",
                                    "command to effect, median ms", "command to effect, p99 ms"};
  for (int n : sizes) names.push_back("state throughput, states/s of " + std::to_string(n) + " nodes");
  // figures[k][0 plain, 1 secure][round]
  std::vector<std::array<std::vector<double>, 2>> figures(names.size());
  for (int r = 0; r < rounds; ++r) {
    std::printf("\nround %d of %d\n", r + 1, rounds);
    std::printf("| scene | nodes | elements | steps/s while publishing every step | states received/s | median step ms | median publish ms | state MB |\n|---|---|---|---|---|---|---|---|\n");
    for (int o = 0; o < 2; ++o) {
      const int mode = (o + r) % 2;  // 0 plain, 1 secure
      profiles = mode ? secure : none;
      // One engine thread: the figure is about publishing, not the engine, and a fixed
      // count keeps the two modes comparable on a shared machine.
      const FramesResult f = frames(mode ? "heart-secure" : "heart-plain", {"--builtin", "heart", "--threads", "1"}, seconds);
      figures[0][mode].push_back(f.steps_per_s);
      figures[1][mode].push_back(f.received_per_s);
    }
    for (int o = 0; o < 2; ++o) {
      const int mode = (o + r) % 2;
      profiles = mode ? secure : none;
      // The cantilever (189 nodes, a step well under a millisecond) on one thread: the
      // latency of the bus and the service loop, not of a loaded engine.
      const LatencyResult l = latency(commands, mode ? "secure: " : "plain: ", {"--builtin", "cantilever", "--threads", "1"});
      figures[2][mode].push_back(l.ack_median_ms);
      figures[3][mode].push_back(l.ack_p99_ms);
      figures[4][mode].push_back(l.effect_median_ms);
      figures[5][mode].push_back(l.effect_p99_ms);
    }
    std::printf("| path | nodes | states/s | MB/s |\n|---|---|---|---|\n");
    for (size_t i = 0; i < sizes.size(); ++i)
      for (int o = 0; o < 2; ++o) {
        const int mode = (o + r) % 2;
        profiles = mode ? secure : none;
        figures[6 + i][mode].push_back(throughput(sizes[i], seconds, mode ? "MeshState, secure" : "MeshState, plain"));
      }
  }
  std::printf("\nmedians over %d rounds\n\n| figure | plain | secure | secure / plain (median of the rounds' ratios) |\n|---|---|---|---|\n",
              rounds);
  for (size_t k = 0; k < names.size(); ++k) {
    std::vector<double> ratios;
    for (int r = 0; r < rounds; ++r)
      if (figures[k][0][r] > 0) ratios.push_back(figures[k][1][r] / figures[k][0][r]);
    std::printf("| %s | %.2f | %.2f | %.2f |\n", names[k].c_str(), percentile(figures[k][0], 0.5), percentile(figures[k][1], 0.5),
                percentile(ratios, 0.5));
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Figures of the fiberfem service on DDS"};
  std::string what = "all";
  double seconds = 10;
  int commands = 200, nodes = 100000;
  std::string secure_dir;
  app.add_option("what", what, "frames | latency | throughput | all | security | first-frames")
      ->check(CLI::IsMember({"frames", "latency", "throughput", "all", "security", "first-frames"}));
  std::vector<std::string> scenes;
  app.add_option("--scene", scenes, "first-frames: a scene file (repeatable)")->check(CLI::ExistingFile);
  int repeat = 3;
  app.add_option("--repeat", repeat, "first-frames: runs of each case (medians reported)")->check(CLI::Range(1, 100));
  std::string against;
  app.add_option("--against", against, "first-frames: another fiberfem binary to run each case with too, alternated")
      ->check(CLI::ExistingFile);
  app.add_option("--secure-dir", secure_dir, "security: the output directory of scripts/make_security.sh")->check(CLI::ExistingDirectory);
  app.add_option("--seconds", seconds, "Measuring time per case, s");
  app.add_option("--commands", commands, "Commands for the latency");
  app.add_option("--nodes", nodes, "Nodes of a state for the throughput");
  int rounds = 3;
  app.add_option("--rounds", rounds, "security: rounds of plain and secure cases (medians reported)")->check(CLI::Range(1, 100));
  CLI11_PARSE(app, argc, argv);
  if (what == "security") {
    if (secure_dir.empty()) {
      std::fprintf(stderr, "bench_service security: --secure-dir DIR (made by scripts/make_security.sh DIR) is required\n");
      return 2;
    }
    security(std::filesystem::absolute(secure_dir).string(), seconds, commands, nodes, rounds);
    return 0;
  }
  if (what == "first-frames") {
    first_frames_table(scenes, repeat, against);
    return 0;
  }
  if (what == "frames" || what == "all") {
    std::printf("| scene | nodes | elements | steps/s while publishing every step | states received/s | median step ms | median publish ms | state MB |\n|---|---|---|---|---|---|---|---|\n");
    frames("heart", {"--builtin", "heart"}, seconds);
    frames("box-100k", {"--builtin", "cantilever", "--set", "mesh.cells=[60, 40, 40]", "--set", "mesh.size=[0.15, 0.1, 0.1]",
                        "--set", "loads.gravity=[0, 0, -1]"},
           seconds);
  }
  if (what == "latency" || what == "all") latency(commands);
  if (what == "throughput" || what == "all") {
    std::printf("| path | nodes | states/s | MB/s |\n|---|---|---|---|\n");
    throughput(nodes, seconds);
    ddsperf(nodes, seconds);
  }
  return 0;
}
