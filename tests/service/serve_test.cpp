// The service on DDS with real processes on loopback (configs/dds/loopback.xml): the real
// `fiberfem serve`, the C++ client library in the test process, the real `fiberfem ctl`
// and the third-party `cyclonedds` command-line tool from PyPI.

#include "clients/ctl/client.hpp"
#include "io/scene.hpp"
#include "process_support.hpp"

#include <nlohmann/json.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include <unistd.h>

namespace fiberfem::testing {
namespace {

using namespace std::chrono_literals;
using clients::Client;

class Serve : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { setenv("CYCLONEDDS_URI", FIBERFEM_DDS_URI, 1); }

  // Starts `fiberfem serve` with a run id unique to this test process.
  std::unique_ptr<BackgroundProcess> start(const std::string& run_id, std::vector<std::string> extra) {
    std::vector<std::string> args = {FIBERFEM_BIN, "serve", "--run-id", run_id};
    args.insert(args.end(), extra.begin(), extra.end());
    return std::make_unique<BackgroundProcess>(args, dir_.file(run_id + ".log"));
  }
  static std::string unique(const std::string& name) { return name + "-" + std::to_string(getpid()); }

  TempDir dir_;
};

TEST_F(Serve, ClientSendsCommandsGetsAcksAndStatesAndALateJoinerGetsTheTopology) {
  const std::string run = unique("cantilever");
  auto service = start(run, {"--builtin", "cantilever", "--status-hz", "10"});
  Client client("test-client");
  ASSERT_EQ(client.resolve_run(run, 20s), run) << service->output();

  // States advance while running.
  const auto s1 = client.next_state(run, 10s);
  ASSERT_TRUE(s1);
  const auto s2 = client.next_state(run, 10s, static_cast<long>(s1->frame));
  ASSERT_TRUE(s2);
  EXPECT_GT(s2->frame, s1->frame);
  EXPECT_GT(s2->time_s, s1->time_s);

  // Pause: acknowledged, and the frame stops.
  const clients::Ack paused = client.send(run, "pause", "{}");
  ASSERT_TRUE(paused.accepted) << paused.reason;
  std::this_thread::sleep_for(300ms);
  const auto p1 = client.next_state(run, 5s);
  ASSERT_TRUE(p1);
  std::this_thread::sleep_for(1500ms);  // a paused service still publishes (deadline 2 s)
  const auto p2 = client.next_state(run, 5s);
  ASSERT_TRUE(p2);
  EXPECT_EQ(p2->frame, p1->frame);
  EXPECT_EQ(p2->frame, paused.frame);

  // Step 5: exactly five frames on.
  const clients::Ack stepped = client.send(run, "step", R"({"count": 5})");
  ASSERT_TRUE(stepped.accepted);
  std::optional<clients::State> s;
  for (int i = 0; i < 20 && (!s || s->frame < paused.frame + 5); ++i) s = client.next_state(run, 5s, s ? static_cast<long>(s->frame) : -1);
  ASSERT_TRUE(s);
  EXPECT_EQ(s->frame, paused.frame + 5);
  std::this_thread::sleep_for(500ms);
  const auto still = client.status(run, 5s);
  ASSERT_TRUE(still);
  EXPECT_EQ(still->frame, paused.frame + 5);
  EXPECT_EQ(still->state, "paused");

  // A rejected command: a reason, and the parameter version does not move.
  const clients::Ack bad = client.send(run, "set_gravity", R"({"gravity": [0, 0, .nan]})");
  EXPECT_FALSE(bad.accepted);
  EXPECT_NE(bad.reason.find("gravity[2]"), std::string::npos) << bad.reason;
  EXPECT_EQ(bad.parameter_version, stepped.parameter_version);
  const clients::Ack unknown = client.send(run, "teleport", "{}");
  EXPECT_FALSE(unknown.accepted);
  EXPECT_NE(unknown.reason.find("unknown command"), std::string::npos);

  // A client that joins late gets the topology (transient-local), equal to the scene's mesh.
  Client late("late-joiner");
  const auto topo = late.topology(run, 10s);
  ASSERT_TRUE(topo);
  const io::Scene scene = io::load_scene(std::string(FIBERFEM_SOURCE_DIR) + "/configs/scenes/demo-cantilever.yaml");
  const core::TetMesh& mesh = scene.model.mesh;
  ASSERT_EQ(topo->num_nodes, static_cast<unsigned>(mesh.num_nodes()));
  ASSERT_EQ(topo->num_elements, static_cast<unsigned>(mesh.num_elements()));
  ASSERT_EQ(topo->tets.size(), 4 * mesh.tets().size());
  EXPECT_EQ(topo->triangles.size(), 3 * mesh.boundary_triangles().size());
  for (int n = 0; n < mesh.num_nodes(); ++n)
    for (int d = 0; d < 3; ++d) ASSERT_FLOAT_EQ(topo->rest_positions[3 * n + d], static_cast<float>(mesh.rest_positions()(d, n)));
  EXPECT_EQ(topo->region_names, std::vector<std::string>{"tissue"});
  EXPECT_EQ(topo->fixed_nodes.size(), mesh.node_set("xmin").size());

  // Resume, then shut down by command: a clean exit.
  ASSERT_TRUE(client.send(run, "resume", "{}").accepted);
  const auto r = client.next_state(run, 5s, static_cast<long>(s->frame));
  ASSERT_TRUE(r);
  EXPECT_GT(r->frame, s->frame);
  ASSERT_TRUE(client.send(run, "shutdown", "{}").accepted);
  EXPECT_EQ(service->wait(20), 0) << service->output();
  EXPECT_NE(service->output().find("shut down by command"), std::string::npos);
}

// The heart rate measured from the published activation matches the commanded one.
TEST_F(Serve, CommandedHeartRateIsTheRateOfThePublishedActivation) {
  const std::string run = unique("beat");
  auto service = start(run, {"--builtin", "cantilever", "--publish-hz", "60", "--set", "loads.gravity=[0, 0, 0]", "--set",
                             "contraction={peak_tension: 300, heart_rate: 60, twitch: {shape: sine, systole: 0.15}}"});
  Client client;
  ASSERT_EQ(client.resolve_run(run, 20s), run) << service->output();
  const clients::Ack ack = client.send(run, "set_contraction", R"({"heart_rate": 150})");
  ASSERT_TRUE(ack.accepted) << ack.reason;
  // Onsets of beats (activation rising from zero) in the states after the change.
  std::vector<double> onsets;
  double last_act = 1, last_t = 0;
  long last = static_cast<long>(ack.frame) + 1;
  const auto t_end = std::chrono::steady_clock::now() + 30s;
  while (onsets.size() < 6 && std::chrono::steady_clock::now() < t_end) {
    const auto st = client.next_state(run, 5s, last);
    ASSERT_TRUE(st);
    last = static_cast<long>(st->frame);
    ASSERT_EQ(st->activation.size(), 40u * 4 * 6 / 2);  // one per element (20 x 2 x 2 cells, 6 tets each)
    const double a = st->activation[0];
    if (last_act == 0.0 && a > 0.0) onsets.push_back(0.5 * (st->time_s + last_t));  // between the two samples
    last_act = a, last_t = st->time_s;
  }
  ASSERT_GE(onsets.size(), 3u) << service->output();
  // A client on a loaded machine may miss the states of a whole beat's quiet phase (the
  // state topic keeps the newest only): an interval between onsets is then a whole number
  // of periods. Each interval over its number of periods; their median.
  std::vector<double> d;
  for (size_t i = 1; i < onsets.size(); ++i) d.push_back(onsets[i] - onsets[i - 1]);
  const double shortest = *std::min_element(d.begin(), d.end());
  std::vector<double> periods;
  for (double di : d) periods.push_back(di / std::max(1.0, std::round(di / shortest)));
  std::nth_element(periods.begin(), periods.begin() + static_cast<std::ptrdiff_t>(periods.size() / 2), periods.end());
  const double period = periods[periods.size() / 2];
  EXPECT_NEAR(60.0 / period, 150.0, 150.0 * 0.05) << "onsets " << ::testing::PrintToString(onsets);
}

TEST_F(Serve, TwoServicesSideBySideEachClientSteersOnlyItsOwnRun) {
  const std::string a = unique("left"), b = unique("right");
  auto sa = start(a, {"--builtin", "cantilever", "--status-hz", "10"});
  auto sb = start(b, {"--builtin", "cantilever", "--status-hz", "10"});
  Client client;
  ASSERT_EQ(client.resolve_run(a, 20s), a) << sa->output();
  ASSERT_EQ(client.resolve_run(b, 20s), b) << sb->output();
  // Without --run the client refuses to guess between two runs.
  EXPECT_THROW(client.resolve_run("", 3s), std::runtime_error);
  ASSERT_TRUE(client.send(a, "pause", "{}").accepted);
  std::this_thread::sleep_for(500ms);
  const auto a1 = client.status(a, 5s), b1 = client.status(b, 5s);
  std::this_thread::sleep_for(1000ms);
  const auto a2 = client.status(a, 5s), b2 = client.status(b, 5s);
  ASSERT_TRUE(a1 && a2 && b1 && b2);
  EXPECT_EQ(a2->state, "paused");
  EXPECT_EQ(a2->frame, a1->frame);
  EXPECT_EQ(b2->state, "running");
  EXPECT_GT(b2->frame, b1->frame);
  EXPECT_EQ(b2->parameter_version, 0u);  // b never saw a's command
}

TEST_F(Serve, KillingAClientNeverDisturbsTheService) {
  const std::string run = unique("sturdy");
  auto service = start(run, {"--builtin", "cantilever"});
  Client client;
  ASSERT_EQ(client.resolve_run(run, 20s), run) << service->output();
  for (int round = 0; round < 2; ++round) {
    BackgroundProcess echo({FIBERFEM_BIN, "ctl", "--run", run, "echo"}, dir_.file("echo.log"));
    for (int i = 0; i < 100 && echo.output().find("frame") == std::string::npos; ++i) std::this_thread::sleep_for(100ms);
    ASSERT_NE(echo.output().find("frame"), std::string::npos) << echo.output();
    echo.signal(SIGKILL);
    EXPECT_EQ(echo.wait(5), 128 + SIGKILL);
  }
  const auto s1 = client.next_state(run, 5s);
  ASSERT_TRUE(s1);
  const auto s2 = client.next_state(run, 5s, static_cast<long>(s1->frame));
  ASSERT_TRUE(s2);
  EXPECT_GT(s2->frame, s1->frame);
  EXPECT_TRUE(client.send(run, "set_time_step", R"({"dt": 0.01})").accepted);
  EXPECT_TRUE(service->running());
}

// The real `fiberfem ctl`: exit codes follow the acknowledgement.
TEST_F(Serve, CtlExitsNonZeroOnRejection) {
  const std::string run = unique("ctl");
  auto service = start(run, {"--builtin", "cantilever"});
  Client client;
  ASSERT_EQ(client.resolve_run(run, 20s), run) << service->output();
  const ProcessResult ok = run_process({FIBERFEM_BIN, "ctl", "--run", run, "send", "set_gravity", R"({"gravity": [0, 0, -1]})"});
  EXPECT_EQ(ok.exit_code, 0) << ok.output;
  EXPECT_NE(ok.output.find("accepted"), std::string::npos);
  const ProcessResult no = run_process({FIBERFEM_BIN, "ctl", "--run", run, "send", "set_time_step", R"({"dt": 99})"});
  EXPECT_EQ(no.exit_code, 3) << no.output;
  EXPECT_NE(no.output.find("rejected"), std::string::npos);
  const ProcessResult list = run_process({FIBERFEM_BIN, "ctl", "list"});
  EXPECT_EQ(list.exit_code, 0);
  EXPECT_NE(list.output.find(run), std::string::npos) << list.output;
  const ProcessResult gone = run_process({FIBERFEM_BIN, "ctl", "--run", "nobody", "--timeout", "1", "send", "pause"});
  EXPECT_EQ(gone.exit_code, 4);
  EXPECT_NE(gone.output.find("no run 'nobody'"), std::string::npos) << gone.output;
}

// A cycle script played by the real `fiberfem ctl play`: every action acknowledged, and
// its effects visible in what the service publishes.
TEST_F(Serve, CycleScriptPlaysAndItsEffectsShowInTheStates) {
  const std::string run = unique("cycle");
  auto service = start(run, {"--builtin", "cantilever", "--publish-hz", "60", "--set", "loads.gravity=[0, 0, 0]", "--set",
                             "contraction={peak_tension: 300, heart_rate: 60, twitch: {shape: sine, systole: 0.15}}"});
  write_file(dir_.file("script.yaml"), R"(
name: test-cycle
actions:
  - at: 0.1
    set_contraction: {heart_rate: 120}
  - from: 0.2
    to: 0.6
    ramp: {key: peak_tension, from: 300, to: 700}
    steps: 4
    command: set_contraction
  - at: 0.7
    apply_force: {name: lift, target: {node_set: xmax}, force: [0, 0, 0.01]}
)");
  Client client;
  ASSERT_EQ(client.resolve_run(run, 20s), run) << service->output();
  const ProcessResult play = run_process({FIBERFEM_BIN, "ctl", "--run", run, "play", dir_.file("script.yaml"), "--log", dir_.file("log.txt")});
  ASSERT_EQ(play.exit_code, 0) << play.output;
  const std::string log = read_file(dir_.file("log.txt"));
  size_t accepted = 0;
  for (size_t p = log.find("accepted"); p != std::string::npos; p = log.find("accepted", p + 1)) ++accepted;
  EXPECT_EQ(accepted, 1u + 5u + 1u) << log;
  // The status reports the end of the ramp and the new rate (once it carries all seven
  // accepted commands: status is published twice a second).
  auto st = client.status(run, 5s);
  for (int i = 0; i < 20 && st && st->parameter_version < 7; ++i) st = client.status(run, 5s);
  ASSERT_TRUE(st);
  EXPECT_EQ(st->parameter_version, 7u);
  EXPECT_DOUBLE_EQ(st->peak_tension_pa, 700.0);
  EXPECT_DOUBLE_EQ(st->heart_rate_bpm, 120.0);
  // The upward force lifts the free end (gravity is off): its z rises by a visible amount.
  const auto topo = client.topology(run, 5s);
  ASSERT_TRUE(topo);
  // One second of simulated time after the script (however slowly the machine runs it).
  auto s = client.next_state(run, 5s);
  ASSERT_TRUE(s);
  const double t_after = s->time_s + 1.0;
  for (int i = 0; i < 2000 && s && s->time_s < t_after; ++i) s = client.next_state(run, 5s, static_cast<long>(s->frame));
  ASSERT_TRUE(s);
  double lift = 0;
  for (size_t n = 0; n < topo->num_nodes; ++n)
    if (std::abs(topo->rest_positions[3 * n] - 0.1f) < 1e-6f) lift = std::max<double>(lift, s->positions[3 * n + 2] - topo->rest_positions[3 * n + 2]);
  EXPECT_GT(lift, 1e-3) << "free end z rise " << lift;
}

// The Python client (clients/python, installed into .venv) talks to the real service.
TEST_F(Serve, PythonClientSendsCommandsAndReceivesStatesAsArrays) {
  const std::string python = std::string(FIBERFEM_SOURCE_DIR) + "/.venv/bin/python";
  const std::string run = unique("python");
  auto service = start(run, {"--builtin", "cantilever"});
  Client client;
  ASSERT_EQ(client.resolve_run(run, 20s), run) << service->output();
  const ProcessResult py = run_process({"timeout", "60", python, std::string(FIBERFEM_SOURCE_DIR) + "/tests/service/python_client_check.py", run});
  ASSERT_EQ(py.exit_code, 0) << py.output;
  const nlohmann::json j = nlohmann::json::parse(py.output.substr(py.output.find('{')));
  const io::Scene scene = io::load_scene(std::string(FIBERFEM_SOURCE_DIR) + "/configs/scenes/demo-cantilever.yaml");
  EXPECT_EQ(j["nodes"], scene.model.mesh.num_nodes());
  EXPECT_EQ(j["elements"], scene.model.mesh.num_elements());
  EXPECT_NEAR(j["rest_sum"].get<double>(), scene.model.mesh.rest_positions().sum(), 1e-4);
  EXPECT_EQ(j["positions_shape"], nlohmann::json::array({scene.model.mesh.num_nodes(), 3}));
  EXPECT_TRUE(j["ok_accepted"].get<bool>());
  EXPECT_FALSE(j["bad_accepted"].get<bool>());
  EXPECT_NE(j["bad_reason"].get<std::string>().find("dt"), std::string::npos);
  EXPECT_EQ(j["version_after"], j["ok_version"]);
  // The C++ client sees the Python client's command in the run's status.
  auto st = client.status(run, 5s);
  for (int i = 0; i < 10 && st && st->parameter_version < 1; ++i) st = client.status(run, 5s);
  ASSERT_TRUE(st);
  EXPECT_EQ(st->parameter_version, 1u);
}

// A third-party tool (the `cyclonedds` CLI of the PyPI wheel, a different DDS build) sees
// the topics and decodes a state sample through XTypes. On a domain of its own (the
// loopback profile with a numbered domain): with other tests' Python clients on the shared
// domain the tool finds two type objects for MeshState (the Python binding's and the C
// one) and stops to ask which to use.
TEST_F(Serve, ThirdPartyCycloneddsToolListsTopicsAndReadsAState) {
  const std::string tool = std::string(FIBERFEM_SOURCE_DIR) + "/.venv/bin/cyclonedds";
  if (!std::filesystem::exists(tool)) GTEST_FAIL() << tool << " missing: run scripts/setup.sh";
  const int domain = 100 + static_cast<int>(getpid() % 120);  // ports 7400 + 250 d stay below 65536
  {
    std::ifstream in(std::string(FIBERFEM_DDS_URI).substr(std::string("file://").size()));
    std::stringstream text;
    text << in.rdbuf();
    std::string xml = text.str();
    const std::string any = "Domain Id=\"any\"";
    ASSERT_NE(xml.find(any), std::string::npos) << "the loopback profile changed";
    xml.replace(xml.find(any), any.size(), "Domain Id=\"" + std::to_string(domain) + "\"");
    std::ofstream(dir_.file("domain.xml")) << xml;
  }
  struct RestoreUri {
    ~RestoreUri() { setenv("CYCLONEDDS_URI", FIBERFEM_DDS_URI, 1); }
  } restore;
  setenv("CYCLONEDDS_URI", ("file://" + dir_.file("domain.xml")).c_str(), 1);
  const std::string id = std::to_string(domain);
  const std::string run = unique("thirdparty");
  auto service = start(run, {"--builtin", "cantilever"});
  Client client;
  ASSERT_EQ(client.resolve_run(run, 20s), run) << service->output();
  const ProcessResult ls = run_process({"timeout", "30", tool, "ls", "-i", id, "--suppress-progress-bar", "--color", "none"});
  for (const char* topic : {"fiberfem_mesh_topology", "fiberfem_mesh_state", "fiberfem_command", "fiberfem_command_ack", "fiberfem_status"})
    EXPECT_NE(ls.output.find(topic), std::string::npos) << topic << "\n" << ls.output;
  const ProcessResult sub = run_process({"timeout", "12", tool, "subscribe", "fiberfem_mesh_state", "-i", id,
                                         "--suppress-progress-bar", "--color", "none"});
  EXPECT_NE(sub.output.find("MeshState("), std::string::npos) << sub.output;
  EXPECT_NE(sub.output.find("run_id='" + run + "'"), std::string::npos) << sub.output.substr(0, 2000);
}

}  // namespace
}  // namespace fiberfem::testing
