// Images, PNG files, the colour map and the frame mailbox.

#include "clients/render/colormap.hpp"
#include "clients/render/field.hpp"
#include "clients/render/frame_mailbox.hpp"
#include "clients/render/image.hpp"
#include "clients/render/png_io.hpp"
#include "process_support.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <random>
#include <thread>

namespace fiberfem::render {
namespace {

TEST(Png, RoundTripThroughLibpngIsExactAtEveryLevel) {
  testing::TempDir dir;
  Image im(37, 23);
  std::mt19937 rng(7);
  for (auto& b : im.rgba) b = static_cast<std::uint8_t>(rng());
  for (int level : {0, 1, 6, 9}) {
    const std::string path = dir.file("im" + std::to_string(level) + ".png");
    write_png(path, im, level);
    const Image back = read_png(path);
    EXPECT_EQ(back.width, 37);
    EXPECT_EQ(back.height, 23);
    EXPECT_EQ(back.rgba, im.rgba) << "level " << level;
  }
  // PNG signature: an independent check that it is a PNG file.
  const std::string bytes = testing::read_file(dir.file("im1.png"));
  EXPECT_EQ(bytes.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
}

TEST(Png, BadPathsAndLevelsAreRefused) {
  testing::TempDir dir;
  const Image im(4, 4);
  EXPECT_THROW(write_png("/nonexistent-dir/x.png", im), std::runtime_error);
  testing::expect_invalid([&] { write_png(dir.file("x.png"), im, 10); }, {"level", "10"});
  testing::write_file(dir.file("not.png"), "hello");
  EXPECT_THROW(read_png(dir.file("not.png")), std::runtime_error);
  EXPECT_THROW(read_png(dir.file("missing.png")), std::runtime_error);
}

TEST(Image, DownscaleAveragesAndStripsLineUp) {
  Image checker(4, 2);
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 4; ++x) {
      const std::uint8_t v = (x + y) % 2 ? 200 : 0;
      std::uint8_t* p = checker.at(x, y);
      p[0] = p[1] = p[2] = v;
    }
  const Image half = downscale(checker, 2, 1);
  EXPECT_EQ(half.at(0, 0)[0], 100);
  EXPECT_EQ(half.at(1, 0)[0], 100);
  const Image third = downscale(Image(9, 3, {90, 30, 60, 255}), 3, 1);
  EXPECT_EQ(third.at(2, 0)[0], 90);
  const Image strip = hstack({Image(5, 3), Image(7, 4)}, 2);
  EXPECT_EQ(strip.width, 14);
  EXPECT_EQ(strip.height, 4);
  testing::expect_invalid([&] { downscale(checker, 8, 1); }, {"downscale"});
}

// matplotlib's viridis at 0, 1/4, 1/2, 3/4, 1: #440154 #3b528b #21918c #5ec962 #fde725.
TEST(Colormap, ViridisMatchesMatplotlib) {
  auto near = [](Rgba c, int r, int g, int b) { return std::abs(c.r - r) <= 6 && std::abs(c.g - g) <= 6 && std::abs(c.b - b) <= 6; };
  EXPECT_TRUE(near(viridis(0.0), 0x44, 0x01, 0x54));
  EXPECT_TRUE(near(viridis(0.25), 0x3b, 0x52, 0x8b));
  EXPECT_TRUE(near(viridis(0.5), 0x21, 0x91, 0x8c));
  EXPECT_TRUE(near(viridis(0.75), 0x5e, 0xc9, 0x62));
  EXPECT_TRUE(near(viridis(1.0), 0xfd, 0xe7, 0x25));
  EXPECT_TRUE(near(viridis(-3), 0x44, 0x01, 0x54));  // clamped
  for (int i = 1; i <= 100; ++i) {  // perceptual order: brightness rises monotonically
    const Rgba a = viridis((i - 1) / 100.0), b = viridis(i / 100.0);
    EXPECT_LE(0.3 * a.r + 0.59 * a.g + 0.11 * a.b, 0.3 * b.r + 0.59 * b.g + 0.11 * b.b + 1.0) << i;
  }
  EXPECT_TRUE(near(viridis(NAN), 128, 128, 128));
  testing::expect_invalid([] { parse_field("temperature"); }, {"temperature", "activation"});
  EXPECT_EQ(parse_field("fiber_strain"), Field::fiber_strain);
}

TEST(Field, ActivationIsTensionOverTheRegionPeak) {
  core::Contraction c;
  c.region_peak_pa = {10e3, 0.0};
  const auto a = activation_from_tension(c, {0, 0, 1}, {5e3, 10e3, 3e3});
  EXPECT_DOUBLE_EQ(a[0], 0.5);
  EXPECT_DOUBLE_EQ(a[1], 1.0);
  EXPECT_DOUBLE_EQ(a[2], 0.0);
  EXPECT_EQ(activation_from_tension(c, {0, 1}, {}), std::vector<double>(2, 0.0));
  testing::expect_invalid([&] { activation_from_tension(c, {0, 1}, {1.0}); }, {"tensions"});
}

TEST(FrameMailbox, KeepsTheNewestFrameAndCountsTheDropped) {
  FrameMailbox box;
  EXPECT_FALSE(box.take());
  for (long s = 1; s <= 3; ++s) {
    FrameData f;
    f.sequence = s;
    box.publish(std::move(f));
  }
  const auto got = box.take();
  ASSERT_TRUE(got);
  EXPECT_EQ(got->sequence, 3);
  EXPECT_EQ(box.dropped(), 2);
  EXPECT_FALSE(box.take());
}

// A producer that never waits against a slow consumer: every frame is either taken or
// counted as dropped, and the consumer ends with the newest one.
TEST(FrameMailbox, SlowConsumerSeesTheNewestFrameAndNothingIsLost) {
  FrameMailbox box;
  constexpr long kFrames = 2000;
  std::atomic<bool> done{false};
  long taken = 0, last = 0;
  std::thread consumer([&] {
    for (;;) {
      const bool finished = done.load();
      if (auto f = box.take()) {
        EXPECT_GT(f->sequence, last);  // newer every time
        last = f->sequence, ++taken;
        std::this_thread::sleep_for(std::chrono::microseconds(200));  // "rendering"
      } else if (finished) {
        break;
      }
    }
  });
  for (long s = 1; s <= kFrames; ++s) {
    FrameData f;
    f.sequence = s;
    f.x = core::Positions::Zero(3, 8);
    box.publish(std::move(f));
  }
  done = true;
  consumer.join();
  EXPECT_EQ(last, kFrames);
  EXPECT_EQ(taken + box.dropped(), kFrames);
  EXPECT_GT(box.dropped(), 0);
}

}  // namespace
}  // namespace fiberfem::render
