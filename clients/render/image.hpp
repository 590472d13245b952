#pragma once
/// @file An RGBA8 image in memory (top row first), and the few operations the renderer
/// needs on it: box-filter downscaling and side-by-side strips.

#include <cstddef>
#include <cstdint>
#include <vector>

namespace fiberfem::render {

/// An 8-bit RGBA colour.
struct Rgba {
  std::uint8_t r = 0, g = 0, b = 0, a = 255;
};

/// An RGBA8 image, row-major, top row first, 4 bytes a pixel, no row padding.
struct Image {
  int width = 0;                   ///< Pixels, >= 0.
  int height = 0;                  ///< Pixels, >= 0.
  std::vector<std::uint8_t> rgba;  ///< width * height * 4 bytes.

  Image() = default;
  /// A width x height image filled with `fill`. @throws std::invalid_argument for a negative size.
  Image(int width, int height, Rgba fill = {});
  /// The pixel at column x, row y (0 = top). Precondition: inside the image.
  std::uint8_t* at(int x, int y) { return rgba.data() + (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)) * 4; }
  const std::uint8_t* at(int x, int y) const { return rgba.data() + (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)) * 4; }
  /// Blends `c` over the pixel at (x, y) with coverage `alpha` in [0, 1]; outside: no-op.
  void blend(int x, int y, Rgba c, double alpha);
  /// Fills the rectangle [x0, x1) x [y0, y1), clipped to the image.
  void fill_rect(int x0, int y0, int x1, int y1, Rgba c);
  /// A line from (x0, y0) to (x1, y1), `width_px` wide (a square pen stamped along it at
  /// every pixel step), clipped to the image.
  void draw_line(double x0, double y0, double x1, double y1, Rgba c, int width_px = 1);
};

/// `src` shrunk to width x height by averaging the source pixels each target pixel covers
/// (area-weighted box filter). @throws std::invalid_argument unless 0 < size <= src size.
Image downscale(const Image& src, int width, int height);

/// The images side by side, left to right, separated by `gap_px` columns of `background`,
/// top-aligned, as tall as the tallest. @throws std::invalid_argument for no images.
Image hstack(const std::vector<Image>& images, int gap_px = 0, Rgba background = {255, 255, 255, 255});

}  // namespace fiberfem::render
