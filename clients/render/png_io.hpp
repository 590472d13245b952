#pragma once
/// @file PNG files through libpng: fast writing (compression level 1 costs about 12 ms for
/// a 1280x720 frame, REFERENCES.md) and reading back (tests, strips).

#include "clients/render/image.hpp"

#include <string>

namespace fiberfem::render {

/// Writes `image` as an 8-bit RGBA PNG. `level` is zlib's compression level, 0 (none,
/// fastest) to 9 (smallest); level 1 and below also skip the row filters (fast frames),
/// 2 and above let libpng choose them (small files, e.g. level 9 for committed pictures).
/// @throws std::runtime_error naming the path if it cannot be written;
/// std::invalid_argument for a level outside [0, 9] or an empty image.
void write_png(const std::string& path, const Image& image, int level = 1);

/// Reads a PNG of any colour type and bit depth, converted to RGBA8.
/// @throws std::runtime_error naming the path if it is missing or not a PNG.
Image read_png(const std::string& path);

}  // namespace fiberfem::render
