#pragma once
/// @file An off-screen OpenGL context (OSMesa, Mesa's llvmpipe rasteriser): no display,
/// no GPU. The colour buffer is client memory, top row first.

#include <cstdint>
#include <string>
#include <vector>

struct osmesa_context;

namespace fiberfem::render {

/// Owns one OSMesa context with an RGBA8 colour buffer and a 24-bit depth buffer.
/// Not copyable; one thread at a time (make_current() before drawing from another).
class OsmesaContext {
 public:
  /// Largest width or height accepted, pixels (OSMesa's own limit is 16384).
  static constexpr int kMaxSize = 8192;

  /// @param width, height buffer size in pixels, each in [1, kMaxSize].
  /// @throws std::invalid_argument for a bad size; std::runtime_error if OSMesa fails.
  OsmesaContext(int width, int height);
  ~OsmesaContext();
  OsmesaContext(const OsmesaContext&) = delete;
  OsmesaContext& operator=(const OsmesaContext&) = delete;

  /// Binds the context and its buffer to the calling thread. @throws std::runtime_error.
  void make_current();
  /// Buffer width and height, pixels.
  int width() const { return width_; }
  int height() const { return height_; }
  /// The colour buffer, width * height * 4 bytes, top row first; complete after glFinish().
  const std::uint8_t* pixels() const { return buffer_.data(); }
  /// GL_RENDERER and GL_VERSION, e.g. "llvmpipe (LLVM 15.0.6, 256 bits) / 4.5 (Compatibility Profile) Mesa 22.3.6".
  std::string describe() const;

 private:
  osmesa_context* ctx_ = nullptr;
  int width_ = 0, height_ = 0;
  std::vector<std::uint8_t> buffer_;
};

}  // namespace fiberfem::render
