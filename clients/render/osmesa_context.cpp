#include "clients/render/osmesa_context.hpp"

#include <GL/osmesa.h>

#include <stdexcept>

namespace fiberfem::render {

OsmesaContext::OsmesaContext(int width, int height) : width_(width), height_(height) {
  if (width < 1 || height < 1 || width > kMaxSize || height > kMaxSize)
    throw std::invalid_argument("image size " + std::to_string(width) + "x" + std::to_string(height) + " is outside [1, " +
                                std::to_string(kMaxSize) + "] pixels per side");
  // A compatibility-profile context: fixed-function state for lines plus GLSL 1.20 shaders.
  const int attribs[] = {OSMESA_FORMAT, OSMESA_RGBA, OSMESA_DEPTH_BITS, 24, OSMESA_STENCIL_BITS, 0, OSMESA_ACCUM_BITS, 0,
                         OSMESA_PROFILE, OSMESA_COMPAT_PROFILE, 0};
  ctx_ = OSMesaCreateContextAttribs(attribs, nullptr);
  if (!ctx_) throw std::runtime_error("OSMesa: cannot create a context (libOSMesa from libosmesa6 missing or broken?)");
  buffer_.resize(static_cast<size_t>(width) * static_cast<size_t>(height) * 4);
  make_current();
}

OsmesaContext::~OsmesaContext() {
  if (ctx_) OSMesaDestroyContext(ctx_);
}

void OsmesaContext::make_current() {
  if (!OSMesaMakeCurrent(ctx_, buffer_.data(), GL_UNSIGNED_BYTE, width_, height_))
    throw std::runtime_error("OSMesa: cannot make the context current at " + std::to_string(width_) + "x" + std::to_string(height_));
  OSMesaPixelStore(OSMESA_Y_UP, 0);  // row 0 of the buffer is the top of the image
}

std::string OsmesaContext::describe() const {
  const auto* r = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  const auto* v = reinterpret_cast<const char*>(glGetString(GL_VERSION));
  return std::string(r ? r : "?") + " / " + (v ? v : "?");
}

}  // namespace fiberfem::render
