// The archive with the real `fiberfem` binary: kill -9 at random moments loses at most
// the frames of one flush interval and leaves a file a SWMR reader opens (and `fiberfem
// archive recover` makes ordinary); a SWMR reader follows a live run; `--resume RUN.h5@t`
// continues bit-for-bit like the uninterrupted run.

#include "service/archive/archive.hpp"

#include "process_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <random>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

namespace fiberfem {
namespace {

using testing::run_process;
using testing::TempDir;
using Clock = std::chrono::steady_clock;

const std::string kBin = FIBERFEM_BIN;
const std::string kHeart = std::string(FIBERFEM_SOURCE_DIR) + "/configs/scenes/heart.yaml";

/// A child process with its stdout on a pipe (read line by line).
class Child {
 public:
  explicit Child(const std::vector<std::string>& args) {
    int fds[2];
    if (pipe(fds) != 0) return;
    pid_ = fork();
    if (pid_ == 0) {
      dup2(fds[1], 1);
      close(fds[0]);
      close(fds[1]);
      std::vector<char*> argv;
      for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
      argv.push_back(nullptr);
      execv(argv[0], argv.data());
      _exit(127);
    }
    close(fds[1]);
    out_ = fdopen(fds[0], "r");
  }
  ~Child() {
    kill9();
    if (out_) fclose(out_);
  }
  /// Next line of its stdout (false at end of file).
  bool line(std::string& s) {
    char buf[512];
    if (!out_ || !fgets(buf, sizeof buf, out_)) return false;
    s = buf;
    return true;
  }
  void kill9() {
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      int status = 0;
      waitpid(pid_, &status, 0);
      pid_ = -1;
    }
  }
  int wait() {
    int status = 0;
    waitpid(pid_, &status, 0);
    pid_ = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

 private:
  pid_t pid_ = -1;
  FILE* out_ = nullptr;
};

// Frames that "frame F step S" lines announced, read until `until` (or the end).
long frames_announced(Child& c, Clock::time_point until) {
  long frames = 0;
  std::string s;
  while (Clock::now() < until && c.line(s)) {
    long f = 0, st = 0;
    if (std::sscanf(s.c_str(), "frame %ld step %ld", &f, &st) == 2) frames = f;
  }
  return frames;
}

// Every child runs on one thread (the same for the reference and the killed runs, and
// robust on a shared, loaded machine).
class ArchiveCli : public ::testing::Test {
 protected:
  void SetUp() override { setenv("OMP_NUM_THREADS", "1", 1); }
};

TEST_F(ArchiveCli, KillNineLosesAtMostOneFlushIntervalAndRecovers) {
  TempDir dir;
  constexpr int kFlush = 10, kSteps = 600;
  // The reference: the same run, uninterrupted.
  const std::string ref_path = dir.file("ref.h5");
  ASSERT_EQ(run_process({kBin, "run", kHeart, "--steps", "120", "--archive", ref_path, "--flush-frames", "1000"}).exit_code, 0);
  const archive::ArchiveReader ref(ref_path);
  ASSERT_EQ(ref.frames(), 121);

  std::mt19937 rng(20261123);
  std::uniform_real_distribution<double> after_s(0.02, 0.8);
  const auto t_start = Clock::now();
  std::vector<long> lost;
  for (int trial = 0; trial < 10; ++trial) {
    const std::string path = dir.file("killed" + std::to_string(trial) + ".h5");
    Child c({kBin, "run", kHeart, "--steps", std::to_string(kSteps), "--archive", path, "--flush-frames", std::to_string(kFlush),
             "--flush-seconds", "0", "--checkpoint-every", "0.25", "--log-frames"});
    std::string first;
    ASSERT_TRUE(c.line(first)) << "trial " << trial;  // the scene line
    // Kill at a random moment after the first frame (SWMR has started by then).
    long announced = 0;
    std::string s;
    while (announced == 0 && c.line(s)) std::sscanf(s.c_str(), "frame %ld", &announced);
    ASSERT_GT(announced, 0);
    const auto kill_at = Clock::now() + std::chrono::microseconds(static_cast<long>(after_s(rng) * 1e6));
    announced = std::max(announced, frames_announced(c, kill_at));
    c.kill9();

    // Opens as a SWMR reader; frames consecutive from step 0, finite and equal to the
    // uninterrupted run's; at most one flush interval lost. (The reader is closed before
    // recover: HDF5 locks the file.)
    long n = 0;
    {
      archive::ArchiveReader r(path, /*follow=*/true);
      n = r.frames();
      EXPECT_GE(n, announced - kFlush) << "trial " << trial << ": " << announced << " frames announced, " << n << " readable";
      EXPECT_GE(n, 1);
      const std::vector<long> steps = r.steps();
      for (long i = 0; i < n; ++i) EXPECT_EQ(steps[static_cast<size_t>(i)], i) << "trial " << trial;
      for (long i : {0L, n / 2, n - 1}) {
        if (i < 0 || i >= n || i >= ref.frames()) continue;
        const archive::Frame f = r.frame(i);
        EXPECT_TRUE(f.positions.allFinite());
        EXPECT_TRUE(f.positions == ref.frame(i).positions) << "trial " << trial << " frame " << i;
      }
      EXPECT_GE(r.checkpoints().size(), 1u);
    }
    lost.push_back(announced - n);
    std::printf("trial %d: killed after %ld frames announced, %ld readable (flush every %d)\n", trial, announced, n, kFlush);

    // Ordinary readers refuse it until it is recovered.
    if (trial < 3) {
      EXPECT_NE(run_process({"h5dump", "-H", path}).exit_code, 0) << "an ordinary open of a crashed SWMR file should fail";
      const auto rec = run_process({kBin, "archive", "recover", path});
      EXPECT_EQ(rec.exit_code, 0) << rec.output;
      EXPECT_NE(rec.output.find(std::to_string(n) + " intact frames"), std::string::npos) << rec.output;
      EXPECT_EQ(run_process({"h5dump", "-H", path}).exit_code, 0);
      archive::ArchiveReader plain(path, /*follow=*/false);
      EXPECT_EQ(plain.frames(), n);
      const std::string xdmf = testing::read_file(dir.file("killed" + std::to_string(trial) + ".xdmf"));
      EXPECT_NE(xdmf.find("<Grid Name=\"frame " + std::to_string(n - 1) + "\""), std::string::npos);
      EXPECT_EQ(xdmf.find("<Grid Name=\"frame " + std::to_string(n) + "\""), std::string::npos);
    }
  }
  EXPECT_LE(*std::max_element(lost.begin(), lost.end()), kFlush);
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - t_start).count(), 60.0);
}

TEST_F(ArchiveCli, SwmrReaderFollowsALiveRun) {
  TempDir dir;
  const std::string path = dir.file("live.h5");
  Child c({kBin, "run", kHeart, "--steps", "150", "--archive", path, "--flush-frames", "5", "--log-frames"});
  std::string s;
  long announced = 0;
  while (announced < 10 && c.line(s)) std::sscanf(s.c_str(), "frame %ld", &announced);
  archive::ArchiveReader r(path, /*follow=*/true);
  const long first = r.frames();
  std::vector<long> seen{first};
  while (c.line(s)) {
    if (s.rfind("frame", 0) == 0) seen.push_back(r.refresh());
  }
  EXPECT_EQ(c.wait(), 0);
  EXPECT_LT(first, 151);
  EXPECT_GT(seen.back(), first) << "the reader saw no new frames";
  EXPECT_TRUE(std::is_sorted(seen.begin(), seen.end()));
  r.refresh();
  EXPECT_EQ(r.frames(), 151);
  EXPECT_TRUE(r.frame(150).positions.allFinite());
  const auto info = run_process({kBin, "archive", "info", path});
  EXPECT_EQ(info.exit_code, 0) << info.output;
  EXPECT_NE(info.output.find("frames: 151"), std::string::npos) << info.output;
}

// A scene recorded for 40 steps with checkpoints every 0.3 s into `a`, resumed at 0.4 s
// (the checkpoint of step 18) into `b` to step 40; every frame of `b` equal to `a`'s.
void run_and_resume_at_step_18(const std::string& scene, const std::string& a, const std::string& b) {
  auto run = run_process({kBin, "run", scene, "--steps", "40", "--archive", a, "--checkpoint-every", "0.3"});
  ASSERT_EQ(run.exit_code, 0) << run.output;
  run = run_process({kBin, "run", "--resume", a + "@0.4", "--archive", b, "--steps", "40"});
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const archive::ArchiveReader ra(a), rb(b);
  ASSERT_EQ(rb.steps().front(), 18);
  for (long i = 0; i < rb.frames(); ++i) {
    const archive::Frame fb = rb.frame(i), fa = ra.frame(fb.step);
    EXPECT_TRUE(fb.positions == fa.positions) << "step " << fb.step;
  }
}

// A run with the closed-loop circulation resumes bit for bit too: the checkpoint carries
// the loop's state, the coupled cavities' volumes and their pressure responses.
TEST_F(ArchiveCli, ACirculationRunResumesBitForBit) {
  TempDir dir;
  const std::string a = dir.file("a.h5"), b = dir.file("b.h5");
  const std::string scene = std::string(FIBERFEM_SOURCE_DIR) + "/configs/scenes/heart-circulation-realtime.yaml";
  run_and_resume_at_step_18(scene, a, b);
  if (HasFatalFailure()) return;
  const archive::ArchiveReader ra(a), rb(b);
  const core::SimulatorCheckpoint ca = ra.read_checkpoint(ra.checkpoints().size() - 1);
  const core::SimulatorCheckpoint cb = rb.read_checkpoint(rb.checkpoints().size() - 1);
  ASSERT_EQ(ca.step_count, 40);
  ASSERT_EQ(cb.step_count, 40);
  ASSERT_EQ(cb.cavity_volume_m3.size(), 2u);  // both ventricles coupled
  EXPECT_TRUE(ca.x == cb.x);
  EXPECT_TRUE(ca.circulation.volume_m3 == cb.circulation.volume_m3);
  EXPECT_TRUE(ca.circulation.pressure_pa == cb.circulation.pressure_pa);
  EXPECT_TRUE(ca.cavity_volume_m3 == cb.cavity_volume_m3);
}

// On the accurate tier as well: the checkpoint adds the loop's state and the cavity's
// volume to the body's state.
TEST_F(ArchiveCli, AnAccurateCirculationRunResumesBitForBit) {
  TempDir dir;
  const std::string scene = dir.file("lv.yaml"), a = dir.file("a.h5"), b = dir.file("b.h5");
  testing::write_file(scene, R"(name: lv-circulation
mesh: {generator: lv_ellipsoid, resolution: {circumferential: 24, longitudinal: 10, transmural: 3}, refine: 0.5}
regions:
  - {name: myocardium, select: all, material: {law: neo_hookean, E: 40000.0, nu: 0.3, density: 1060.0}, damping: {mass: 20.0, stiffness: 0.0}}
fibers: {rule: {endo_angle: 60, epi_angle: -60}}
fixed: [{node_set: base}]
contraction: {peak_tension: 500.0, heart_rate: 72}
measure: {cavities: {lv: {node_set: endo}}}
circulation: {ventricles: {left: lv}, scale: {pressure: 0.00125, volume: 0.015}}
solver: {dt: 0.0166667}
)");
  run_and_resume_at_step_18(scene, a, b);
  if (HasFatalFailure()) return;
  const archive::ArchiveReader ra(a), rb(b);
  using core::hyperelastic::DynamicState;
  const auto ca = std::get<DynamicState>(ra.read_engine_checkpoint(ra.checkpoints().size() - 1));
  const auto cb = std::get<DynamicState>(rb.read_engine_checkpoint(rb.checkpoints().size() - 1));
  ASSERT_EQ(ca.steps, 40);
  ASSERT_EQ(cb.steps, 40);
  ASSERT_EQ(cb.cavity_volume_m3.size(), 1u);
  EXPECT_TRUE(ca.x == cb.x);
  EXPECT_TRUE(ca.circulation.volume_m3 == cb.circulation.volume_m3);
  EXPECT_TRUE(ca.circulation.pressure_pa == cb.circulation.pressure_pa);
  EXPECT_TRUE(ca.cavity_volume_m3 == cb.cavity_volume_m3);
  EXPECT_GT(ca.circulation.volume_m3[0], 0);
}

TEST_F(ArchiveCli, ResumeContinuesBitForBit) {
  TempDir dir;
  const std::string a = dir.file("a.h5"), b = dir.file("b.h5");
  auto run = run_process({kBin, "run", kHeart, "--steps", "70", "--archive", a, "--checkpoint-every", "0.5"});
  ASSERT_EQ(run.exit_code, 0) << run.output;
  run = run_process({kBin, "run", "--resume", a + "@0.7", "--archive", b, "--steps", "70"});
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("checkpoint at t = 0.5"), std::string::npos) << run.output;
  const archive::ArchiveReader ra(a), rb(b);
  ASSERT_EQ(rb.frames(), 41);  // steps 30 .. 70
  EXPECT_EQ(rb.steps().front(), 30);
  for (long i = 0; i < rb.frames(); ++i) {
    const archive::Frame fb = rb.frame(i), fa = ra.frame(fb.step);
    EXPECT_TRUE(fb.positions == fa.positions) << "step " << fb.step;
    EXPECT_TRUE(fb.activation_pa == fa.activation_pa) << "step " << fb.step;
    if (i > 0) {  // frame 0 is the restored state (no step report)
      EXPECT_EQ(fb.solver_iterations, fa.solver_iterations) << "step " << fb.step;
    }
  }
  // The last checkpoints (double precision) of both runs are the same state.
  const core::SimulatorCheckpoint ca = ra.read_checkpoint(ra.checkpoints().size() - 1);
  const core::SimulatorCheckpoint cb = rb.read_checkpoint(rb.checkpoints().size() - 1);
  EXPECT_EQ(ca.step_count, 70);
  EXPECT_EQ(cb.step_count, 70);
  EXPECT_TRUE(ca.x == cb.x);
  EXPECT_TRUE(ca.v == cb.v);

  // Errors name what is wrong.
  auto bad = run_process({kBin, "run", "--resume", a + "@-1"});
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.output.find("no checkpoint at or before t = -1"), std::string::npos) << bad.output;
  bad = run_process({kBin, "run", "--resume", a + "@soon"});
  EXPECT_NE(bad.output.find("'soon' is not a time"), std::string::npos) << bad.output;
  bad = run_process({kBin, "run", "--resume", kHeart});
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.output.find("not an HDF5 file"), std::string::npos) << bad.output;
  bad = run_process({kBin, "run", "--resume", a, "--archive", a});
  EXPECT_NE(bad.output.find("must not be the archive being resumed from"), std::string::npos) << bad.output;
  bad = run_process({kBin, "run", kHeart, "--flush-frames", "3"});
  EXPECT_NE(bad.output.find("need --archive"), std::string::npos) << bad.output;
  bad = run_process({kBin, "archive", "info", kHeart});
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.output.find("not an HDF5 file"), std::string::npos) << bad.output;
}

}  // namespace
}  // namespace fiberfem
