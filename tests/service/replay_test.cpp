// Recording a served run and replaying it (service/replay.hpp) with real processes on
// loopback: the replay republishes the archive's frames on the live topics, seekable and
// steppable, and clients see a live-looking run with the replay flag.

#include "clients/ctl/client.hpp"
#include "process_support.hpp"
#include "service/archive/archive.hpp"
#if defined(FIBERFEM_HAVE_RENDER)
#include "clients/render/png_io.hpp"
#endif

#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <thread>

namespace fiberfem::testing {
namespace {

using namespace std::chrono_literals;
using clients::Client;

class Replay : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { setenv("CYCLONEDDS_URI", FIBERFEM_DDS_URI, 1); }
  static std::string unique(const std::string& name) { return name + "-" + std::to_string(getpid()); }
  TempDir dir_;
};

TEST_F(Replay, ServedRunIsRecordedAndReplayedFrameForFrame) {
  // 1. Serve and record 1.5 s of the cantilever, with one command on the way.
  const std::string run = unique("rec");
  const std::string h5 = dir_.file("run.h5");
  {
    // Started paused, so the commands land before any step however slow the machine.
    BackgroundProcess service({FIBERFEM_BIN, "serve", "--builtin", "cantilever", "--run-id", run, "--until", "1.5", "--archive", h5,
                               "--flush-frames", "5", "--paused"},
                              dir_.file("serve.log"));
    Client client;
    ASSERT_EQ(client.resolve_run(run, 20s), run) << service.output();
    ASSERT_TRUE(client.send(run, "set_gravity", R"({"gravity": [0, 0, -20]})").accepted);
    ASSERT_FALSE(client.send(run, "set_time_step", R"({"dt": -1})").accepted);
    ASSERT_TRUE(client.send(run, "resume", "{}").accepted);
    ASSERT_EQ(service.wait(60), 0) << service.output();
  }
  const archive::ArchiveReader archive(h5);
  ASSERT_EQ(archive.frames(), 91);  // the rest state and 90 steps
  const auto commands = archive.commands();
  ASSERT_EQ(commands.size(), 3u);
  EXPECT_EQ(commands[0].kind, "set_gravity");
  EXPECT_TRUE(commands[0].accepted);
  EXPECT_FALSE(commands[1].accepted);
  EXPECT_NE(commands[1].reason.find("'dt'"), std::string::npos);

  // 2. Replay it, paused: frame by frame, seek, then play to the end.
  const std::string rrun = unique("replay");
  BackgroundProcess replay({FIBERFEM_BIN, "replay", h5, "--run-id", rrun, "--paused", "--rate", "2"}, dir_.file("replay.log"));
  Client client;
  ASSERT_EQ(client.resolve_run(rrun, 20s), rrun) << replay.output();
  const auto st = client.status(rrun, 5s);
  ASSERT_TRUE(st);
  EXPECT_TRUE(st->replay);
  EXPECT_EQ(st->mode, "replay");
  const auto topo = client.topology(rrun, 10s);
  ASSERT_TRUE(topo);
  EXPECT_TRUE(topo->replay);
  ASSERT_EQ(topo->num_nodes, static_cast<unsigned>(archive.header().rest_positions.cols()));
  EXPECT_EQ(topo->region_names, std::vector<std::string>{"tissue"});

  auto expect_frame = [&](const clients::State& s, long i) {
    const archive::Frame f = archive.frame(i);
    EXPECT_EQ(static_cast<long>(s.frame), f.step);
    EXPECT_DOUBLE_EQ(s.time_s, f.time_s);
    ASSERT_EQ(s.positions.size(), static_cast<size_t>(f.positions.size()));
    for (Eigen::Index k = 0; k < f.positions.size(); ++k) ASSERT_EQ(s.positions[static_cast<size_t>(k)], static_cast<float>(f.positions.data()[k]));
  };
  const auto s0 = client.next_state(rrun, 5s);
  ASSERT_TRUE(s0);
  expect_frame(*s0, 0);
  ASSERT_TRUE(client.send(rrun, "step", R"({"count": 3})").accepted);
  std::optional<clients::State> s3;
  for (int i = 0; i < 10 && (!s3 || s3->frame < 3); ++i) s3 = client.next_state(rrun, 5s, s3 ? static_cast<long>(s3->frame) : 0);
  ASSERT_TRUE(s3);
  expect_frame(*s3, 3);
  const clients::Ack seek = client.send(rrun, "seek", R"({"time": 1.01})");
  ASSERT_TRUE(seek.accepted) << seek.reason;
  const auto s60 = client.next_state(rrun, 5s, 3);
  ASSERT_TRUE(s60);
  expect_frame(*s60, 60);  // the last frame at or before 1.01 s: step 60 (t = 60 x 0.0166667 s)
  EXPECT_FALSE(client.send(rrun, "seek", R"({"frame": 5000})").accepted);
  EXPECT_FALSE(client.send(rrun, "set_gravity", R"({"gravity": [0, 0, 0]})").accepted);  // not a replay command

  // Playing at x2: frames arrive in order up to the last one.
  ASSERT_TRUE(client.send(rrun, "resume", "{}").accepted);
  long last = 60;
  for (int i = 0; i < 200 && last < 90; ++i) {
    const auto s = client.next_state(rrun, 5s, last);
    ASSERT_TRUE(s);
    EXPECT_GT(static_cast<long>(s->frame), last);
    last = static_cast<long>(s->frame);
  }
  EXPECT_EQ(last, 90);
  ASSERT_TRUE(client.send(rrun, "shutdown", "{}").accepted);
  EXPECT_EQ(replay.wait(20), 0) << replay.output();
}

TEST_F(Replay, RecordingStartsAndStopsByCommandAndARestoreStartsTheNextFile) {
  const std::string run = unique("startstop");
  BackgroundProcess service({FIBERFEM_BIN, "serve", "--builtin", "cantilever", "--run-id", run}, dir_.file("serve.log"));
  Client client;
  ASSERT_EQ(client.resolve_run(run, 20s), run) << service.output();
  const std::string h5 = dir_.file("live.h5");
  EXPECT_FALSE(client.send(run, "stop_recording", "{}").accepted);
  const clients::Ack bad = client.send(run, "start_recording", R"({"path": ")" + h5 + R"(", "flush_frames": 0})");
  EXPECT_FALSE(bad.accepted);
  EXPECT_NE(bad.reason.find("flush_frames"), std::string::npos) << bad.reason;
  ASSERT_TRUE(client.send(run, "checkpoint", "{}").accepted);
  ASSERT_TRUE(client.send(run, "start_recording", R"({"path": ")" + h5 + R"("})").accepted);
  // Wait (however loaded the machine) until the status shows frames recorded.
  auto wait_recorded = [&](unsigned long n) {
    for (int i = 0; i < 200; ++i) {
      const auto st = client.status(run, 5s);
      if (st && st->recorded_frames >= n) return;
    }
    FAIL() << "the status never showed " << n << " recorded frames";
  };
  wait_recorded(10);
  // The sidecar follows a live recording (ParaView can open what is flushed so far).
  const std::string sidecar = read_file(dir_.file("live.xdmf"));
  EXPECT_NE(sidecar.find("<Xdmf"), std::string::npos);
  EXPECT_NE(sidecar.find("Name=\"frame 0\""), std::string::npos) << sidecar.substr(0, 500);
  const clients::Ack restored = client.send(run, "restore", "{}");
  ASSERT_TRUE(restored.accepted) << restored.reason;
  EXPECT_NE(restored.reason.find("live-2.h5"), std::string::npos) << restored.reason;
  wait_recorded(5);
  const clients::Ack stopped = client.send(run, "stop_recording", "{}");
  ASSERT_TRUE(stopped.accepted) << stopped.reason;
  const archive::ArchiveReader first(h5), second(dir_.file("live-2.h5"));
  EXPECT_GE(first.frames(), 10);
  EXPECT_GE(second.frames(), 5);
  const auto t1 = first.times(), t2 = second.times();
  for (size_t i = 1; i < t1.size(); ++i) EXPECT_GT(t1[i], t1[i - 1]);
  for (size_t i = 1; i < t2.size(); ++i) EXPECT_GT(t2[i], t2[i - 1]);
  EXPECT_LT(t2.front(), t1.back());  // the second file starts back at the checkpoint
}

// A served run resumed from its archive's checkpoint (with a command applied before it)
// continues bit-for-bit like the uninterrupted run.
TEST_F(Replay, ServeResumesFromACheckpointBitForBit) {
  const std::string run = unique("whole");
  const std::string whole = dir_.file("whole.h5"), tail = dir_.file("tail.h5");
  {
    BackgroundProcess service({FIBERFEM_BIN, "serve", "--builtin", "cantilever", "--run-id", run, "--fast", "--paused", "--until", "2",
                               "--archive", whole},
                              dir_.file("whole.log"));
    Client client;
    ASSERT_EQ(client.resolve_run(run, 20s), run) << service.output();
    ASSERT_TRUE(client.send(run, "set_gravity", R"({"gravity": [0, 0, -20]})").accepted);
    ASSERT_TRUE(client.send(run, "apply_force", R"({"target": {"node_set": "xmax"}, "force": [0, 0.001, 0]})").accepted);
    ASSERT_TRUE(client.send(run, "resume", "{}").accepted);
    ASSERT_EQ(service.wait(60), 0) << service.output();
  }
  {
    const std::string run2 = unique("tail");
    BackgroundProcess service({FIBERFEM_BIN, "serve", "--builtin", "cantilever", "--run-id", run2, "--fast", "--until", "2", "--resume",
                               whole + "@1.2", "--archive", tail},
                              dir_.file("tail.log"));
    ASSERT_EQ(service.wait(60), 0) << service.output();
    EXPECT_NE(service.output().find("resumed from"), std::string::npos) << service.output();
  }
  const archive::ArchiveReader a(whole), b(tail);
  ASSERT_EQ(a.steps().back(), 120);
  ASSERT_EQ(b.steps().back(), 120);
  EXPECT_EQ(b.steps().front(), 60);  // the checkpoint at 1 s
  const archive::Frame fa = a.frame(a.frames() - 1), fb = b.frame(b.frames() - 1);
  EXPECT_EQ((fa.positions - fb.positions).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_GT((fa.positions - a.header().rest_positions).cwiseAbs().maxCoeff(), 1e-3);  // it moved
}

}  // namespace
}  // namespace fiberfem::testing

#if defined(FIBERFEM_HAVE_RENDER)
namespace fiberfem::testing {
namespace {

// Share of pixels that differ by more than `tol` in any channel.
double differing(const render::Image& a, const render::Image& b, int tol) {
  if (a.width != b.width || a.height != b.height) return 1.0;
  long n = 0;
  for (size_t i = 0; i < a.rgba.size(); i += 4)
    for (int c = 0; c < 3; ++c)
      if (std::abs(int(a.rgba[i + c]) - int(b.rgba[i + c])) > tol) {
        ++n;
        break;
      }
  return static_cast<double>(n) / (a.rgba.size() / 4.0);
}

// The renderer drawing an archive shows what it draws when it simulates the scene itself
// (two paths: archived float32 positions against the simulator's own).
TEST_F(Replay, RenderingAnArchiveMatchesRenderingTheSceneItself) {
  const std::string scene = std::string(FIBERFEM_SOURCE_DIR) + "/configs/scenes/demo-cantilever.yaml";
  const std::string h5 = dir_.file("beam.h5");
  ASSERT_EQ(run_process({FIBERFEM_BIN, "run", scene, "--steps", "30", "--archive", h5}).exit_code, 0);
  const ProcessResult from_archive = run_process({FIBERFEM_BIN, "render", h5, "--out", dir_.file("a"), "--last", "--width", "320",
                                                  "--height", "180", "--no-overlay"});
  ASSERT_EQ(from_archive.exit_code, 0) << from_archive.output;
  const ProcessResult from_scene = run_process({FIBERFEM_BIN, "render", scene, "--steps", "30", "--out", dir_.file("s"), "--last",
                                                "--width", "320", "--height", "180", "--no-overlay"});
  ASSERT_EQ(from_scene.exit_code, 0) << from_scene.output;
  const render::Image a = render::read_png(dir_.file("a/frame-00000.png"));
  const render::Image s = render::read_png(dir_.file("s/frame-00000.png"));
  EXPECT_LT(differing(a, s, 24), 0.005);
  // ... and not the rest shape: the first archived frame differs visibly.
  ASSERT_EQ(run_process({FIBERFEM_BIN, "render", h5, "--out", dir_.file("r"), "--at", "0", "--width", "320", "--height", "180",
                         "--no-overlay"}).exit_code, 0);
  EXPECT_GT(differing(render::read_png(dir_.file("r/frame-00000.png")), a, 24), 0.01);
}

// Rendering live from the bus: frames of a running service, its newest state each time.
TEST_F(Replay, RenderingLiveFromTheBusDrawsTheRunningService) {
  // The service starts paused at rest; the renderer joins; then the beam is released.
  const std::string run = unique("live");
  BackgroundProcess service({FIBERFEM_BIN, "serve", "--builtin", "cantilever", "--run-id", run, "--paused"}, dir_.file("serve.log"));
  Client client;
  ASSERT_EQ(client.resolve_run(run, 20s), run) << service.output();
  BackgroundProcess live({FIBERFEM_BIN, "render", "--live", "--run", run, "--frames", "6", "--out", dir_.file("live"), "--width", "320",
                          "--height", "180", "--no-overlay"},
                         dir_.file("render.log"));
  for (int i = 0; i < 300 && !std::filesystem::exists(dir_.file("live/frame-00000.png")); ++i) std::this_thread::sleep_for(50ms);
  ASSERT_TRUE(std::filesystem::exists(dir_.file("live/frame-00000.png"))) << live.output();
  ASSERT_TRUE(client.send(run, "resume", "{}").accepted);
  ASSERT_EQ(live.wait(120), 0) << live.output();
  EXPECT_NE(live.output().find("skipped while drawing"), std::string::npos) << live.output();
  for (int i = 0; i < 6; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "/frame-%05d.png", i);
    EXPECT_TRUE(std::filesystem::exists(dir_.file("live") + name)) << name;
  }
  // Frame 0 is the rest shape; by frame 5 the released beam has fallen: they differ.
  EXPECT_GT(differing(render::read_png(dir_.file("live/frame-00000.png")), render::read_png(dir_.file("live/frame-00005.png")), 24), 0.002);
  EXPECT_TRUE(service.running());
}

}  // namespace
}  // namespace fiberfem::testing
#endif
