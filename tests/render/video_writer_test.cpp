// MP4 through the real ffmpeg, checked with ffprobe (frame count and size).

#include "clients/render/video_writer.hpp"
#include "process_support.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

namespace fiberfem::render {
namespace {

std::string probe(const std::string& path) {
  const auto r = testing::run_process({"ffprobe", "-v", "error", "-count_frames", "-select_streams", "v:0", "-show_entries",
                                       "stream=codec_name,width,height,nb_read_frames", "-of", "csv=p=0", path});
  std::string out = r.output;
  while (!out.empty() && (out.back() == '\n' || out.back() == '\r')) out.pop_back();
  return out;
}

TEST(VideoWriter, Mp4IsDecodableWithEveryFrame) {
  testing::TempDir dir;
  for (const std::string codec : {"libx264", "mpeg4"}) {
    VideoSettings s;
    s.path = dir.file(codec + ".mp4");
    s.width = 64, s.height = 48, s.fps = 25, s.codec = codec;
    VideoWriter w(s);
    for (int k = 0; k < 12; ++k) w.write(Image(64, 48, {static_cast<std::uint8_t>(20 * k), 100, 50, 255}));
    w.close();
    EXPECT_EQ(probe(s.path), (codec == "libx264" ? "h264" : "mpeg4") + std::string(",64,48,12"));
  }
}

TEST(VideoWriter, OddSizesArePaddedToEven) {
  testing::TempDir dir;
  VideoSettings s;
  s.path = dir.file("odd.mp4");
  s.width = 33, s.height = 21;
  VideoWriter w(s);
  for (int k = 0; k < 3; ++k) w.write(Image(33, 21));
  w.close();
  EXPECT_EQ(probe(s.path), "h264,34,22,3");
}

TEST(VideoWriter, ProblemsAreReportedNotCrashed) {
  testing::TempDir dir;
  VideoSettings s;
  s.path = dir.file("x.mp4");
  s.width = 32, s.height = 32;
  s.ffmpeg = "/nonexistent/ffmpeg";
  try {
    VideoWriter w(s);
    ADD_FAILURE() << "expected a missing ffmpeg to be reported";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("not found"), std::string::npos) << e.what();
  }
  s.ffmpeg = "ffmpeg";
  s.codec = "prores";
  testing::expect_invalid([&] { VideoWriter w(s); }, {"codec", "prores"});
  s.codec = "libx264";
  {
    VideoWriter w(s);
    testing::expect_invalid([&] { w.write(Image(16, 16)); }, {"16x16", "32x32"});
  }
  // An unwritable output: ffmpeg fails and its own message comes back.
  s.path = "/nonexistent-dir/x.mp4";
  EXPECT_THROW(
      {
        VideoWriter w(s);
        for (int k = 0; k < 200; ++k) w.write(Image(32, 32));
        w.close();
      },
      std::runtime_error);
}

}  // namespace
}  // namespace fiberfem::render
