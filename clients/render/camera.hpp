#pragma once
/// @file The camera: where it stands, what it looks at, its field of view; presets that
/// frame a bounding box from six directions.

#include "core/types.hpp"

#include <string>

namespace fiberfem::render {

/// A perspective (or orthographic) camera. Scene units are metres; the scene's +z is the
/// presets' "up" (the heart's long axis, the box scenes' vertical).
struct Camera {
  core::Vec3 eye = core::Vec3(0, -1, 0);     ///< Eye position, m.
  core::Vec3 target = core::Vec3::Zero();    ///< Point looked at (image centre), m.
  core::Vec3 up = core::Vec3::UnitZ();       ///< Up direction (not parallel to target - eye).
  double fov_deg = 30.0;                     ///< Vertical field of view, degrees, in (0, 170). Default 30.
  /// Orthographic projection instead of perspective; the visible height is then
  /// `ortho_height_m` and fov_deg is unused. Default false.
  bool orthographic = false;
  double ortho_height_m = 1.0;               ///< Visible height (orthographic only), m, > 0.

  /// @throws std::invalid_argument naming the field (non-finite values, eye == target,
  /// up parallel to the view direction, fov outside (0, 170), ortho height <= 0).
  void validate() const;
  /// World to eye coordinates (OpenGL convention: the camera looks down -z).
  Eigen::Matrix4d view() const;
  /// Eye to clip coordinates for an image of `aspect` = width / height, with clip
  /// planes at distances `near_m` < `far_m` in front of the eye.
  Eigen::Matrix4d projection(double aspect, double near_m, double far_m) const;
};

/// Named viewing directions. The eye looks at the box centre from: front = -y,
/// back = +y, left = -x, right = +x, top = +z (image up = +y), iso = (+x, -y, +z) diagonal.
enum class CameraPreset { front, back, left, right, top, iso };

const char* to_string(CameraPreset p);
/// @throws std::invalid_argument naming the text and the accepted names.
CameraPreset parse_camera_preset(const std::string& text);

/// A camera looking from `preset`'s direction at the box [lo, hi] from the distance at
/// which all eight corners fit in an image of `aspect` = width / height with a relative
/// `margin` (0.08: 8 % of the half-extent to spare), their projection centred (frame_points).
/// @throws std::invalid_argument for an empty box, aspect <= 0 or fov outside (0, 170).
Camera frame_box(CameraPreset preset, const core::Vec3& lo, const core::Vec3& hi, double aspect, double fov_deg = 30.0,
                 double margin = 0.08);

/// The same for a point cloud (e.g. the rest surface nodes): looks from the preset's
/// direction, from the distance at which every point fits (tighter than the box's corners
/// for rounded shapes seen diagonally), at a target placed so that the points' projected
/// extent is centred in the image.
/// @throws std::invalid_argument for fewer than one point, non-finite points, a
/// zero-size cloud, aspect <= 0 or fov outside (0, 170).
Camera frame_points(CameraPreset preset, const core::Positions& points, double aspect, double fov_deg = 30.0,
                    double margin = 0.08);

}  // namespace fiberfem::render
