#include "clients/render/camera.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace fiberfem::render {
namespace {

constexpr double kPi = 3.14159265358979323846;

bool finite(const core::Vec3& v) { return v.allFinite(); }

struct Direction {
  core::Vec3 from;  // unit vector from the target to the eye
  core::Vec3 up;
};

Direction direction_of(CameraPreset p) {
  switch (p) {
    case CameraPreset::front: return {{0, -1, 0}, {0, 0, 1}};
    case CameraPreset::back: return {{0, 1, 0}, {0, 0, 1}};
    case CameraPreset::left: return {{-1, 0, 0}, {0, 0, 1}};
    case CameraPreset::right: return {{1, 0, 0}, {0, 0, 1}};
    case CameraPreset::top: return {{0, 0, 1}, {0, 1, 0}};
    case CameraPreset::iso: return {core::Vec3(1, -1, 0.8).normalized(), {0, 0, 1}};
  }
  return {{0, -1, 0}, {0, 0, 1}};
}

}  // namespace

void Camera::validate() const {
  if (!finite(eye)) throw std::invalid_argument("camera.eye: not finite");
  if (!finite(target)) throw std::invalid_argument("camera.target: not finite");
  if (!finite(up) || up.norm() == 0) throw std::invalid_argument("camera.up: must be a finite non-zero vector");
  const core::Vec3 d = target - eye;
  if (!(d.norm() > 0)) throw std::invalid_argument("camera.eye: equals camera.target");
  if (d.normalized().cross(up.normalized()).norm() < 1e-6)
    throw std::invalid_argument("camera.up: parallel to the viewing direction (target - eye)");
  if (!(fov_deg > 0 && fov_deg < 170)) throw std::invalid_argument("camera.fov_deg: " + std::to_string(fov_deg) + " is outside (0, 170)");
  if (orthographic && !(ortho_height_m > 0 && std::isfinite(ortho_height_m)))
    throw std::invalid_argument("camera.ortho_height_m: must be positive");
}

// gluLookAt: rows of the rotation are the camera's right, up and backward axes.
Eigen::Matrix4d Camera::view() const {
  const core::Vec3 f = (target - eye).normalized();
  const core::Vec3 s = f.cross(up).normalized();
  const core::Vec3 u = s.cross(f);
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.block<1, 3>(0, 0) = s.transpose();
  m.block<1, 3>(1, 0) = u.transpose();
  m.block<1, 3>(2, 0) = -f.transpose();
  m(0, 3) = -s.dot(eye), m(1, 3) = -u.dot(eye), m(2, 3) = f.dot(eye);
  return m;
}

// gluPerspective / glOrtho.
Eigen::Matrix4d Camera::projection(double aspect, double n, double f) const {
  Eigen::Matrix4d p = Eigen::Matrix4d::Zero();
  if (orthographic) {
    const double t = 0.5 * ortho_height_m, r = t * aspect;
    p(0, 0) = 1 / r, p(1, 1) = 1 / t, p(2, 2) = -2 / (f - n), p(2, 3) = -(f + n) / (f - n), p(3, 3) = 1;
    return p;
  }
  const double c = 1 / std::tan(0.5 * fov_deg * kPi / 180);
  p(0, 0) = c / aspect, p(1, 1) = c, p(2, 2) = (f + n) / (n - f), p(2, 3) = 2 * f * n / (n - f), p(3, 2) = -1;
  return p;
}

const char* to_string(CameraPreset p) {
  switch (p) {
    case CameraPreset::front: return "front";
    case CameraPreset::back: return "back";
    case CameraPreset::left: return "left";
    case CameraPreset::right: return "right";
    case CameraPreset::top: return "top";
    case CameraPreset::iso: return "iso";
  }
  return "?";
}

CameraPreset parse_camera_preset(const std::string& text) {
  for (CameraPreset p : {CameraPreset::front, CameraPreset::back, CameraPreset::left, CameraPreset::right, CameraPreset::top,
                         CameraPreset::iso})
    if (text == to_string(p)) return p;
  throw std::invalid_argument("unknown camera preset '" + text + "' (use front, back, left, right, top or iso)");
}

// A corner c (relative to the centre) with components (r, u, b) along the camera's right,
// up and backward axes projects inside the image when |r| / (d - b) <= tan(fov_x / 2) and
// |u| / (d - b) <= tan(fov_y / 2), with d the eye's distance from the centre: so
// d >= b + |r| / tan(fov_x / 2) and d >= b + |u| / tan(fov_y / 2) for every corner.
Camera frame_points(CameraPreset preset, const core::Positions& points, double aspect, double fov_deg, double margin) {
  if (points.cols() < 1 || !points.allFinite()) throw std::invalid_argument("frame: no points, or points not finite");
  const core::Vec3 lo = points.rowwise().minCoeff(), hi = points.rowwise().maxCoeff();
  if ((hi - lo).norm() == 0) throw std::invalid_argument("frame: the points have zero extent");
  if (!(aspect > 0 && std::isfinite(aspect))) throw std::invalid_argument("frame: aspect must be positive");
  if (!(fov_deg > 0 && fov_deg < 170)) throw std::invalid_argument("frame: fov_deg " + std::to_string(fov_deg) + " is outside (0, 170)");
  const Direction dir = direction_of(preset);
  Camera cam;
  cam.fov_deg = fov_deg;
  cam.up = dir.up;
  cam.target = 0.5 * (lo + hi);
  const core::Vec3 back = dir.from, right = dir.up.cross(back).normalized(), up = back.cross(right);
  const double ty = std::tan(0.5 * fov_deg * kPi / 180), tx = ty * aspect;
  double d = 0;
  // Distance for the current target; then the target moves so that the projected extent
  // is centred in the image (a perspective view of a box is not symmetric about the
  // projection of its centre), and the distance is found again.
  auto fit_distance = [&] {
    d = 0;
    for (Eigen::Index k = 0; k < points.cols(); ++k) {
      const core::Vec3 rel = (points.col(k) - cam.target) * (1 + margin);
      d = std::max({d, rel.dot(back) + std::abs(rel.dot(right)) / tx, rel.dot(back) + std::abs(rel.dot(up)) / ty});
    }
  };
  fit_distance();
  for (int iteration = 0; iteration < 3 && d > 0; ++iteration) {
    double x_lo = HUGE_VAL, x_hi = -HUGE_VAL, y_lo = HUGE_VAL, y_hi = -HUGE_VAL;
    bool in_front = true;
    for (Eigen::Index k = 0; k < points.cols() && in_front; ++k) {
      const core::Vec3 rel = points.col(k) - cam.target;
      const double depth = d - rel.dot(back);
      in_front = depth > 0;
      x_lo = std::min(x_lo, rel.dot(right) / depth), x_hi = std::max(x_hi, rel.dot(right) / depth);
      y_lo = std::min(y_lo, rel.dot(up) / depth), y_hi = std::max(y_hi, rel.dot(up) / depth);
    }
    if (!in_front) break;
    cam.target += 0.5 * d * ((x_lo + x_hi) * right + (y_lo + y_hi) * up);
    fit_distance();
  }
  cam.eye = cam.target + d * back;
  cam.ortho_height_m = 2 * d * ty;
  return cam;
}

Camera frame_box(CameraPreset preset, const core::Vec3& lo, const core::Vec3& hi, double aspect, double fov_deg, double margin) {
  if (!lo.allFinite() || !hi.allFinite() || (hi - lo).minCoeff() < 0 || (hi - lo).norm() == 0)
    throw std::invalid_argument("frame_box: empty or invalid bounding box");
  core::Positions corners(3, 8);
  for (int k = 0; k < 8; ++k) corners.col(k) = core::Vec3((k & 1 ? hi : lo).x(), (k & 2 ? hi : lo).y(), (k & 4 ? hi : lo).z());
  return frame_points(preset, corners, aspect, fov_deg, margin);
}

}  // namespace fiberfem::render
