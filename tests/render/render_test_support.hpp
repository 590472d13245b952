#pragma once
// Helpers of the renderer tests: pixel counting against the background, and an
// independent pinhole projection (written out here, not taken from camera.cpp).

#include "clients/render/camera.hpp"
#include "clients/render/image.hpp"

#include <cmath>

namespace fiberfem::testing {

inline bool is_background(const render::Image& im, int x, int y, render::Rgba bg = {255, 255, 255, 255}) {
  const std::uint8_t* p = im.at(x, y);
  return p[0] == bg.r && p[1] == bg.g && p[2] == bg.b;
}

inline long count_foreground(const render::Image& im) {
  long n = 0;
  for (int y = 0; y < im.height; ++y)
    for (int x = 0; x < im.width; ++x) n += !is_background(im, x, y);
  return n;
}

/// Pixel (column, row; row 0 at the top, pixel centres at +0.5) of world point `p` seen by
/// a perspective camera: the point's offset from the eye along the camera's right, up and
/// forward axes, divided by depth and tan(fov / 2).
inline Eigen::Vector2d project(const render::Camera& c, const core::Vec3& p, int width, int height) {
  const core::Vec3 f = (c.target - c.eye).normalized(), s = f.cross(c.up).normalized(), u = s.cross(f);
  const core::Vec3 d = p - c.eye;
  const double t = std::tan(0.5 * c.fov_deg * M_PI / 180), aspect = static_cast<double>(width) / height;
  const double nx = d.dot(s) / (d.dot(f) * t * aspect), ny = d.dot(u) / (d.dot(f) * t);
  return {0.5 * (nx + 1) * width, 0.5 * (1 - ny) * height};
}

}  // namespace fiberfem::testing
