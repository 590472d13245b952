// Bad commands to a live service (docs/bad-input.md): the real `fiberfem serve` recording
// to an archive, the C++ client library and the real `fiberfem ctl play` on loopback DDS.
// Every bad command field is refused with an acknowledgement naming the field; the run
// keeps stepping; afterwards the recording opens, holds every frame up to the shutdown
// and every command the run saw (refused ones with their reasons), and `fiberfem archive
// info` reads it. With FIBERFEM_BAD_COMMAND_TABLE=FILE the observed acknowledgements are
// written there as a Markdown table (scripts/bad_input_table.sh).

#include "clients/ctl/client.hpp"
#include "process_support.hpp"
#include "service/archive/archive.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace fiberfem::testing {
namespace {

using namespace std::chrono_literals;

const char* kTiny = R"(name: tiny
mesh: {generator: box, size: [0.1, 0.02, 0.02], cells: [2, 1, 1]}
regions:
  - name: tissue
    select: all
    material: {E_L: 60.0e3, E_T: 20.0e3, nu_LT: 0.25, nu_T: 0.45, G_L: 8.0e3, density: 1000.0}
    damping: {mass: 40.0, stiffness: 0.0}
fibers: {uniform: [1, 0, 0]}
fixed:
  - plane: {axis: x, value: 0.0}
loads: {gravity: [0, 0, -9.81]}
contraction: {peak_tension: 1000, heart_rate: 60}
solver: {dt: 0.01}
)";

struct BadCommand {
  std::string field;  // what is bad, in words
  std::string kind, args;
  std::vector<std::string> expect;  // fragments of the reason
  bool recorded = true;  // refused by the run (recorded), not by the decoder before it
};

std::string node_list(int n) {
  std::string s = "[";
  for (int i = 0; i < n; ++i) s += (i ? ", " : "") + std::to_string(i);
  return s + "]";
}

std::vector<BadCommand> bad_commands() {
  return {
      {"force: NaN", "apply_force", R"({"target": {"node": 3}, "force": [0, 0, .nan]})", {"force[2]", "not finite"}},
      {"force: +inf", "apply_force", R"({"target": {"node": 3}, "force": [.inf, 0, 0]})", {"force[0]", "not finite"}},
      {"force: -inf magnitude", "apply_force", R"({"target": {"node": 3}, "magnitude": -.inf, "along": "fibers"})", {"magnitude", "not finite"}},
      {"force: a string", "apply_force", R"({"target": {"node": 3}, "force": "up"})", {"'force'", "three numbers"}},
      {"unknown node index", "apply_force", R"({"target": {"node": 100000}, "force": [0, 0, 1]})", {"target.node", "out of range [0, 11]"}},
      {"negative node index", "apply_force", R"({"target": {"node": -1}, "force": [0, 0, 1]})", {"target.node", "out of range"}},
      {"fractional node index", "apply_force", R"({"target": {"node": 2.5}, "force": [0, 0, 1]})", {"target.node", "whole number"}},
      {"node set as a list", "apply_force", R"({"target": {"node_set": [1]}, "force": [0, 0, 1]})", {"target.node_set", "string"}},
      {"huge node list (100000 indices)", "apply_force", R"({"target": {"nodes": )" + node_list(100000) + R"(}, "force": [0, 0, 1]})",
       {"target.nodes[12]", "out of range"}},
      {"repeated node", "apply_force", R"({"target": {"nodes": [1, 1]}, "force": [0, 0, 1]})", {"target.nodes[1]", "listed twice"}},
      {"missing target", "apply_force", R"({"force": [0, 0, 1]})", {"needs 'target'"}},
      {"dt out of range", "set_time_step", R"({"dt": 100})", {"'dt' = 100", "out of range"}},
      {"dt wrong type", "set_time_step", R"({"dt": "fast"})", {"'dt' must be a number"}},
      {"dt missing", "set_time_step", "{}", {"needs 'dt'"}},
      {"nu_T out of range", "set_material", R"({"nu_T": 1.5})", {"nu_T"}},
      {"unknown parameter name", "set_material", R"({"stiffness": 3})", {"unknown argument 'stiffness'"}},
      {"unknown region", "set_material", R"({"region": "bone", "E_L": 1e5})", {"no region 'bone'"}},
      {"heart rate negative", "set_contraction", R"({"heart_rate": -5})", {"heart_rate"}},
      {"gravity of two numbers", "set_gravity", R"({"gravity": [0, 0]})", {"'gravity'", "three numbers"}},
      {"step count huge", "step", R"({"count": 1e12})", {"'count'", "out of range"}},
      {"fibers: zero", "set_fibers", R"({"uniform": [0, 0, 0]})", {"fibers.uniform", "zero"}},
      {"fibers: file missing", "set_fibers", R"({"file": "/nonexistent/fibers.txt"})", {"fibers.file", "does not exist"}},
      {"solver method unknown", "set_solver", R"({"method": "magic"})", {"'method'"}},
      {"unknown command", "teleport", "{}", {"unknown command 'teleport'"}},
      {"arguments not an object", "pause", "[1, 2]", {"JSON object"}},
      {"arguments not JSON", "set_gravity", "{{{", {"not valid JSON"}},
      {"argument key a list", "set_gravity", R"({[1]: 2})", {"argument names"}},
      {"start_recording while recording", "start_recording", R"({"path": "/tmp/x.h5"})", {"already recording"}},
      {"kind with a space", "set material", "{}", {"command field 'kind'", "not a command name"}, false},
      {"kind empty", "", "{}", {"command field 'kind' is empty"}, false},
      {"args not UTF-8", "set_gravity", "{\"gravity\": \"\xff\xfe\"}", {"command field 'args'", "not valid UTF-8"}, false},
      {"args with a control character", "set_gravity", "{\"gravity\": \x01}", {"command field 'args'", "control character"}, false},
      {"args of 2 MiB", "set_gravity", "{\"gravity\": [0, 0, 1], \"pad\": \"" + std::string(2 << 20, 'x') + "\"}",
       {"command field 'args'", "the limit is 1048576"}, false},
  };
}

std::string cell(std::string s, size_t max = 90) {
  if (s.size() > max) s = s.substr(0, max - 10) + "... (" + std::to_string(s.size()) + " bytes)";
  std::string o;
  for (unsigned char c : s) {
    if (c == '|') o += "\\|";
    else if (c < 0x20 || c >= 0x7F) {
      char b[8];
      std::snprintf(b, sizeof b, "\\x%02x", c);
      o += b;
    } else o += static_cast<char>(c);
  }
  return o;
}

TEST(BadCommands, RefusedByTheLiveServiceWhichKeepsSteppingAndRecording) {
  setenv("CYCLONEDDS_URI", FIBERFEM_DDS_URI, 1);
  TempDir dir;
  write_file(dir.file("tiny.yaml"), kTiny);
  const std::string run = "bad-commands-" + std::to_string(getpid());
  const std::string h5 = dir.file("rec.h5");
  BackgroundProcess service({FIBERFEM_BIN, "serve", dir.file("tiny.yaml"), "--run-id", run, "--status-hz", "10", "--threads", "1",
                             "--archive", h5, "--flush-frames", "1"},
                            dir.file("serve.log"));
  clients::Client client("bad-command-test");
  ASSERT_EQ(client.resolve_run(run, 20s), run) << read_file(dir.file("serve.log"));
  const auto first = client.next_state(run, 10s);
  ASSERT_TRUE(first);

  std::ostringstream table;
  table << "| bad field | kind | args | accepted | reason (the acknowledgement) |\n|---|---|---|---|---|\n";
  // Whether the command was refused with a reason holding every expected word; one row of
  // the table either way.
  auto refused_naming = [&table](const clients::Ack& ack, const BadCommand& b) {
    EXPECT_FALSE(ack.accepted) << b.field << ": " << ack.reason;
    bool all = !ack.accepted;
    for (const std::string& e : b.expect) {
      const bool has = ack.reason.find(e) != std::string::npos;
      EXPECT_TRUE(has) << b.field << ": the reason lacks '" << e << "': " << ack.reason;
      all = all && has;
    }
    table << "| " << b.field << " | `" << cell(b.kind) << "` | `" << cell(b.args) << "` | " << (ack.accepted ? "yes" : "no") << " | "
          << cell(ack.reason, 400) << " |\n";
    return all;
  };
  int refused = 0;
  unsigned long last_frame = first->frame;
  for (const BadCommand& b : bad_commands()) {
    refused += refused_naming(client.send(run, b.kind, b.args, 20s), b);
    // The run keeps stepping: a newer state after each refusal.
    const auto st = client.next_state(run, 10s, static_cast<long>(last_frame));
    ASSERT_TRUE(st) << b.field << ": no state after the refusal\n" << read_file(dir.file("serve.log"));
    EXPECT_GT(st->frame, last_frame);
    last_frame = st->frame;
  }

  // A malformed cycle played by the real client: refused at its first action, exit 3.
  write_file(dir.file("bad-cycle.yaml"), "name: bad\nactions:\n  - at: 0\n    set_time_step: {dt: -1}\n");
  const ProcessResult cyc = run_process({"/usr/bin/env", "CYCLONEDDS_URI=" FIBERFEM_DDS_URI, FIBERFEM_BIN, "ctl", "--run", run, "play",
                                         dir.file("bad-cycle.yaml")});
  EXPECT_EQ(cyc.exit_code, 3) << cyc.output;
  EXPECT_NE(cyc.output.find("REJECTED at frame"), std::string::npos) << cyc.output;
  EXPECT_NE(cyc.output.find("'dt' = -1 is out of range"), std::string::npos) << cyc.output;
  table << "| cycle action `set_time_step: {dt: -1}` (`fiberfem ctl play`) | `set_time_step` | `{dt: -1}` | no | exit " << cyc.exit_code
        << ", " << cell(cyc.output.substr(cyc.output.find("REJECTED") == std::string::npos ? 0 : cyc.output.find("REJECTED"), 64), 400) << " |\n";

  // Still a working service: status advances, a good command is accepted, it shuts down cleanly.
  const auto s1 = client.status(run, 5s);
  ASSERT_TRUE(s1);
  std::this_thread::sleep_for(300ms);
  const auto s2 = client.status(run, 5s);
  ASSERT_TRUE(s2);
  EXPECT_GT(s2->frame, s1->frame);
  EXPECT_EQ(s2->state, "running");
  EXPECT_TRUE(client.send(run, "set_gravity", R"({"gravity": [0, 0, -1]})").accepted);
  EXPECT_TRUE(client.send(run, "shutdown", "{}").accepted);
  EXPECT_EQ(service.wait(30), 0) << read_file(dir.file("serve.log"));

  // The recording: opens, frames complete and in order, every command the run saw.
  const archive::ArchiveReader a(h5);
  EXPECT_GT(a.frames(), 10);
  const auto times = a.times();
  for (size_t i = 1; i < times.size(); ++i) EXPECT_GT(times[i], times[i - 1]);
  const archive::Frame last = a.frame(a.frames() - 1);
  EXPECT_TRUE(last.positions.allFinite());
  EXPECT_EQ(last.status, "ok");
  const auto cmds = a.commands();
  size_t expect_recorded = 2;  // the good set_gravity and the shutdown
  for (const BadCommand& b : bad_commands()) expect_recorded += b.recorded;
  expect_recorded += 1;  // the cycle's refused action
  EXPECT_EQ(cmds.size(), expect_recorded);
  size_t refused_recorded = 0;
  for (const auto& c : cmds) refused_recorded += !c.accepted && !c.reason.empty();
  EXPECT_EQ(refused_recorded, expect_recorded - 2);
  const ProcessResult info = run_process({FIBERFEM_BIN, "archive", "info", h5});
  EXPECT_EQ(info.exit_code, 0) << info.output;

  // The same recording replayed: the replay's own commands refuse bad values too, and it
  // keeps publishing.
  const std::string rrun = run + "-replay";
  BackgroundProcess replay({FIBERFEM_BIN, "replay", h5, "--run-id", rrun, "--loop", "--status-hz", "10"}, dir.file("replay.log"));
  ASSERT_EQ(client.resolve_run(rrun, 20s), rrun) << read_file(dir.file("replay.log"));
  const std::vector<BadCommand> replay_bad = {
      {"replay: step count fractional", "step", R"({"count": 1.5})", {"'count'", "whole number"}},
      {"replay: seek frame fractional", "seek", R"({"frame": 2.5})", {"'frame'", "whole number"}},
      {"replay: seek time NaN", "seek", R"({"time": .nan})", {"'time'", "not finite"}},
      {"replay: seek time negative", "seek", R"({"time": -1})", {"'time' = -1", "out of range"}},
      {"replay: seek both time and frame", "seek", R"({"time": 0, "frame": 0})", {"exactly one of 'time'"}},
      {"replay: rate out of range", "set_rate", R"({"rate": 1e9})", {"'rate' = 1e+09", "out of range"}},
      {"replay: loop not a boolean", "loop", R"({"on": "maybe"})", {"'on'", "true or false"}},
      {"replay: a live-run command", "set_gravity", R"({"gravity": [0, 0, 1]})", {"not a replay command"}},
      {"replay: argument key a list", "seek", R"({[1]: 2})", {"argument names"}},
  };
  int replay_refused = 0;
  for (const BadCommand& b : replay_bad) {
    replay_refused += refused_naming(client.send(rrun, b.kind, b.args, 20s), b);
  }
  const auto r1 = client.status(rrun, 5s);
  std::this_thread::sleep_for(500ms);
  const auto r2 = client.status(rrun, 5s);
  ASSERT_TRUE(r1 && r2);
  EXPECT_NE(r2->frame, r1->frame) << "the replay stopped publishing";
  EXPECT_TRUE(client.send(rrun, "shutdown", "{}").accepted);
  EXPECT_EQ(replay.wait(30), 0) << read_file(dir.file("replay.log"));

  table << "\n" << replay_refused << " of " << replay_bad.size() << " bad replay commands refused with the field named. "
        << refused << " of " << bad_commands().size() << " bad commands refused with the field named; the run stepped on "
        << "(frame " << first->frame << " to " << s2->frame << "); the recording holds " << a.frames() << " frames and " << cmds.size()
        << " command records (" << refused_recorded << " refusals with their reasons; the " << (bad_commands().size() + 1 + 2 - cmds.size())
        << " samples the decoder refused never reach the run or the recording) and `fiberfem archive info` reads it (exit "
        << info.exit_code << ").\n";
  if (const char* out = std::getenv("FIBERFEM_BAD_COMMAND_TABLE")) std::ofstream(out) << table.str();
  std::printf("%s", table.str().c_str());
}

}  // namespace
}  // namespace fiberfem::testing
