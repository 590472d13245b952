#pragma once
/// @file The renderer: the shaded, colour-mapped surface of a deforming tetrahedral mesh,
/// drawn off-screen (OSMesa) into an RGBA image, with optional fiber glyphs, colour bar
/// and caption (docs/rendering.md).

#include "clients/render/camera.hpp"
#include "clients/render/field.hpp"
#include "clients/render/frame.hpp"
#include "clients/render/image.hpp"

#include <memory>
#include <optional>
#include <utility>

namespace fiberfem::render {

/// What to draw and how. Every field has a default; validate() names a bad one.
struct RenderSettings {
  int width = 1280;                  ///< Image width, pixels, in [16, 8192]. Default 1280.
  int height = 720;                  ///< Image height, pixels, in [16, 8192]. Default 720.
  Field field = Field::activation;   ///< Colouring. Default activation.
  /// Fixed colour range (min < max) in the field's SI unit (displacement in metres).
  /// Unset: activation uses [0, 1]; fiber_strain and displacement use the smallest range
  /// holding every frame drawn so far (it only grows, so a movie does not flicker).
  std::optional<std::pair<double, double>> range;
  /// Per-element fields (activation, fiber_strain) averaged to the surface nodes and
  /// interpolated across each triangle (smooth colours); false colours each triangle
  /// with its element's own value (faceted). Default true.
  bool smooth = true;
  bool fibers = false;               ///< Fiber glyphs on the surface elements. Default off.
  /// Glyph length as a multiple of the mean surface edge length, in (0, 10]. Default 0.6.
  double fiber_length = 0.6;
  /// At most this many glyphs: with more surface triangles, every k-th triangle gets one
  /// (k = ceil(triangles / max)), in [1, 10^7]. Default 4000.
  int max_fiber_glyphs = 4000;
  /// Caption and label text height (em), pixels; 0 picks height / 42 (at least 9). Default 0.
  int font_px = 0;
  /// Supersampling factor per side (anti-aliasing: drawn at k times the size, then
  /// averaged down), in [1, 4]; costs about k^2. Default 1.
  int supersample = 1;
  /// Lighting per pixel (Blinn-Phong in a GLSL 1.20 fragment shader), or per vertex
  /// (OpenGL's fixed-function Blinn-Phong, Gouraud-interpolated; same lights). Default true.
  bool per_pixel_lighting = true;
  bool colour_bar = true;            ///< Colour bar (scalar fields) or region legend. Default on.
  bool caption = true;               ///< FrameView::caption at the top left. Default on.
  /// The pressure-volume inset at the bottom left, for frames that carry a loop
  /// (FrameView::pv_loop). Default on.
  bool pv_inset = true;
  Rgba background{255, 255, 255, 255};  ///< Default white.
  Rgba text{40, 40, 40, 255};        ///< Caption and label colour. Default dark grey.

  /// @throws std::invalid_argument naming the field.
  void validate() const;
};

/// Wall time of the phases of the last render() call, seconds.
struct RenderTimes {
  double prepare_s = 0;   ///< Field values, colours, normals, vertex arrays (CPU).
  double draw_s = 0;      ///< GL calls and glFinish (llvmpipe rasterises here).
  double readback_s = 0;  ///< Copy (or supersampling reduction) of the colour buffer into the image.
  double overlay_s = 0;   ///< Colour bar, caption text and the pressure-volume inset.
  double total_s = 0;
};

/// Draws frames of one mesh. Owns an OSMesa context; use it from one thread at a time
/// (render() binds the context to the calling thread). Drawing is
/// synchronous: a live caller keeps only the newest frame (FrameMailbox) and renders when
/// the previous render() has returned, so a slow renderer drops frames instead of
/// slowing the simulation.
class Renderer {
 public:
  /// Extracts the surface of `mesh` and creates the context. The renderer keeps a
  /// reference to `mesh`: it must outlive the renderer.
  /// @throws std::invalid_argument for bad settings; std::runtime_error if OSMesa fails.
  Renderer(const core::TetMesh& mesh, RenderSettings settings = {});
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  /// The camera used from the next render() on. @throws std::invalid_argument (Camera::validate()).
  void set_camera(const Camera& camera);
  /// The current camera and the (validated) settings.
  const Camera& camera() const;
  const RenderSettings& settings() const;
  /// The colour range the last frame used (field SI unit).
  std::pair<double, double> range() const;

  /// Draws `frame` and returns the image (valid until the next call).
  /// @throws std::invalid_argument if the frame does not match the mesh or lacks the
  /// data the field needs (activation, fibers).
  const Image& render(const FrameView& frame);
  /// Phase times of the last render(), seconds.
  const RenderTimes& last_times() const;
  /// GL renderer and version string of the context.
  std::string describe() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace fiberfem::render
