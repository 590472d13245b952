// `fiberfem run` as a user runs it (the real binary): the JSON report's content against the
// scene and against itself, the scene hash, overrides and CLI shorthands, failing runs
// (exit status and reason), bad input, and an interrupted run that still leaves its report.

#include "process_support.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <csignal>
#include <fcntl.h>
#include <thread>

namespace {

using fiberfem::testing::read_file;
using fiberfem::testing::read_json;
using fiberfem::testing::run_process;
using fiberfem::testing::TempDir;
using fiberfem::testing::write_file;
using nlohmann::json;

const std::string kBin = FIBERFEM_BIN;

// A small dynamic beam; the tip probe sits on the free end.
const char* kScene = R"(name: report-beam
mesh:
  generator: box
  size: [0.02, 0.004, 0.004]
  cells: [10, 2, 2]
regions:
  - name: all
    select: all
    material: {E_L: 60.0e3, E_T: 20.0e3, nu_LT: 0.25, nu_T: 0.45, G_L: 8.0e3, density: 1000.0}
    damping: {mass: 5.0}
fixed:
  - plane: {axis: x, value: 0.0}
loads:
  gravity: [0, 0, -9.81]
solver:
  dt: 0.01
  until: 0.2
probes:
  tip: [0.02, 0.002, 0.002]
  root: [0.0, 0.002, 0.002]
)";

// The pthread OpenBLAS starts a thread per core when it loads, and they spin for 0.1 s
// beside the first steps; fiberfem sets it to one thread and stops its threads as it
// starts, unless the user set OPENBLAS_NUM_THREADS: a one-thread run is then one thread.
TEST(BatchRun, TheProcessRunsWithoutBlasThreads) {
  auto observe = [](const std::vector<std::string>& env, std::string& blas, int& threads) {
    fiberfem::testing::BackgroundProcess run({kBin, "run", "--builtin", "cantilever", "--steps", "100000000", "--threads", "1"},
                                             "/tmp/fiberfem-blas-threads.log", env);
    const std::string proc = "/proc/" + std::to_string(run.pid());
    std::this_thread::sleep_for(std::chrono::milliseconds(500));  // stepping by now
    // (The environment the process started with: a value set by the process itself is not here.)
    const std::string environ = read_file(proc + "/environ");
    const size_t at = environ.find("OPENBLAS_NUM_THREADS=");
    blas = at == std::string::npos ? "" : environ.substr(at + 21, environ.find('\0', at) - at - 21);
    threads = 0;
    for (const auto& t : std::filesystem::directory_iterator(proc + "/task")) threads += t.is_directory();
  };
  std::string blas;
  int threads = 0;
  observe({}, blas, threads);
  EXPECT_EQ(threads, 1) << "a one-thread run should have no other thread (OpenBLAS's would be one per core)";
  observe({"OPENBLAS_NUM_THREADS=2"}, blas, threads);
  EXPECT_EQ(blas, "2");
  EXPECT_EQ(threads, 2) << "the user's OPENBLAS_NUM_THREADS should be kept, and OpenBLAS's second thread with it";
}

TEST(BatchRun, ReportDescribesTheRun) {
  TempDir dir;
  write_file(dir.file("beam.yaml"), kScene);
  const auto r = run_process({kBin, "run", dir.file("beam.yaml"), "--report", dir.file("r.json")});
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const json j = read_json(dir.file("r.json"));
  ASSERT_TRUE(j.is_object()) << read_file(dir.file("r.json"));
  EXPECT_EQ(j["format"], "fiberfem-run-report");
  EXPECT_EQ(j["status"], "completed");
  EXPECT_EQ(j["scene"]["name"], "report-beam");
  EXPECT_EQ(j["scene"]["elements"], 10 * 2 * 2 * 6);
  EXPECT_EQ(j["scene"]["nodes"], 11 * 3 * 3);
  EXPECT_EQ(j["scene"]["sha256"].get<std::string>().size(), 64u);
  // The cells are 2 mm cubes (0.02 / 10, 0.004 / 2): Kuhn tetrahedra of a cube have
  // dihedral angles 45, 60 and 90 degrees.
  EXPECT_NEAR(j["scene"]["min_dihedral_deg"].get<double>(), 45.0, 1e-9);
  EXPECT_NEAR(j["scene"]["max_dihedral_deg"].get<double>(), 90.0, 1e-9);
  // 0.2 s at 0.01 s: 20 steps, and the simulated time they add up to.
  EXPECT_EQ(j["steps"]["requested"], 20);
  EXPECT_EQ(j["steps"]["completed"], 20);
  EXPECT_NEAR(j["steps"]["simulated_time_s"].get<double>(), 0.2, 1e-12);
  // Phase times add up to no more than the step total, which is no more than wall time.
  const json& t = j["timing"]["mean_per_step_s"];
  EXPECT_LE(t["rotations"].get<double>() + t["assembly"].get<double>() + t["solve"].get<double>(),
            t["total"].get<double>() * (1 + 1e-9));
  EXPECT_LE(j["timing"]["engine_s"].get<double>(), j["timing"]["wall_s"].get<double>());
  EXPECT_GT(j["solver"]["iterations_total"].get<int>(), 0);
  EXPECT_LE(j["solver"]["max_relative_residual"].get<double>(), 1e-6);
  // Probes: final = rest + displacement; the clamped root does not move; the tip sags.
  ASSERT_EQ(j["probes"].size(), 2u);
  for (const json& p : j["probes"])
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR(p["final_m"][k].get<double>(), p["rest_m"][k].get<double>() + p["displacement_m"][k].get<double>(), 1e-15);
  EXPECT_EQ(j["probes"][1]["name"], "root");
  EXPECT_EQ(j["probes"][1]["displacement_m"], json::array({0.0, 0.0, 0.0}));
  EXPECT_LT(j["probes"][0]["displacement_m"][2].get<double>(), -1e-5);
  // Energy: released from rest, the beam converts gravity potential into strain energy
  // and motion, losing some to damping: elastic + kinetic gained <= potential lost.
  const json& e0 = j["energies"]["initial"];
  const json& e1 = j["energies"]["final"];
  EXPECT_EQ(e0["kinetic_j"].get<double>(), 0.0);
  EXPECT_EQ(e0["elastic_j"].get<double>(), 0.0);
  const double lost = e0["gravity_j"].get<double>() - e1["gravity_j"].get<double>();
  EXPECT_GT(lost, 0);
  EXPECT_LE(e1["elastic_j"].get<double>() + e1["kinetic_j"].get<double>(), lost);
  // The summary names the steps and the probes.
  EXPECT_NE(r.output.find("summary: completed: 20 of 20 steps"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("probe tip: displacement"), std::string::npos);
}

TEST(BatchRun, StaticReportAgreesWithTheSettledDynamicRun) {
  TempDir dir;
  write_file(dir.file("beam.yaml"), kScene);
  const auto s = run_process({kBin, "run", dir.file("beam.yaml"), "--static", "--report", dir.file("s.json")});
  ASSERT_EQ(s.exit_code, 0) << s.output;
  const auto d = run_process({kBin, "run", dir.file("beam.yaml"), "--until", "3", "--report", dir.file("d.json")});
  ASSERT_EQ(d.exit_code, 0) << d.output;
  const json js = read_json(dir.file("s.json")), jd = read_json(dir.file("d.json"));
  EXPECT_EQ(js["mode"], "static");
  EXPECT_TRUE(js["static"]["converged"].get<bool>());
  EXPECT_LT(js["static"]["relative_residual"].get<double>(), 1e-8);
  // After 3 s with mass damping 5/s (amplitude e^-7.5), the dynamic tip is at the static one.
  const double us = js["probes"][0]["displacement_m"][2].get<double>();
  const double ud = jd["probes"][0]["displacement_m"][2].get<double>();
  EXPECT_NEAR(ud / us, 1.0, 2e-3);
  EXPECT_EQ(jd["steps"]["completed"], 300);
}

TEST(BatchRun, SceneHashFollowsContentNotLayout) {
  TempDir dir;
  auto hash = [&](const std::string& text, std::vector<std::string> extra = {}) {
    write_file(dir.file("s.yaml"), text);
    std::vector<std::string> args{kBin, "run", dir.file("s.yaml"), "--steps", "1", "--report", dir.file("h.json")};
    args.insert(args.end(), extra.begin(), extra.end());
    const auto r = run_process(args);
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return read_json(dir.file("h.json"))["scene"]["sha256"].get<std::string>();
  };
  const std::string base = hash(kScene);
  // Comments and blank lines do not change the scene.
  EXPECT_EQ(hash(std::string("# a comment\n\n") + kScene), base);
  // A changed value does, whether edited in the file or set on the command line, and the
  // two agree when they say the same thing.
  const std::string edited = fiberfem::testing::replace_once(kScene, "dt: 0.01", "dt: 0.005");
  EXPECT_NE(hash(edited), base);
  EXPECT_EQ(hash(kScene, {"--set", "solver.dt=0.005"}), hash(edited));
  EXPECT_EQ(hash(kScene, {"--dt", "0.005"}), hash(edited));
}

TEST(BatchRun, OverridesAndShorthandsReachTheRun) {
  TempDir dir;
  write_file(dir.file("beam.yaml"), kScene);
  const auto r = run_process({kBin, "run", dir.file("beam.yaml"), "--cells", "8", "2", "2", "--solver", "direct", "--set",
                              "solver.until=0.05", "--report", dir.file("r.json")});
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const json j = read_json(dir.file("r.json"));
  EXPECT_EQ(j["scene"]["elements"], 8 * 2 * 2 * 6);
  EXPECT_EQ(j["solver"]["method"], "direct");
  EXPECT_EQ(j["steps"]["requested"], 5);
  EXPECT_EQ(j["scene"]["overrides"], json::array({"solver.method=direct", "mesh.cells=[8, 2, 2]", "solver.until=0.05"}));
}

TEST(BatchRun, FailingRunExitsNonZeroWithTheReasonAndKeepsItsReport) {
  TempDir dir;
  write_file(dir.file("beam.yaml"), kScene);
  // One block-Jacobi iteration cannot reach the failure residual: every retry fails.
  const auto r = run_process({kBin, "run", dir.file("beam.yaml"), "--preconditioner", "block_jacobi", "--set",
                              "solver.max_iterations=1", "--set", "solver.tolerance=1e-12", "--report", dir.file("r.json")});
  EXPECT_NE(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("failed"), std::string::npos) << r.output;
  const json j = read_json(dir.file("r.json"));
  EXPECT_EQ(j["status"], "failed");
  EXPECT_NE(j["reason"].get<std::string>().find("step 1"), std::string::npos) << j["reason"];
  EXPECT_EQ(j["steps"]["completed"], 0);
}

TEST(BatchRun, BadInputIsRefusedByName) {
  TempDir dir;
  write_file(dir.file("beam.yaml"), fiberfem::testing::replace_once(kScene, "dt: 0.01", "dt: -0.01"));
  auto r = run_process({kBin, "run", dir.file("beam.yaml"), "--report", dir.file("r.json")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("beam.yaml:16: solver.dt: must be in"), std::string::npos) << r.output;
  write_file(dir.file("beam.yaml"), kScene);
  r = run_process({kBin, "run", dir.file("beam.yaml"), "--set", "solver.method=cholesky"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("--set solver.method: 'cholesky' is not one of pcg, direct"), std::string::npos) << r.output;
  r = run_process({kBin, "run", dir.file("missing.yaml")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("missing.yaml: cannot open the scene file"), std::string::npos) << r.output;
  r = run_process({kBin, "run", "--builtin", "heart-of-gold"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("unknown built-in scene 'heart-of-gold'"), std::string::npos) << r.output;
  // An unwritable report path fails the run by name.
  r = run_process({kBin, "run", dir.file("beam.yaml"), "--steps", "1", "--report", dir.file("no/such/dir/r.json")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("--report"), std::string::npos) << r.output;
}

TEST(BatchRun, InterruptedRunWritesItsReport) {
  TempDir dir;
  write_file(dir.file("beam.yaml"), kScene);
  const std::string report = dir.file("r.json");
  // A run far longer than the test: SIGINT must stop it at a step boundary.
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    const int devnull = open("/dev/null", O_WRONLY);
    dup2(devnull, 1);
    dup2(devnull, 2);
    execl(kBin.c_str(), kBin.c_str(), "run", dir.file("beam.yaml").c_str(), "--until", "1e6", "--report", report.c_str(),
          static_cast<char*>(nullptr));
    _exit(127);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  kill(pid, SIGINT);
  int status = 0;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 1);
  const json j = read_json(report);
  EXPECT_EQ(j["status"], "interrupted");
  EXPECT_GT(j["steps"]["completed"].get<int>(), 0);
  EXPECT_LT(j["steps"]["completed"].get<int>(), j["steps"]["requested"].get<int>());
}

}  // namespace

namespace {
// A bar on rollers contracting slowly along its fibers (sine twitch, systole 2 s, heavy
// mass damping): quasi-static uniaxial stress, so the fiber stretch is 1 - T/E_L everywhere.
const char* kBar = R"(name: bar
mesh:
  generator: box
  size: [0.02, 0.004, 0.004]
  cells: [10, 2, 2]
regions:
  - name: muscle
    select: all
    material: {E_L: 60.0e3, E_T: 20.0e3, nu_LT: 0.25, nu_T: 0.45, G_L: 8.0e3, density: 1000.0}
    damping: {mass: 200.0}
fixed:
  - plane: {axis: x, value: 0.0}
    components: [x]
  - box: [[-1.0e-9, -1.0e-9, -1.0e-9], [1.0e-9, 1.0e-9, 1.0e-9]]
    components: [y, z]
  - box: [[-1.0e-9, 0.003999, -1.0e-9], [1.0e-9, 0.004001, 1.0e-9]]
    components: [z]
contraction:
  peak_tension: 600.0
  period: 4.0
  twitch: {shape: sine, systole: 2.0}
solver:
  dt: 0.01
  until: 2.0
)";
}  // namespace

// The report's contraction metrics against the uniaxial answer: peak fiber shortening
// T / E_L = 0.01 (3%: the damping lag of the slow motion, measured 0.4% in
// tests/core/contraction_test.cpp), reached in beat 0.
TEST(BatchRun, FiberShorteningOfAContractingBar) {
  TempDir dir;
  write_file(dir.file("bar.yaml"), kBar);
  const auto r = run_process({kBin, "run", dir.file("bar.yaml"), "--report", dir.file("r.json")});
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const json j = read_json(dir.file("r.json"));
  ASSERT_TRUE(j.contains("contraction")) << j.dump(1);
  EXPECT_EQ(j["contraction"]["mode"], "active_stress");
  EXPECT_NEAR(j["contraction"]["peak_fiber_shortening"].get<double>() / (600.0 / 60e3), 1.0, 0.03);
  ASSERT_EQ(j["contraction"]["beats"].size(), 1u);
  EXPECT_EQ(j["contraction"]["beats"][0]["beat"], 0);
  EXPECT_NE(r.output.find("peak fiber shortening"), std::string::npos);
}
