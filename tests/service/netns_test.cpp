// Several hosts on one DDS domain (docs/reliability.md): network namespaces made by the
// test, joined by veth pairs to a bridge in a hub namespace, link-local addresses in
// 169.254.213.0/24 (never routed: the traffic stays inside the namespaces), a Cyclone
// profile per host with its interface and explicit peers (no multicast). The service runs
// on one host, clients on two others: discovery, steering, a replay watched across hosts,
// then one client host is cut off and brought back and its follower recovers on its own.
// Needs root and `ip netns`; skipped otherwise.

#include "process_support.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <thread>

namespace fiberfem::testing {
namespace {

using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

const std::string kBin = FIBERFEM_BIN;
// iproute2's `ip`, wherever the system puts it.
const std::string kIp = [] {
  for (const char* p : {"/usr/sbin/ip", "/sbin/ip", "/usr/bin/ip", "/bin/ip"})
    if (access(p, X_OK) == 0) return std::string(p);
  return std::string("/usr/sbin/ip");
}();

double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

int count_lines(const std::string& text, const std::string& prefix) {
  int n = 0;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) n += l.rfind(prefix, 0) == 0;
  return n;
}

template <class P>
bool wait_until(P pred, double timeout_s) {
  const auto end = Clock::now() + std::chrono::duration<double>(timeout_s);
  while (Clock::now() < end) {
    if (pred()) return true;
    std::this_thread::sleep_for(50ms);
  }
  return pred();
}

// The namespaces, links and bridge of one test run, named after its pid; all deleted when
// the object goes (deleting a namespace deletes the veth ends in it, and with them their
// peers).
class Hosts {
 public:
  static constexpr int kHosts = 3;  // 0: the service, 1 and 2: clients
  Hosts() : tag_(std::to_string(getpid() % 100000)) {}
  ~Hosts() {
    for (const std::string& ns : created_) run_process({kIp, "netns", "del", ns});
  }
  /// Builds the network; returns "" or what failed.
  std::string build() {
    if (const std::string e = cmd({kIp, "netns", "add", hub()}); !e.empty()) return e;
    created_.push_back(hub());
    for (const auto& c : std::vector<std::vector<std::string>>{
             {kIp, "-n", hub(), "link", "set", "lo", "up"},
             {kIp, "-n", hub(), "link", "add", "br0", "type", "bridge"},
             {kIp, "-n", hub(), "link", "set", "br0", "up"}})
      if (const std::string e = cmd(c); !e.empty()) return e;
    for (int h = 0; h < kHosts; ++h) {
      if (const std::string e = cmd({kIp, "netns", "add", ns(h)}); !e.empty()) return e;
      created_.push_back(ns(h));
      const std::string peer = "p" + std::to_string(h);
      for (const auto& c : std::vector<std::vector<std::string>>{
               {kIp, "-n", ns(h), "link", "set", "lo", "up"},
               {kIp, "-n", ns(h), "link", "add", dev(h), "type", "veth", "peer", "name", peer, "netns", hub()},
               {kIp, "-n", ns(h), "addr", "add", address(h) + "/24", "dev", dev(h)},
               {kIp, "-n", ns(h), "link", "set", dev(h), "up"},
               {kIp, "-n", hub(), "link", "set", peer, "master", "br0"},
               {kIp, "-n", hub(), "link", "set", peer, "up"}})
        if (const std::string e = cmd(c); !e.empty()) return e;
    }
    return "";
  }
  std::string ns(int h) const { return "fiberfem-" + tag_ + "-h" + std::to_string(h); }
  std::string hub() const { return "fiberfem-" + tag_ + "-hub"; }
  static std::string dev(int h) { return "eth" + std::to_string(h); }
  static std::string address(int h) { return "169.254.213." + std::to_string(h + 1); }
  /// The Cyclone profile of host h: its interface, the peers of every host, no multicast.
  static std::string profile(int h) {
    std::string peers;
    for (int p = 0; p < kHosts; ++p) peers += "<Peer address=\"" + address(p) + "\"/>";
    return "<CycloneDDS xmlns=\"https://cdds.io/config\"><Domain Id=\"any\"><General><Interfaces><NetworkInterface name=\"" +
           dev(h) + "\"/></Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery>" +
           "<ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>16</MaxAutoParticipantIndex><Peers>" + peers +
           "</Peers></Discovery></Domain></CycloneDDS>\n";
  }

 private:
  static std::string cmd(const std::vector<std::string>& args) {
    const ProcessResult r = run_process(args);
    if (r.exit_code == 0) return "";
    std::string line;
    for (const std::string& a : args) line += a + " ";
    return line + "failed: " + r.output;
  }
  std::string tag_;
  std::vector<std::string> created_;
};

TEST(SeveralHosts, DiscoverySteeringReplayAndACutOffClientRecovers) {
  if (geteuid() != 0) GTEST_SKIP() << "needs root to create network namespaces (ip netns)";
  if (access(kIp.c_str(), X_OK) != 0) GTEST_SKIP() << kIp << " not found (Debian package iproute2)";
  TempDir dir;
  Hosts hosts;  // declared before the processes: torn down after they are stopped
  if (const std::string e = hosts.build(); !e.empty()) GTEST_SKIP() << "cannot build network namespaces here: " << e;
  for (int h = 0; h < Hosts::kHosts; ++h) write_file(dir.file("host" + std::to_string(h) + ".xml"), Hosts::profile(h));
  // A command on host h (through `ip netns exec`, with that host's profile).
  auto on = [&](int h, std::vector<std::string> args) {
    std::vector<std::string> full = {kIp, "netns", "exec", hosts.ns(h), "env",
                                     "CYCLONEDDS_URI=file://" + dir.file("host" + std::to_string(h) + ".xml")};
    full.insert(full.end(), args.begin(), args.end());
    return full;
  };
  // A recorded run to replay later (no DDS).
  const std::string recorded = dir.file("recorded.h5");
  const ProcessResult rec = run_process({kBin, "run", std::string(FIBERFEM_SOURCE_DIR) + "/configs/scenes/demo-cantilever.yaml", "--steps",
                                         "120", "--archive", recorded});
  ASSERT_EQ(rec.exit_code, 0) << rec.output;

  const std::string run = "hosts-" + std::to_string(getpid()), replay_run = "hosts-replay-" + std::to_string(getpid());
  const auto t0 = Clock::now();
  BackgroundProcess service(on(0, {kBin, "serve", "--builtin", "cantilever", "--threads", "1", "--run-id", run, "--status-hz", "4"}),
                            dir.file("serve.log"));
  BackgroundProcess follower(on(1, {kBin, "ctl", "--run", run, "--timeout", "120", "echo", "--follow", "--lost-after", "3"}),
                             dir.file("follower.log"));

  // Discovery: host 1 follows the run of host 0.
  ASSERT_TRUE(wait_until([&] { return count_lines(follower.output(), "frame ") >= 3; }, 40))
      << "follower:\n" << follower.output() << "\nservice:\n" << service.output();
  const double discovery_s = since(t0);
  EXPECT_EQ(count_lines(follower.output(), "following run " + run), 1);

  // Steering from host 2: accepted, and host 1 sees its parameter version in the states.
  const ProcessResult sent = run_process(on(2, {kBin, "ctl", "--run", run, "--timeout", "30", "send", "set_gravity", R"({"gravity": [0, 0, -5]})"}));
  ASSERT_EQ(sent.exit_code, 0) << sent.output;
  unsigned version = 0;
  const size_t at = sent.output.find("parameter version ");
  ASSERT_NE(at, std::string::npos) << sent.output;
  version = static_cast<unsigned>(std::stoul(sent.output.substr(at + 18)));
  EXPECT_GE(version, 1u);
  EXPECT_TRUE(wait_until([&] { return follower.output().find(" v" + std::to_string(version) + ":") != std::string::npos; }, 15))
      << follower.output();

  // Replay on host 2, watched from host 1.
  BackgroundProcess replay(on(2, {kBin, "replay", recorded, "--run-id", replay_run, "--loop"}), dir.file("replay.log"));
  const ProcessResult watched = run_process(on(1, {kBin, "ctl", "--run", replay_run, "--timeout", "30", "echo", "--count", "5"}));
  EXPECT_EQ(watched.exit_code, 0) << watched.output << "\nreplay:\n" << replay.output();
  EXPECT_EQ(count_lines(watched.output, "frame "), 5) << watched.output;
  const ProcessResult topo = run_process(on(1, {kBin, "ctl", "--run", replay_run, "--timeout", "30", "topology"}));
  EXPECT_NE(topo.output.find("(replay)"), std::string::npos) << topo.output;
  replay.stop();

  // Cut host 1 off, then bring it back: its follower reports the run lost (no status within
  // the 3 s lease) and follows it again, without being restarted.
  ASSERT_EQ(run_process({kIp, "-n", hosts.ns(1), "link", "set", Hosts::dev(1), "down"}).exit_code, 0);
  const auto t_cut = Clock::now();
  ASSERT_TRUE(wait_until([&] { return count_lines(follower.output(), "lost run " + run) == 1; }, 20)) << follower.output();
  const double notice_s = since(t_cut);
  // Cut for 1 s past the notice (or FIBERFEM_NETNS_CUT_S in all, for measuring cuts past
  // the 10 s participant lease, after which discovery starts over; docs/reliability.md).
  const char* cut_env = std::getenv("FIBERFEM_NETNS_CUT_S");
  const double cut_s = cut_env ? std::atof(cut_env) : notice_s + 1.0;
  while (since(t_cut) < cut_s) std::this_thread::sleep_for(50ms);
  ASSERT_EQ(run_process({kIp, "-n", hosts.ns(1), "link", "set", Hosts::dev(1), "up"}).exit_code, 0);
  const auto t_up = Clock::now();
  const int frames_before = count_lines(follower.output(), "frame ");
  ASSERT_TRUE(wait_until(
      [&] { return count_lines(follower.output(), "following run " + run) == 2 && count_lines(follower.output(), "frame ") >= frames_before + 3; },
      40))
      << follower.output();
  const double recover_s = since(t_up);
  EXPECT_TRUE(follower.running());
  EXPECT_TRUE(service.running()) << service.output();
  std::printf("hosts: discovery %.1f s after the service started; loss noticed %.1f s after the cut; link down %.1f s; following again %.1f s "
              "after the link came back\n",
              discovery_s, notice_s, cut_s, recover_s);
  follower.stop();
  EXPECT_EQ(service.stop(), 0) << service.output();
}

// The follower's rule without a run id ("the only live run, then the only live run of the
// same scene"), on a host of its own: in a namespace with only its loopback no other
// service on the machine is on the domain. The service is killed and restarted without
// --run-id (a new default id); a paused heart runs beside it; the follower picks the
// restarted cantilever, not the heart.
TEST(SeveralHosts, FollowerWithoutARunIdFollowsTheRestartedServiceOfTheSameScene) {
  if (geteuid() != 0) GTEST_SKIP() << "needs root to create network namespaces (ip netns)";
  if (access(kIp.c_str(), X_OK) != 0) GTEST_SKIP() << kIp << " not found (Debian package iproute2)";
  TempDir dir;
  const std::string ns = "fiberfem-" + std::to_string(getpid() % 100000) + "-alone";
  if (run_process({kIp, "netns", "add", ns}).exit_code != 0) GTEST_SKIP() << "cannot create a network namespace here";
  struct Deleter {
    std::string ns;
    ~Deleter() { run_process({kIp, "netns", "del", ns}); }
  } deleter{ns};  // declared before the processes: deleted after they are stopped
  ASSERT_EQ(run_process({kIp, "-n", ns, "link", "set", "lo", "up"}).exit_code, 0);
  auto on = [&](std::vector<std::string> args) {
    std::vector<std::string> full = {kIp, "netns", "exec", ns, "env",
                                     "CYCLONEDDS_URI=file://" + std::string(FIBERFEM_SOURCE_DIR) + "/configs/dds/loopback.xml"};
    full.insert(full.end(), args.begin(), args.end());
    return full;
  };
  auto service = std::make_unique<BackgroundProcess>(on({kBin, "serve", "--builtin", "cantilever", "--threads", "1", "--status-hz", "4"}),
                                                     dir.file("serve-1.log"));
  BackgroundProcess follower(on({kBin, "ctl", "--timeout", "60", "echo", "--follow"}), dir.file("follower.log"));
  ASSERT_TRUE(wait_until([&] { return count_lines(follower.output(), "frame ") >= 3; }, 30)) << follower.output();
  const std::string first_pid = std::to_string(service->pid());
  EXPECT_NE(follower.output().find("following run demo-cantilever-"), std::string::npos) << follower.output();
  EXPECT_NE(follower.output().find("-" + first_pid + ":"), std::string::npos) << follower.output();

  service->signal(SIGKILL);
  service->wait(10);
  ASSERT_TRUE(wait_until([&] { return count_lines(follower.output(), "lost run ") == 1; }, 15)) << follower.output();
  BackgroundProcess heart(on({kBin, "serve", "--builtin", "heart", "--threads", "1", "--paused", "--status-hz", "4"}), dir.file("heart.log"));
  std::this_thread::sleep_for(1s);  // the heart is on the domain first
  service = std::make_unique<BackgroundProcess>(on({kBin, "serve", "--builtin", "cantilever", "--threads", "1", "--status-hz", "4"}),
                                                dir.file("serve-2.log"));
  const std::string second_pid = std::to_string(service->pid());
  ASSERT_TRUE(wait_until([&] { return count_lines(follower.output(), "following run ") == 2; }, 30)) << follower.output();
  const std::string out = follower.output();
  const std::string second = out.substr(out.rfind("following run "));
  EXPECT_EQ(second.rfind("following run demo-cantilever-", 0), 0u) << second;
  EXPECT_NE(second.find("-" + second_pid + ":"), std::string::npos) << "followed " << second << "; the new service is pid " << second_pid;
  EXPECT_TRUE(wait_until([&] { return count_lines(follower.output(), "frame ") >= count_lines(out, "frame ") + 3; }, 15));
  follower.stop();
}

}  // namespace
}  // namespace fiberfem::testing
