// Faults and load with real processes on loopback (docs/reliability.md): the service
// killed with SIGKILL and restarted again and again while clients follow it on their own;
// floods of commands from several client processes; a subscriber stalled with SIGSTOP.
// Timings are measured and printed; the asserts keep generous bands (a shared 2-core CI).

#include "clients/ctl/client.hpp"
#include "process_support.hpp"
#include "service/archive/archive.hpp"

#include <nlohmann/json.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <set>
#include <sstream>
#include <thread>

namespace fiberfem::testing {
namespace {

using namespace std::chrono_literals;
using clients::Client;
using Clock = std::chrono::steady_clock;

const std::string kBin = FIBERFEM_BIN;

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
}

// What a follower (ctl echo --follow, python -m fiberfem_client watch) printed.
struct FollowLog {
  int found = 0, lost = 0;
  std::vector<int> frames_after_found;  // frame lines after each "following" line
  std::vector<std::string> lost_reasons;
};

FollowLog parse_follow(const std::string& text) {
  FollowLog f;
  for (const std::string& l : lines_of(text)) {
    if (l.rfind("following run ", 0) == 0) ++f.found, f.frames_after_found.push_back(0);
    else if (l.rfind("lost run ", 0) == 0) ++f.lost, f.lost_reasons.push_back(l);
    else if (l.rfind("frame ", 0) == 0 && !f.frames_after_found.empty()) ++f.frames_after_found.back();
  }
  return f;
}

class Faults : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { setenv("CYCLONEDDS_URI", FIBERFEM_DDS_URI, 1); }
  static std::string unique(const std::string& name) { return name + "-" + std::to_string(getpid()); }
  std::unique_ptr<BackgroundProcess> serve(const std::string& run_id, const std::string& log, std::vector<std::string> extra) {
    std::vector<std::string> args = {kBin, "serve", "--run-id", run_id, "--threads", "1"};
    args.insert(args.end(), extra.begin(), extra.end());
    return std::make_unique<BackgroundProcess>(args, dir_.file(log));
  }
  // Waits up to `timeout_s` for `pred()`; true when it held.
  template <class P>
  static bool wait_until(P pred, double timeout_s) {
    const auto end = Clock::now() + std::chrono::duration<double>(timeout_s);
    while (Clock::now() < end) {
      if (pred()) return true;
      std::this_thread::sleep_for(50ms);
    }
    return pred();
  }
  // Steps per second of `run` from `n` status samples.
  static std::vector<double> rates(Client& c, const std::string& run, int n) {
    std::vector<double> r;
    for (int i = 0; i < n; ++i)
      if (const auto s = c.status(run, 5s)) r.push_back(s->frames_per_second);
    return r;
  }
  TempDir dir_;
};

// Kill -9 the service mid-run, restart it (recover the archive, resume from its last
// checkpoint under the same run id, record into a new archive), three times. Each archive
// opens and holds every frame up to at most one flush interval before the kill; the
// C++ and Python followers, never restarted, notice each loss and follow the new service.
TEST_F(Faults, KillNineRestartLoopLosesAtMostAFlushIntervalAndClientsFollow) {
  constexpr int kKills = 3, kFlush = 10;
  const std::string run = unique("killed");
  const std::string python = std::string(FIBERFEM_SOURCE_DIR) + "/.venv/bin/python";
  BackgroundProcess ctl({kBin, "ctl", "--run", run, "--timeout", "60", "echo", "--follow"}, dir_.file("ctl.log"));
  BackgroundProcess py({python, "-m", "fiberfem_client", "watch", "--run", run, "--timeout", "60"}, dir_.file("py.log"),
                       {"PYTHONPATH=" + std::string(FIBERFEM_SOURCE_DIR) + "/clients/python"});
  Client client("kill-test");
  std::vector<long> lost_frames;
  std::vector<double> notice_s;
  std::unique_ptr<BackgroundProcess> service;
  for (int k = 0; k <= kKills; ++k) {
    const std::string archive = dir_.file("run-" + std::to_string(k) + ".h5");
    std::vector<std::string> args = {"--builtin", "cantilever", "--status-hz", "4", "--archive", archive, "--flush-frames",
                                     std::to_string(kFlush), "--flush-seconds", "0"};
    if (k > 0) args.insert(args.end(), {"--resume", dir_.file("run-" + std::to_string(k - 1) + ".h5")});
    service = serve(run, "serve-" + std::to_string(k) + ".log", args);
    // Both followers find the new service and show its frames.
    ASSERT_TRUE(wait_until(
        [&] {
          const FollowLog c = parse_follow(ctl.output()), p = parse_follow(py.output());
          return c.found == k + 1 && c.frames_after_found.back() >= 5 && p.found == k + 1 && p.frames_after_found.back() >= 5;
        },
        30))
        << "incarnation " << k << "\nctl:\n" << ctl.output() << "\npython:\n" << py.output() << "\nservice:\n" << service->output();
    if (k == kKills) break;

    // Past the checkpoint a second into the incarnation (the next one resumes from it),
    // kill right after a published frame: it was recorded before it was published.
    auto s = client.next_state(run, 5s);
    ASSERT_TRUE(s);
    const double t_begin = s->time_s;
    while (s && s->time_s < t_begin + 1.2) s = client.next_state(run, 5s, static_cast<long>(s->frame));
    ASSERT_TRUE(s);
    service->signal(SIGKILL);
    const auto t_kill = Clock::now();
    ASSERT_EQ(service->wait(10), 128 + SIGKILL);
    ASSERT_TRUE(wait_until([&] { return parse_follow(ctl.output()).lost == k + 1 && parse_follow(py.output()).lost == k + 1; }, 15))
        << "the followers did not notice the kill\nctl:\n" << ctl.output() << "\npython:\n" << py.output();
    notice_s.push_back(std::chrono::duration<double>(Clock::now() - t_kill).count());

    // The archive opens (as a SWMR reader: it was never closed), its frames consecutive,
    // and at most one flush interval short of the frame published before the kill.
    {
      const archive::ArchiveReader r(archive, /*follow=*/true);
      ASSERT_GE(r.frames(), 1);
      const std::vector<long> steps = r.steps();
      for (size_t i = 1; i < steps.size(); ++i) ASSERT_EQ(steps[i], steps[i - 1] + 1) << archive;
      EXPECT_GE(steps.back(), static_cast<long>(s->frame) - kFlush) << archive << ": last recorded step " << steps.back()
                                                                   << ", frame " << s->frame << " was published before the kill";
      EXPECT_TRUE(r.frame(r.frames() - 1).positions.allFinite());
      EXPECT_GE(r.checkpoints().size(), 1u);
      lost_frames.push_back(std::max(0L, static_cast<long>(s->frame) - steps.back()));
    }
    const ProcessResult rec = run_process({kBin, "archive", "recover", archive});
    ASSERT_EQ(rec.exit_code, 0) << rec.output;
  }
  // The last incarnation resumed where the previous one's last checkpoint was: its
  // archive starts there, not at step 0.
  {
    const archive::ArchiveReader first(dir_.file("run-1.h5"), /*follow=*/true);
    EXPECT_GT(first.steps().front(), 0);
  }
  try {
    // Steering the restarted run works (this client's first command since the restarts),
    // then it shuts down cleanly.
    ASSERT_TRUE(client.send(run, "set_gravity", R"({"gravity": [0, 0, -9.81]})").accepted);
    ASSERT_TRUE(client.send(run, "shutdown", "{}").accepted);
  } catch (const std::exception& e) {
    FAIL() << e.what() << "\nservice:\n" << service->output();
  }
  EXPECT_EQ(service->wait(20), 0) << service->output();
  ASSERT_TRUE(wait_until([&] { return parse_follow(ctl.output()).lost == kKills + 1; }, 10)) << ctl.output();
  for (const FollowLog& f : {parse_follow(ctl.output()), parse_follow(py.output())}) {
    EXPECT_EQ(f.found, kKills + 1);
    for (int n : f.frames_after_found) EXPECT_GE(n, 5);
    for (int i = 0; i < kKills; ++i) {  // noticed by silence or by the status liveliness lease
      const std::string& why = f.lost_reasons[static_cast<size_t>(i)];
      EXPECT_TRUE(why.find("no status for") != std::string::npos || why.find("liveliness lost") != std::string::npos ||
                  why.find("lease expired") != std::string::npos)
          << why;
    }
  }
  EXPECT_TRUE(ctl.running()) << "the follower must outlive the services";
  for (size_t i = 0; i < lost_frames.size(); ++i)
    std::printf("kill %zu: %ld frames lost (flush every %d), loss noticed by both followers after %.2f s\n", i + 1, lost_frames[i],
                kFlush, notice_s[i]);
}

// Four client processes flood the service with 600 commands each (8 in flight per client):
// every command gets exactly one acknowledgement and is applied exactly once (each accepted
// command increments the parameter version: the acks' versions are exactly v0+1 .. v0+N,
// and the archive logs each command id once); a repeated command id is answered again, not
// applied again; the step rate keeps within a generous band of the unloaded one.
// The live renderer is a follower too: `fiberfem render --live --run ID` draws on across a
// kill -9 and restart of the service under the same run id (the new service's topology
// checked against the mesh drawn), and every frame asked for is written.
TEST_F(Faults, LiveRendererFollowsARestartedService) {
  if (run_process({kBin, "render", "--help"}).exit_code != 0) GTEST_SKIP() << "fiberfem built without the renderer";
  const std::string run = unique("rendered");
  auto service = serve(run, "serve-a.log", {"--builtin", "cantilever", "--status-hz", "4"});
  constexpr int kFrames = 120;
  BackgroundProcess render({kBin, "render", "--live", "--run", run, "--frames", std::to_string(kFrames), "--width", "96", "--out",
                            dir_.file("frames")},
                           dir_.file("render.log"));
  ASSERT_TRUE(wait_until([&] { const FollowLog f = parse_follow(render.output()); return f.found == 1 && f.frames_after_found[0] >= 5; }, 30))
      << render.output();
  service->signal(SIGKILL);
  service->wait(10);
  service = serve(run, "serve-b.log", {"--builtin", "cantilever", "--status-hz", "4"});
  ASSERT_EQ(render.wait(90), 0) << render.output() << "\nservice:\n" << service->output();
  const FollowLog f = parse_follow(render.output());
  EXPECT_EQ(f.found, 2) << render.output();
  EXPECT_EQ(f.lost, 1) << render.output();
  ASSERT_EQ(f.frames_after_found.size(), 2u);
  EXPECT_GE(f.frames_after_found[1], 5) << "no frame drawn from the restarted service\n" << render.output();
  int pngs = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir_.file("frames"))) pngs += e.path().extension() == ".png";
  EXPECT_EQ(pngs, kFrames);
}

TEST_F(Faults, CommandFloodFromFourClientsAppliesEachCommandOnceAndKeepsTheFrameRate) {
  constexpr int kClients = 4, kEach = 600;
  const std::string run = unique("flood");
  const std::string archive = dir_.file("flood.h5");
  auto service = serve(run, "serve.log", {"--builtin", "cantilever", "--status-hz", "4", "--archive", archive});
  Client client("flood-test");
  ASSERT_EQ(client.resolve_run(run, 20s), run) << service->output();
  const clients::Ack first = client.send(run, "set_gravity", R"({"gravity": [0, 0, -9.81]})");
  ASSERT_TRUE(first.accepted);
  const unsigned v0 = first.parameter_version;
  const std::vector<double> before = rates(client, run, 8);

  std::vector<std::unique_ptr<BackgroundProcess>> floods;
  for (int i = 0; i < kClients; ++i)
    floods.push_back(std::make_unique<BackgroundProcess>(
        std::vector<std::string>{kBin, "ctl", "--run", run, "--timeout", "120", "flood", "set_gravity",
                                 R"({"gravity": [0, 0, -9.81]})", "--count", std::to_string(kEach), "--window", "8"},
        dir_.file("flood-" + std::to_string(i) + ".log")));
  std::vector<double> during;
  while (std::any_of(floods.begin(), floods.end(), [](auto& f) { return f->running(); }))
    if (const auto s = client.status(run, 5s)) during.push_back(s->frames_per_second);
  if (during.size() > 2) during.erase(during.begin());  // the period before the flood began

  std::set<unsigned> versions;
  int acked = 0;
  double total_rate = 0;
  for (auto& f : floods) {
    ASSERT_EQ(f->wait(1), 0) << f->output();
    const std::string out = f->output();
    const nlohmann::json j = nlohmann::json::parse(out.substr(out.find('{')));
    EXPECT_EQ(j["sent"], kEach);
    EXPECT_EQ(j["acked"], kEach);
    EXPECT_EQ(j["accepted"], kEach);
    // A command not answered within a second is written again under its id: a second answer
    // to it may come, never a second application (the versions below).
    EXPECT_LE(j["duplicate_acks"].get<int>(), j["resent"].get<int>());
    acked += j["acked"].get<int>();
    total_rate += j["commands_per_s"].get<double>();
    for (unsigned v : j["versions"].get<std::vector<unsigned>>()) EXPECT_TRUE(versions.insert(v).second) << "version " << v << " twice";
  }
  ASSERT_EQ(acked, kClients * kEach);
  ASSERT_EQ(versions.size(), static_cast<size_t>(kClients * kEach));
  EXPECT_EQ(*versions.begin(), v0 + 1);
  EXPECT_EQ(*versions.rbegin(), v0 + kClients * kEach);

  // A command written twice under one id (a client's resend): one application, two answers.
  {
    dds::Participant pp;
    dds::Writer<fiberfem_Command> w(pp);
    dds::Reader<fiberfem_CommandAck> acks(pp);
    ASSERT_TRUE(wait_until([&] { return w.matched() > 0 && acks.matched() > 0; }, 10));
    std::this_thread::sleep_for(1500ms);  // the service's command reader among those matched
    std::string rid = run, id = "resend-" + std::to_string(getpid()), cid = "resend", kind = "set_gravity",
                args = R"({"gravity": [0, 0, -9.8]})";
    fiberfem_Command c{};
    c.run_id = rid.data(), c.command_id = id.data(), c.client_id = cid.data(), c.kind = kind.data(), c.args = args.data();
    w.write(c);
    w.write(c);
    std::vector<unsigned> answered;
    wait_until(
        [&] {
          acks.take([&](const fiberfem_CommandAck& a, const dds_sample_info_t&) {
            if (dds::str(a.run_id) == run && dds::str(a.command_id) == id) answered.push_back(a.parameter_version);
          });
          return answered.size() >= 2;
        },
        10);
    ASSERT_EQ(answered.size(), 2u);
    EXPECT_EQ(answered[0], v0 + kClients * kEach + 1);
    EXPECT_EQ(answered[1], answered[0]) << "the repeated command was applied again";
    const clients::Ack next = client.send(run, "set_gravity", R"({"gravity": [0, 0, -9.81]})");
    EXPECT_EQ(next.parameter_version, answered[0] + 1);
  }
  service->signal(SIGTERM);
  ASSERT_EQ(service->wait(20), 0) << service->output();
  EXPECT_NE(service->output().find("1 repeated commands answered again"), std::string::npos) << service->output();

  // The archive logs every command once: the first, the flood, the resent one, the last.
  const archive::ArchiveReader r(archive);
  std::set<std::string> ids;
  for (const auto& c : r.commands()) EXPECT_TRUE(ids.insert(c.id).second) << "command " << c.id << " logged twice";
  EXPECT_EQ(ids.size(), static_cast<size_t>(kClients * kEach + 3));

  const double unloaded = median(before), flooded = median(during);
  std::printf("flood: %d commands from %d clients at %.0f commands/s in all; steps/s unloaded %.1f, during the flood %.1f (%zu samples)\n",
              kClients * kEach, kClients, total_rate, unloaded, flooded, during.size());
  ASSERT_FALSE(during.empty());
  EXPECT_GE(flooded, 0.5 * unloaded) << "the flood starved the steps";
}

// A subscriber stopped with SIGSTOP (it neither takes samples nor acknowledges them at the
// protocol level) does not slow the service: states are keep-last 1, so the writer replaces
// an unacknowledged frame instead of waiting. Checked on the time a state write takes (the
// status's publish time: a writer waiting for the stalled reader would show it there) and,
// loosely, on the step rate (on a shared machine it moves by a factor of two on its own).
TEST_F(Faults, StalledSubscriberDoesNotSlowTheService) {
  const std::string run = unique("stalled");
  auto service = serve(run, "serve.log", {"--builtin", "heart", "--fast", "--publish-hz", "60", "--status-hz", "4"});
  Client client("stall-test");
  ASSERT_EQ(client.resolve_run(run, 20s), run) << service->output();
  auto sample = [&](int n, std::vector<double>& rate, std::vector<double>& publish_ms) {
    for (int i = 0; i < n; ++i)
      if (const auto s = client.status(run, 5s)) rate.push_back(s->frames_per_second), publish_ms.push_back(s->publish_ms);
  };
  std::vector<double> rate_alone, pub_alone, rate_stalled, pub_stalled;
  sample(2, rate_alone, pub_alone);  // start-up
  rate_alone.clear(), pub_alone.clear();
  sample(10, rate_alone, pub_alone);

  BackgroundProcess echo({kBin, "ctl", "--run", run, "echo"}, dir_.file("echo.log"));
  ASSERT_TRUE(wait_until([&] { return echo.output().find("frame ") != std::string::npos; }, 20)) << echo.output();
  echo.signal(SIGSTOP);
  const auto before = client.status(run, 5s);
  sample(14, rate_stalled, pub_stalled);  // about 3.5 s: within the stalled participant's lease
  const auto after = client.status(run, 5s);
  echo.signal(SIGCONT);
  ASSERT_TRUE(before && after);
  EXPECT_GT(after->frame, before->frame + 20) << "the service stopped stepping";
  EXPECT_EQ(after->failed_steps, 0u);
  EXPECT_EQ(after->state, "running");
  ASSERT_TRUE(client.send(run, "shutdown", "{}").accepted);
  EXPECT_EQ(service->wait(20), 0) << service->output();
  std::printf("stalled subscriber: steps/s alone %.1f, with a stopped subscriber %.1f; state write %.3f ms alone, %.3f ms stalled (medians)\n",
              median(rate_alone), median(rate_stalled), median(pub_alone), median(pub_stalled));
  EXPECT_LT(median(pub_stalled), 20.0) << "state writes wait for the stalled subscriber";
  EXPECT_GE(median(rate_stalled), 0.25 * median(rate_alone));
}

// --command-budget out of its range is refused with the option named, before DDS starts.
TEST_F(Faults, CommandBudgetOutOfRangeIsRefused) {
  for (const char* bad : {"0", "-1", "20000", "abc"}) {
    const ProcessResult r = run_process({kBin, "serve", "--builtin", "cantilever", "--command-budget", bad, "--until", "0.01"});
    EXPECT_NE(r.exit_code, 0) << bad;
    EXPECT_NE(r.output.find("--command-budget"), std::string::npos) << bad << ": " << r.output;
  }
}

}  // namespace
}  // namespace fiberfem::testing
