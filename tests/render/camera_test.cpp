// Camera matrices against their definitions, presets, framing and bad keys.

#include "clients/render/camera.hpp"
#include "render/render_test_support.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

namespace fiberfem::render {
namespace {

Eigen::Vector3d clip_to_ndc(const Eigen::Vector4d& c) { return c.head<3>() / c.w(); }

TEST(Camera, ViewAndProjectionAgreeWithTheIndependentProjection) {
  Camera c;
  c.eye = {1, -3, 2}, c.target = {0.2, 0.1, -0.3}, c.up = {0, 0, 1}, c.fov_deg = 35;
  c.validate();
  const int W = 320, H = 200;
  const Eigen::Matrix4d V = c.view(), P = c.projection(double(W) / H, 0.1, 100);
  EXPECT_LT((V * c.eye.homogeneous()).head<3>().norm(), 1e-12);  // the eye is the origin
  const Eigen::Vector4d t = V * c.target.homogeneous();
  EXPECT_NEAR(t.x(), 0, 1e-12);
  EXPECT_NEAR(t.y(), 0, 1e-12);
  EXPECT_LT(t.z(), 0);  // looking down -z
  for (const core::Vec3& p : {core::Vec3(0.5, 0.4, 0.1), core::Vec3(-0.3, 0.9, -0.2), core::Vec3(0.0, 0.0, 0.5)}) {
    const Eigen::Vector3d ndc = clip_to_ndc(P * V * p.homogeneous());
    const Eigen::Vector2d px = testing::project(c, p, W, H);
    EXPECT_NEAR(0.5 * (ndc.x() + 1) * W, px.x(), 1e-9);
    EXPECT_NEAR(0.5 * (1 - ndc.y()) * H, px.y(), 1e-9);
    EXPECT_GT(ndc.z(), -1);
    EXPECT_LT(ndc.z(), 1);
  }
}

TEST(Camera, FramingFitsEveryCornerWithItsMargin) {
  const core::Vec3 lo(0, 0, 0), hi(0.1, 0.02, 0.05);
  for (CameraPreset p : {CameraPreset::front, CameraPreset::back, CameraPreset::left, CameraPreset::right, CameraPreset::top,
                         CameraPreset::iso}) {
    const Camera c = frame_box(p, lo, hi, 16.0 / 9.0, 30, 0.1);
    double extent = 0;
    for (int k = 0; k < 8; ++k) {
      const core::Vec3 corner((k & 1 ? hi : lo).x(), (k & 2 ? hi : lo).y(), (k & 4 ? hi : lo).z());
      const Eigen::Vector2d px = testing::project(c, corner, 1600, 900);
      extent = std::max({extent, std::abs(px.x() - 800) / 800, std::abs(px.y() - 450) / 450});
    }
    EXPECT_LT(extent, 1.0) << to_string(p);
    EXPECT_GT(extent, 0.8) << to_string(p) << ": framing too loose";
    EXPECT_EQ(parse_camera_preset(to_string(p)), p);
  }
}

TEST(Camera, BadKeysAreRefusedByName) {
  Camera c;
  c.eye = c.target = {1, 2, 3};
  testing::expect_invalid([&] { c.validate(); }, {"camera.eye", "equals"});
  c = Camera{};
  c.up = {0, 1, 0};  // parallel to the default view direction (+y)
  testing::expect_invalid([&] { c.validate(); }, {"camera.up", "parallel"});
  c = Camera{};
  c.fov_deg = 0;
  testing::expect_invalid([&] { c.validate(); }, {"fov_deg"});
  c = Camera{};
  c.eye.x() = NAN;
  testing::expect_invalid([&] { c.validate(); }, {"camera.eye"});
  testing::expect_invalid([] { parse_camera_preset("sideways"); }, {"sideways", "front"});
  testing::expect_invalid([] { frame_box(CameraPreset::iso, {0, 0, 0}, {0, 0, 0}, 1.0); }, {"bounding box"});
}

}  // namespace
}  // namespace fiberfem::render
