#include "clients/render/png_io.hpp"

#include <png.h>

#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <vector>

namespace fiberfem::render {

void write_png(const std::string& path, const Image& image, int level) {
  if (level < 0 || level > 9) throw std::invalid_argument("write_png: compression level " + std::to_string(level) + " is outside [0, 9]");
  if (image.width <= 0 || image.height <= 0) throw std::invalid_argument("write_png: empty image for " + path);
  std::unique_ptr<FILE, int (*)(FILE*)> f(std::fopen(path.c_str(), "wb"), &std::fclose);
  if (!f) throw std::runtime_error("cannot write " + path + ": " + std::strerror(errno));
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!info) {
    png_destroy_write_struct(&png, nullptr);
    throw std::runtime_error("write_png: libpng could not start for " + path);
  }
  std::vector<png_bytep> rows(static_cast<size_t>(image.height));
  for (int y = 0; y < image.height; ++y) rows[static_cast<size_t>(y)] = const_cast<png_bytep>(image.at(0, y));
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    throw std::runtime_error("cannot write " + path + " (libpng error; disk full?)");
  }
  png_init_io(png, f.get());
  png_set_IHDR(png, info, static_cast<png_uint_32>(image.width), static_cast<png_uint_32>(image.height), 8,
               PNG_COLOR_TYPE_RGB_ALPHA, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_compression_level(png, level);
  if (level <= 1) png_set_filter(png, 0, PNG_FILTER_NONE);
  png_write_info(png, info);
  png_write_image(png, rows.data());
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  if (std::fflush(f.get()) != 0) throw std::runtime_error("cannot write " + path + ": " + std::strerror(errno));
}

Image read_png(const std::string& path) {
  png_image im;
  std::memset(&im, 0, sizeof im);
  im.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&im, path.c_str()))
    throw std::runtime_error("cannot read PNG " + path + ": " + im.message);
  im.format = PNG_FORMAT_RGBA;
  Image out(static_cast<int>(im.width), static_cast<int>(im.height));
  if (!png_image_finish_read(&im, nullptr, out.rgba.data(), 0, nullptr)) {
    const std::string msg = im.message;
    png_image_free(&im);
    throw std::runtime_error("cannot read PNG " + path + ": " + msg);
  }
  return out;
}

}  // namespace fiberfem::render
