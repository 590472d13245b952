// `fiberfem render` as users run it (the real binary): PNG frames, an MP4, a strip, and
// bad input refused by name with exit code 1.

#include "clients/render/png_io.hpp"
#include "process_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

namespace fiberfem::testing {
namespace {

const std::string kBin = FIBERFEM_BIN;
const std::string kScene = std::string(FIBERFEM_SOURCE_DIR) + "/configs/scenes/box-gravity.yaml";

TEST(RenderCli, WritesFramesVideoAndStrip) {
  TempDir dir;
  const auto r = run_process({kBin, "render", kScene, "--out", dir.file("frames"), "--steps", "6", "--every", "2", "--width", "64",
                              "--height", "48", "--mp4", dir.file("run.mp4"), "--strip", dir.file("strip.png"), "--strip-panels",
                              "3", "--strip-width", "32", "--camera", "front"});
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (int k = 0; k < 4; ++k) {  // the initial state and steps 2, 4, 6
    char name[32];
    std::snprintf(name, sizeof name, "/frame-%05d.png", k);
    const render::Image im = render::read_png(dir.file("frames") + name);
    EXPECT_EQ(im.width, 64);
    EXPECT_EQ(im.height, 48);
  }
  EXPECT_FALSE(std::filesystem::exists(dir.file("frames") + "/frame-00004.png"));
  const auto probe = run_process({"ffprobe", "-v", "error", "-count_frames", "-select_streams", "v:0", "-show_entries",
                                  "stream=width,height,nb_read_frames", "-of", "csv=p=0", dir.file("run.mp4")});
  EXPECT_EQ(probe.output.substr(0, 8), "64,48,4\n") << probe.output;
  const render::Image strip = render::read_png(dir.file("strip.png"));
  EXPECT_EQ(strip.width, 3 * 32 + 2 * 4);
  EXPECT_EQ(strip.height, 24);
  EXPECT_NE(r.output.find("4 frames"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("run.mp4"), std::string::npos) << r.output;
}

int count_frames(const std::string& dir) {
  int n = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) n += e.path().extension() == ".png";
  return n;
}

// --at picks steps by time, --last only the end; a static scene draws rest and equilibrium.
TEST(RenderCli, FrameSelectionAndStaticScenes) {
  TempDir dir;
  const std::vector<std::string> small = {"--width", "48", "--height", "32", "--no-overlay"};
  auto run = [&](std::vector<std::string> args) {
    args.insert(args.begin(), kBin);
    args.insert(args.end(), small.begin(), small.end());
    const auto r = run_process(args);
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return r.output;
  };
  run({"render", kScene, "--out", dir.file("at"), "--at", "0.05", "0.1"});
  EXPECT_EQ(count_frames(dir.file("at")), 2);
  EXPECT_NE(run({"render", kScene, "--out", dir.file("last"), "--steps", "3", "--last"}).find("1 frames"), std::string::npos);
  EXPECT_EQ(count_frames(dir.file("last")), 1);
  const std::string stat = std::string(FIBERFEM_SOURCE_DIR) + "/configs/scenes/cantilever-along.yaml";
  run({"render", stat, "--out", dir.file("static")});
  ASSERT_EQ(count_frames(dir.file("static")), 2);
  // The equilibrium sags under its load: the two frames differ.
  EXPECT_NE(render::read_png(dir.file("static") + "/frame-00000.png").rgba,
            render::read_png(dir.file("static") + "/frame-00001.png").rgba);
}

TEST(RenderCli, BadInputIsRefusedByName) {
  TempDir dir;
  const std::vector<std::string> base = {kBin, "render", kScene, "--steps", "1"};
  auto run = [&](std::vector<std::string> extra, const std::string& expected) {
    std::vector<std::string> args = base;
    args.insert(args.end(), extra.begin(), extra.end());
    for (const char* key : {"--width", "--height"})
      if (std::find(extra.begin(), extra.end(), key) == extra.end()) args.insert(args.end(), {key, "32"});
    const auto r = run_process(args);
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find(expected), std::string::npos) << "expected '" << expected << "' in: " << r.output;
  };
  run({"--out", dir.file("a"), "--field", "temperature"}, "unknown field 'temperature'");
  run({"--out", dir.file("a"), "--field", "activation"}, "has no contraction");
  run({"--out", dir.file("a"), "--width", "0"}, "width: 0 px");
  run({"--out", dir.file("a"), "--height", "90000"}, "height: 90000 px");
  run({"--out", dir.file("a"), "--camera", "sideways"}, "unknown camera preset 'sideways'");
  run({"--out", dir.file("a"), "--eye", "0.005", "0.005", "0.025", "--target", "0.005", "0.005", "0.025"}, "camera.eye: equals");
  run({"--out", dir.file("a"), "--up", "0", "0", "0"}, "camera.up");
  run({"--out", "/proc/fiberfem-cannot-write"}, "--out /proc/fiberfem-cannot-write");
  run({"--out", dir.file("a"), "--range", "1", "0"}, "range");
  run({"--out", dir.file("a"), "--mp4", "/nonexistent-dir/x.mp4"}, "cannot write /nonexistent-dir/x.mp4");
  run({"--no-png"}, "--no-png leaves nothing");
  run({"--out", dir.file("a"), "--at", "5"}, "--at 5.000000 s is after the end of the run");
  run({"--out", dir.file("a"), "--png-level", "12"}, "--png-level 12");
  run({"--out", dir.file("a"), "--strip", dir.file("s.png"), "--set", "contraction={peak_tension: 1000}"}, "shorter than one beat");
  // ffmpeg missing from PATH
  std::vector<std::string> no_path = {"/usr/bin/env", "PATH=/nonexistent"};
  no_path.insert(no_path.end(), base.begin(), base.end());
  no_path.insert(no_path.end(), {"--width", "32", "--height", "32"});
  for (const char* a : {"--out", "", "--mp4", ""}) no_path.emplace_back(a);
  no_path[no_path.size() - 3] = dir.file("b");
  no_path[no_path.size() - 1] = dir.file("b.mp4");
  const auto r = run_process(no_path);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("'ffmpeg' not found on PATH"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace fiberfem::testing
