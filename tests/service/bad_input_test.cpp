// Bad input at every file and command-line entry point of the real `fiberfem` binary
// (docs/bad-input.md): each row runs the binary on one bad value and checks that it exits
// non-zero without a signal or a sanitizer report, with a message naming the file, key or
// option and what is wrong. With FIBERFEM_BAD_INPUT_TABLE=FILE set, the observed rows
// (exit code and the first line of the message) are written there as a Markdown table:
// scripts/bad_input_table.sh puts them into docs/bad-input.md.

#include "process_support.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <unistd.h>
#include <vector>

namespace fiberfem::testing {
namespace {

const char* kTiny = R"(name: tiny
mesh: {generator: box, size: [0.1, 0.02, 0.02], cells: [2, 1, 1]}
regions:
  - name: tissue
    select: all
    material: {E_L: 60.0e3, E_T: 20.0e3, nu_LT: 0.25, nu_T: 0.45, G_L: 8.0e3, density: 1000.0}
fibers: {uniform: [1, 0, 0]}
fixed:
  - plane: {axis: x, value: 0.0}
loads: {gravity: [0, 0, -9.81]}
contraction: {peak_tension: 1000, heart_rate: 60}
solver: {dt: 0.01, until: 0.04}
)";

// kTiny with `from` replaced by `to` (the test fails if `from` is not there).
std::string tiny_with(const std::string& from, const std::string& to) {
  std::string s = kTiny;
  const size_t at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) s.replace(at, from.size(), to);
  return s;
}

struct Row {
  std::string entry;   // entry point (command and what it reads)
  std::string field;   // the file, key or option
  std::string bad;     // the bad value, in words
  std::vector<std::string> args;  // after the binary; {D} is the scratch directory
  std::vector<std::string> expect;  // fragments the message must contain ({D} too)
};

std::string expand(std::string s, const std::string& dir) {
  for (size_t at; (at = s.find("{D}")) != std::string::npos;) s.replace(at, 3, dir);
  return s;
}

// The line of the output that carries the refusal: the first with the row's first
// expected fragment, else the first non-empty one.
std::string error_line(const std::string& output, const std::string& fragment, const std::string& dir) {
  std::istringstream in(output);
  std::string line, found;
  while (std::getline(in, line)) {
    if (line.find(fragment) != std::string::npos) {
      found = line;
      break;
    }
    if (found.empty() && !line.empty()) found = line;
  }
  for (size_t at; (at = found.find(dir)) != std::string::npos;) found.replace(at, dir.size(), "D");
  for (size_t at = 0; (at = found.find('|', at)) != std::string::npos; at += 2) found.replace(at, 1, "\\|");
  if (found.size() > 300) found = found.substr(0, 300) + "...";
  return found;
}

class BadInput : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir();
    const auto f = [](const std::string& n) { return dir_->file(n); };
    write_file(f("tiny.yaml"), kTiny);
    // Unreadable: mode 000 (root reads it anyway: that row runs as nobody through setpriv).
    std::filesystem::permissions(dir_->file(""), std::filesystem::perms::owner_all | std::filesystem::perms::group_read |
                                                     std::filesystem::perms::group_exec | std::filesystem::perms::others_read |
                                                     std::filesystem::perms::others_exec);
    write_file(f("locked.yaml"), kTiny);
    std::filesystem::permissions(f("locked.yaml"), std::filesystem::perms::none);
    write_file(f("empty.yaml"), "");
    std::filesystem::create_directories(f("a-directory"));
    write_file(f("not-yaml.yaml"), "name: [unclosed\n  mesh: {\n");
    write_file(f("list.yaml"), "- 1\n- 2\n");
    write_file(f("missing-mesh.yaml"), tiny_with("mesh: {generator: box, size: [0.1, 0.02, 0.02], cells: [2, 1, 1]}\n", ""));
    write_file(f("nan-material.yaml"), tiny_with("E_L: 60.0e3", "E_L: .nan"));
    write_file(f("inf-gravity.yaml"), tiny_with("gravity: [0, 0, -9.81]", "gravity: [0, 0, -.inf]"));
    write_file(f("string-dt.yaml"), tiny_with("dt: 0.01", "dt: fast"));
    write_file(f("negative-dt.yaml"), tiny_with("dt: 0.01", "dt: -0.01"));
    write_file(f("nu-out-of-range.yaml"), tiny_with("nu_T: 0.45", "nu_T: 1.5"));
    write_file(f("huge-cells.yaml"), tiny_with("cells: [2, 1, 1]", "cells: [100000, 100000, 100000]"));
    write_file(f("unknown-key.yaml"), tiny_with("solver: {dt: 0.01", "solver: {dt: 0.01, speed: 11"));
    write_file(f("zero-fiber.yaml"), tiny_with("uniform: [1, 0, 0]", "uniform: [0, 0, 0]"));
    write_file(f("mesh-missing.yaml"), tiny_with("{generator: box, size: [0.1, 0.02, 0.02], cells: [2, 1, 1]}", "{file: nowhere.msh}"));
    write_file(f("mesh-dir.yaml"), tiny_with("{generator: box, size: [0.1, 0.02, 0.02], cells: [2, 1, 1]}", "{file: a-directory.msh}"));
    std::filesystem::create_directories(f("a-directory.msh"));
    write_file(f("fibers-dev-zero.yaml"), tiny_with("{uniform: [1, 0, 0]}", "{file: /dev/zero}"));
    write_file(f("truncated.msh"), "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n");
    write_file(f("mesh-truncated.yaml"), tiny_with("{generator: box, size: [0.1, 0.02, 0.02], cells: [2, 1, 1]}", "{file: truncated.msh}"));
    write_file(f("mesh-empty.yaml"), tiny_with("{generator: box, size: [0.1, 0.02, 0.02], cells: [2, 1, 1]}", "{file: empty.msh}"));
    write_file(f("empty.msh"), "");
    // Fiber files: the box has 2 cells = 12 elements and 12 nodes.
    write_file(f("fibers-5.txt"), "1 0 0\n1 0 0\n1 0 0\n1 0 0\n1 0 0\n");
    write_file(f("fibers-wrong-mesh.yaml"), tiny_with("{uniform: [1, 0, 0]}", "{file: fibers-5.txt}"));
    write_file(f("fibers-nan.txt"), "1 0 0\nnan 0 0\n");
    write_file(f("fibers-nan.yaml"), tiny_with("{uniform: [1, 0, 0]}", "{file: fibers-nan.txt}"));
    write_file(f("fibers-truncated.txt"), "1 0 0\n1 0\n");
    write_file(f("fibers-truncated.yaml"), tiny_with("{uniform: [1, 0, 0]}", "{file: fibers-truncated.txt}"));
    write_file(f("fibers-empty.txt"), "");
    write_file(f("fibers-empty.yaml"), tiny_with("{uniform: [1, 0, 0]}", "{file: fibers-empty.txt}"));
    write_file(f("fibers-dir.yaml"), tiny_with("{uniform: [1, 0, 0]}", "{file: a-directory}"));
    // Archives.
    write_file(f("not-hdf5.h5"), "this is not an HDF5 file\n");
    write_file(f("empty.h5"), "");
    ProcessResult r = run_process({FIBERFEM_BIN, "run", f("tiny.yaml"), "--archive", f("good.h5")});
    ASSERT_EQ(r.exit_code, 0) << r.output;
    {  // the first half of a good archive
      const std::string bytes = read_file_binary(f("good.h5"));
      std::ofstream(f("truncated.h5"), std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size() / 2));
    }
    // Another format version, and a file of another program, made with h5py.
    r = run_process({FIBERFEM_PYTHON, "-c",
                     "import h5py, shutil, sys; d = sys.argv[1]; shutil.copy(d + '/good.h5', d + '/version3.h5')\n"
                     "with h5py.File(d + '/version3.h5', 'r+') as f: f.attrs['format_version'] = 3\n"
                     "with h5py.File(d + '/other.h5', 'w') as f: f['x'] = [1, 2, 3]\n"
                     "shutil.copy(d + '/good.h5', d + '/bad-tets.h5')\n"
                     "with h5py.File(d + '/bad-tets.h5', 'r+') as f: f['mesh/tets'][0, 0] = 1000\n"
                     "shutil.copy(d + '/good.h5', d + '/bad-checkpoint.h5')\n"
                     "with h5py.File(d + '/bad-checkpoint.h5', 'r+') as f:\n"
                     "  e = f['checkpoints/header_end'][:]; at = int(e[-2]) if len(e) > 1 else 0\n"
                     "  f['checkpoints/headers'][at:at + 8] = list(b'garbage!')\n",
                     dir_->file("")});
    ASSERT_EQ(r.exit_code, 0) << r.output;
    // Another scene's archive (12 elements there, 48 here): resuming it is a wrong mesh.
    write_file(f("bigger.yaml"), tiny_with("cells: [2, 1, 1]", "cells: [4, 2, 1]"));
    // Cycle scripts.
    write_file(f("cycle-no-actions.yaml"), "name: x\nactions: []\n");
    write_file(f("cycle-nan.yaml"), "actions:\n  - at: .nan\n    pause: {}\n");
    write_file(f("cycle-list-kind.yaml"), "actions:\n  - at: 1\n    command: [pause]\n");
    write_file(f("cycle-huge.yaml"), "actions:\n  - at: 0\n    every: 0.001\n    until: 1000000\n    pause: {}\n");
    write_file(f("cycle-times.yaml"), "actions:\n  - at: 0\n    every: 1\n    times: 2.5\n    pause: {}\n");
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static std::string read_file_binary(const std::string& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  }
  static TempDir* dir_;
};
TempDir* BadInput::dir_ = nullptr;

const std::vector<Row>& rows() {
  static const std::vector<Row> r = {
      // Scene files.
      {"run SCENE", "scene file", "missing", {"run", "{D}/nowhere.yaml"}, {"nowhere.yaml", "does not exist"}},
      {"run SCENE", "scene file", "a directory", {"run", "{D}/a-directory"}, {"a-directory", "is a directory"}},
      {"run SCENE", "scene file", "unreadable (mode 000)", {"{nobody}", "run", "{D}/locked.yaml"}, {"locked.yaml", "cannot be read"}},
      {"run SCENE", "scene file", "empty", {"run", "{D}/empty.yaml"}, {"empty.yaml", "mapping"}},
      {"run SCENE", "scene file", "not YAML", {"run", "{D}/not-yaml.yaml"}, {"not-yaml.yaml:", "YAML"}},
      {"run SCENE", "scene file", "a list, not a mapping", {"run", "{D}/list.yaml"}, {"list.yaml", "mapping"}},
      {"run SCENE", "mesh", "missing", {"run", "{D}/missing-mesh.yaml"}, {"missing-mesh.yaml", "mesh", "missing"}},
      {"run SCENE", "regions[0].material.E_L", "NaN", {"run", "{D}/nan-material.yaml"}, {"nan-material.yaml:6", "E_L", "finite"}},
      {"run SCENE", "loads.gravity[2]", "-inf", {"run", "{D}/inf-gravity.yaml"}, {"inf-gravity.yaml:10", "gravity[2]", "finite"}},
      {"run SCENE", "solver.dt", "a string", {"run", "{D}/string-dt.yaml"}, {"string-dt.yaml:12", "solver.dt", "number"}},
      {"run SCENE", "solver.dt", "negative", {"run", "{D}/negative-dt.yaml"}, {"negative-dt.yaml:12", "solver.dt"}},
      {"run SCENE", "regions[0].material.nu_T", "1.5 (out of range)", {"run", "{D}/nu-out-of-range.yaml"}, {"nu-out-of-range.yaml", "nu_T"}},
      {"run SCENE", "mesh.cells", "1e15 cells (huge)", {"run", "{D}/huge-cells.yaml"}, {"huge-cells.yaml:2", "mesh.cells", "at most"}},
      {"run SCENE", "solver.speed", "unknown key", {"run", "{D}/unknown-key.yaml"}, {"unknown-key.yaml:12", "solver.speed", "unknown key"}},
      {"run SCENE", "fibers.uniform", "zero vector", {"run", "{D}/zero-fiber.yaml"}, {"zero-fiber.yaml:7", "fibers.uniform", "zero"}},
      // Mesh files.
      {"run SCENE", "mesh.file", "missing", {"run", "{D}/mesh-missing.yaml"}, {"mesh-missing.yaml:2", "nowhere.msh", "does not exist"}},
      {"run SCENE", "mesh.file", "a directory", {"run", "{D}/mesh-dir.yaml"}, {"mesh-dir.yaml:2", "a-directory.msh", "is a directory"}},
      {"run SCENE", "mesh.file", "truncated gmsh", {"run", "{D}/mesh-truncated.yaml"}, {"mesh-truncated.yaml:2", "truncated.msh:"}},
      {"run SCENE", "mesh.file", "empty gmsh", {"run", "{D}/mesh-empty.yaml"}, {"mesh-empty.yaml:2", "empty.msh"}},
      // Fiber files.
      {"run SCENE", "fibers.file", "5 vectors for a 12-element mesh (wrong mesh)", {"run", "{D}/fibers-wrong-mesh.yaml"},
       {"fibers-wrong-mesh.yaml:7", "fibers-5.txt", "5", "12"}},
      {"run SCENE", "fibers.file", "NaN component", {"run", "{D}/fibers-nan.yaml"}, {"fibers-nan.txt:2", "non-finite", "nan 0 0"}},
      {"run SCENE", "fibers.file", "truncated line", {"run", "{D}/fibers-truncated.yaml"}, {"fibers-truncated.txt:2", "three numbers"}},
      {"run SCENE", "fibers.file", "empty", {"run", "{D}/fibers-empty.yaml"}, {"fibers-empty.txt", "no vectors"}},
      {"run SCENE", "fibers.file", "/dev/zero (endless)", {"run", "{D}/fibers-dev-zero.yaml"}, {"fibers-dev-zero.yaml:7", "/dev/zero", "not a regular file"}},
      {"run SCENE", "fibers.file", "a directory", {"run", "{D}/fibers-dir.yaml"}, {"fibers-dir.yaml:7", "a-directory", "is a directory"}},
      // Command-line options.
      {"run", "--dt", "NaN", {"run", "{D}/tiny.yaml", "--dt", "nan"}, {"solver.dt", "expected a number"}},
      {"run", "--dt", "inf", {"run", "{D}/tiny.yaml", "--dt", "inf"}, {"--dt"}},
      {"run", "--dt", "a word", {"run", "{D}/tiny.yaml", "--dt", "fast"}, {"--dt"}},
      {"run", "--steps", "0", {"run", "{D}/tiny.yaml", "--steps", "0"}, {"--steps"}},
      {"run", "--until", "-1", {"run", "{D}/tiny.yaml", "--until", "-1"}, {"--until"}},
      {"run", "--cells", "0 1 1", {"run", "{D}/tiny.yaml", "--cells", "0", "1", "1"}, {"--cells"}},
      {"run", "--threads", "-1", {"run", "{D}/tiny.yaml", "--threads", "-1"}, {"--threads"}},
      {"run", "--compression", "10", {"run", "{D}/tiny.yaml", "--archive", "{D}/c.h5", "--compression", "10"}, {"--compression"}},
      {"run", "--set", "no '='", {"run", "{D}/tiny.yaml", "--set", "solver.dt"}, {"--set solver.dt", "key.path=value"}},
      {"run", "--set", "unknown key", {"run", "{D}/tiny.yaml", "--set", "solver.speed=3"}, {"--set solver.speed", "unknown key"}},
      {"run", "--set", "NaN value", {"run", "{D}/tiny.yaml", "--set", "solver.dt=.nan"}, {"--set solver.dt", "finite"}},
      {"run", "--builtin", "unknown name", {"run", "--builtin", "nothing"}, {"nothing"}},
      {"run", "(unknown option)", "--speed 3", {"run", "{D}/tiny.yaml", "--speed", "3"}, {"--speed"}},
      {"serve SCENE", "scene file", "NaN in the scene", {"serve", "{D}/nan-material.yaml", "--run-id", "bad-input-test"}, {"nan-material.yaml:6", "E_L", "finite"}},
      {"serve", "--publish-hz", "0", {"serve", "{D}/tiny.yaml", "--publish-hz", "0"}, {"--publish-hz"}},
      {"serve", "--real-time-factor", "inf", {"serve", "{D}/tiny.yaml", "--real-time-factor", "inf"}, {"--real-time-factor"}},
      {"serve --resume", "RUN.h5", "not HDF5", {"serve", "{D}/tiny.yaml", "--resume", "{D}/not-hdf5.h5", "--run-id", "bad-input-test"}, {"not-hdf5.h5", "not an HDF5 file"}},
      {"serve --resume", "RUN.h5", "another scene's archive (wrong mesh)", {"serve", "{D}/bigger.yaml", "--resume", "{D}/good.h5", "--run-id", "bad-input-test"}, {"--resume", "good.h5", "another scene"}},
      // Archives given to resume.
      {"run --resume", "RUN.h5", "missing", {"run", "{D}/tiny.yaml", "--resume", "{D}/nowhere.h5"}, {"nowhere.h5", "does not exist"}},
      {"run --resume", "RUN.h5", "a directory", {"run", "{D}/tiny.yaml", "--resume", "{D}/a-directory"}, {"a-directory", "is a directory"}},
      {"run --resume", "RUN.h5", "empty file", {"run", "{D}/tiny.yaml", "--resume", "{D}/empty.h5"}, {"empty.h5", "not an HDF5 file"}},
      {"run --resume", "RUN.h5", "not HDF5", {"run", "{D}/tiny.yaml", "--resume", "{D}/not-hdf5.h5"}, {"not-hdf5.h5", "not an HDF5 file"}},
      {"run --resume", "RUN.h5", "HDF5 of another program", {"run", "{D}/tiny.yaml", "--resume", "{D}/other.h5"}, {"other.h5", "not a fiberfem archive"}},
      {"run --resume", "RUN.h5", "format version 3", {"run", "{D}/tiny.yaml", "--resume", "{D}/version3.h5"}, {"version3.h5", "version 3", "reads version 1 and 2"}},
      {"run --resume", "RUN.h5", "truncated (first half)", {"run", "{D}/tiny.yaml", "--resume", "{D}/truncated.h5"}, {"truncated.h5"}},
      {"run --resume", "RUN.h5", "another scene's archive (wrong mesh)", {"run", "{D}/bigger.yaml", "--resume", "{D}/good.h5"}, {"--resume", "good.h5", "mesh with 12 nodes", "another scene"}},
      {"run --resume", "RUN.h5@T", "T not a number", {"run", "{D}/tiny.yaml", "--resume", "{D}/good.h5@soon"}, {"--resume", "soon", "not a time"}},
      {"run --resume", "RUN.h5@T", "T before the first checkpoint", {"run", "{D}/tiny.yaml", "--resume", "{D}/good.h5@-5"}, {"good.h5", "no checkpoint at or before"}},
      // Archives given to the archive tools and to replay.
      {"archive info", "RUN.h5", "missing", {"archive", "info", "{D}/nowhere.h5"}, {"nowhere.h5"}},
      {"archive info", "RUN.h5", "a directory", {"archive", "info", "{D}/a-directory"}, {"a-directory", "is a directory"}},
      {"archive info", "RUN.h5", "not HDF5", {"archive", "info", "{D}/not-hdf5.h5"}, {"not-hdf5.h5", "not an HDF5 file"}},
      {"archive info", "RUN.h5", "format version 3", {"archive", "info", "{D}/version3.h5"}, {"version3.h5", "version 3"}},
      {"archive info", "RUN.h5", "truncated", {"archive", "info", "{D}/truncated.h5"}, {"truncated.h5"}},
      {"archive info", "mesh/tets", "a node index out of range", {"archive", "info", "{D}/bad-tets.h5"}, {"bad-tets.h5", "mesh/tets[0] = 1000", "not a node index"}},
      {"run --resume", "checkpoints/headers", "garbage bytes in the last checkpoint", {"run", "{D}/tiny.yaml", "--resume", "{D}/bad-checkpoint.h5"}, {"bad-checkpoint.h5", "checkpoint", "malformed"}},
      {"archive recover", "RUN.h5", "not HDF5", {"archive", "recover", "{D}/not-hdf5.h5"}, {"not-hdf5.h5", "not an HDF5 file"}},
      {"replay", "RUN.h5", "missing", {"replay", "{D}/nowhere.h5", "--exit-at-end"}, {"nowhere.h5"}},
      {"replay", "RUN.h5", "not HDF5", {"replay", "{D}/not-hdf5.h5", "--exit-at-end"}, {"not-hdf5.h5", "not an HDF5 file"}},
      {"replay", "RUN.h5", "format version 3", {"replay", "{D}/version3.h5", "--exit-at-end"}, {"version3.h5", "version 3"}},
      {"replay", "--rate", "0", {"replay", "{D}/good.h5", "--rate", "0"}, {"--rate"}},
      {"replay", "--rate", "NaN", {"replay", "{D}/good.h5", "--rate", "nan"}, {"--rate", "nan"}},
      // Cycle scripts (parsed before any run is looked for).
      {"ctl play", "SCRIPT", "missing", {"ctl", "play", "{D}/nowhere.yaml"}, {"nowhere.yaml", "does not exist"}},
      {"ctl play", "SCRIPT", "a directory", {"ctl", "play", "{D}/a-directory"}, {"a-directory", "is a directory"}},
      {"ctl play", "SCRIPT", "/dev/zero (endless)", {"ctl", "play", "/dev/zero"}, {"/dev/zero", "not a regular file"}},
      {"ctl play", "SCRIPT", "empty", {"ctl", "play", "{D}/empty.yaml"}, {"empty.yaml", "mapping"}},
      {"ctl play", "actions", "empty list", {"ctl", "play", "{D}/cycle-no-actions.yaml"}, {"cycle-no-actions.yaml:1", "actions"}},
      {"ctl play", "actions[0].at", "NaN", {"ctl", "play", "{D}/cycle-nan.yaml"}, {"cycle-nan.yaml:2: action 1", "'at'", "finite"}},
      {"ctl play", "actions[0].command", "a list", {"ctl", "play", "{D}/cycle-list-kind.yaml"}, {"cycle-list-kind.yaml:3: action 1", "'command'"}},
      {"ctl play", "actions[0].every", "1e9 repeats (huge)", {"ctl", "play", "{D}/cycle-huge.yaml"}, {"cycle-huge.yaml", "action 1", "100000"}},
      {"ctl play", "actions[0].times", "2.5", {"ctl", "play", "{D}/cycle-times.yaml"}, {"cycle-times.yaml", "action 1", "'times'", "whole"}},
      {"ctl", "--timeout", "-1", {"ctl", "--timeout", "-1", "list"}, {"--timeout"}},
  };
  return r;
}

TEST_F(BadInput, EveryEntryPointRefusesWithAClearMessage) {
  const std::string dir = dir_->file("");
  const std::string d = dir.substr(0, dir.size() - 1);  // without the trailing '/'
  std::ostringstream table;
  table << "| entry point | file, key or option | bad value | exit | message (D = the test's directory) |\n"
        << "|---|---|---|---|---|\n";
  int passed = 0;
  for (const Row& row : rows()) {
    std::vector<std::string> args = {FIBERFEM_BIN};
    for (const std::string& a : row.args) args.push_back(expand(a, d));
    if (args[1] == "{nobody}") {  // as an ordinary user (root reads every file)
      args.erase(args.begin() + 1);
      if (geteuid() == 0) args.insert(args.begin(), {"/usr/bin/setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"});
    }
    // Loopback DDS for the commands that would start it (none should get that far).
    args.insert(args.begin(), {"/usr/bin/env", "CYCLONEDDS_URI=" FIBERFEM_DDS_URI, "ASAN_OPTIONS=abort_on_error=1"});
    const ProcessResult r = run_process(args);
    const std::string what = row.entry + " / " + row.field + " / " + row.bad;
    EXPECT_NE(r.exit_code, 0) << what << "\n" << r.output;
    EXPECT_LT(r.exit_code, 128) << what << ": died of a signal\n" << r.output;
    EXPECT_EQ(r.output.find("Sanitizer"), std::string::npos) << what << "\n" << r.output;
    EXPECT_EQ(r.output.find("runtime error:"), std::string::npos) << what << "\n" << r.output;
    EXPECT_EQ(r.output.find("terminate called"), std::string::npos) << what << "\n" << r.output;
    bool all = r.exit_code != 0 && r.exit_code < 128;
    for (const std::string& e : row.expect) {
      const bool has = r.output.find(expand(e, d)) != std::string::npos;
      EXPECT_TRUE(has) << what << ": the message lacks '" << e << "'\n" << r.output;
      all = all && has;
    }
    passed += all;
    table << "| `" << row.entry << "` | `" << row.field << "` | " << row.bad << " | " << r.exit_code << " | "
          << error_line(r.output, expand(row.expect.front(), d), d) << " |\n";
  }
  table << "\n" << passed << " of " << rows().size() << " bad inputs refused with a clear message, exit 1-127, no signal.\n";
  if (const char* out = std::getenv("FIBERFEM_BAD_INPUT_TABLE")) std::ofstream(out) << table.str();
  std::printf("%s", table.str().c_str());
}

}  // namespace
}  // namespace fiberfem::testing
