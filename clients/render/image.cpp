#include "clients/render/image.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace fiberfem::render {

Image::Image(int w, int h, Rgba fill) : width(w), height(h) {
  if (w < 0 || h < 0) throw std::invalid_argument("Image: negative size " + std::to_string(w) + "x" + std::to_string(h));
  rgba.resize(static_cast<size_t>(w) * static_cast<size_t>(h) * 4);
  for (size_t i = 0; i < rgba.size(); i += 4) {
    rgba[i] = fill.r, rgba[i + 1] = fill.g, rgba[i + 2] = fill.b, rgba[i + 3] = fill.a;
  }
}

void Image::blend(int x, int y, Rgba c, double alpha) {
  if (x < 0 || y < 0 || x >= width || y >= height || alpha <= 0) return;
  alpha = std::min(alpha, 1.0);
  std::uint8_t* p = at(x, y);
  const std::uint8_t src[3] = {c.r, c.g, c.b};
  for (int k = 0; k < 3; ++k) p[k] = static_cast<std::uint8_t>(std::lround(p[k] + alpha * (src[k] - p[k])));
}

void Image::fill_rect(int x0, int y0, int x1, int y1, Rgba c) {
  x0 = std::max(x0, 0), y0 = std::max(y0, 0), x1 = std::min(x1, width), y1 = std::min(y1, height);
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) {
      std::uint8_t* p = at(x, y);
      p[0] = c.r, p[1] = c.g, p[2] = c.b, p[3] = c.a;
    }
}

void Image::draw_line(double x0, double y0, double x1, double y1, Rgba c, int width_px) {
  const int steps = std::max(1, static_cast<int>(std::ceil(std::max(std::abs(x1 - x0), std::abs(y1 - y0)))));
  const int lo = -(width_px - 1) / 2, hi = width_px / 2;
  for (int i = 0; i <= steps; ++i) {
    const double f = static_cast<double>(i) / steps;
    const int x = static_cast<int>(std::lround(x0 + f * (x1 - x0))), y = static_cast<int>(std::lround(y0 + f * (y1 - y0)));
    fill_rect(x + lo, y + lo, x + hi + 1, y + hi + 1, c);
  }
}

// Each target pixel [tx, tx+1) covers source columns [tx sx, (tx+1) sx) (sx = src/target);
// the weights are the overlap lengths, separably in x and y.
Image downscale(const Image& src, int width, int height) {
  if (width <= 0 || height <= 0 || width > src.width || height > src.height)
    throw std::invalid_argument("downscale: target " + std::to_string(width) + "x" + std::to_string(height) +
                                " must be positive and at most the source " + std::to_string(src.width) + "x" +
                                std::to_string(src.height));
  auto spans = [](int n_src, int n_dst) {
    struct Span { int first; std::vector<double> w; };
    std::vector<Span> out(static_cast<size_t>(n_dst));
    const double s = static_cast<double>(n_src) / n_dst;
    for (int t = 0; t < n_dst; ++t) {
      const double a = t * s, b = (t + 1) * s;
      Span& sp = out[static_cast<size_t>(t)];
      sp.first = static_cast<int>(std::floor(a));
      for (int i = sp.first; i < n_src && i < b; ++i) sp.w.push_back((std::min<double>(i + 1, b) - std::max<double>(i, a)) / s);
    }
    return out;
  };
  const auto xs = spans(src.width, width), ys = spans(src.height, height);
  Image dst(width, height);
  std::vector<double> row(static_cast<size_t>(width) * 4);
  for (int ty = 0; ty < height; ++ty) {
    std::fill(row.begin(), row.end(), 0.0);
    const auto& sy = ys[static_cast<size_t>(ty)];
    for (size_t j = 0; j < sy.w.size(); ++j) {
      const int y = sy.first + static_cast<int>(j);
      for (int tx = 0; tx < width; ++tx) {
        const auto& sx = xs[static_cast<size_t>(tx)];
        for (size_t i = 0; i < sx.w.size(); ++i) {
          const std::uint8_t* p = src.at(sx.first + static_cast<int>(i), y);
          const double w = sx.w[i] * sy.w[j];
          for (int k = 0; k < 4; ++k) row[static_cast<size_t>(tx) * 4 + static_cast<size_t>(k)] += w * p[k];
        }
      }
    }
    for (int tx = 0; tx < width; ++tx)
      for (int k = 0; k < 4; ++k)
        dst.at(tx, ty)[k] = static_cast<std::uint8_t>(std::clamp(std::lround(row[static_cast<size_t>(tx) * 4 + static_cast<size_t>(k)]), 0L, 255L));
  }
  return dst;
}

Image hstack(const std::vector<Image>& images, int gap_px, Rgba background) {
  if (images.empty()) throw std::invalid_argument("hstack: no images");
  int w = gap_px * static_cast<int>(images.size() - 1), h = 0;
  for (const Image& im : images) w += im.width, h = std::max(h, im.height);
  Image out(w, h, background);
  int x0 = 0;
  for (const Image& im : images) {
    for (int y = 0; y < im.height; ++y)
      std::copy_n(im.at(0, y), static_cast<size_t>(im.width) * 4, out.at(x0, y));
    x0 += im.width + gap_px;
  }
  return out;
}

}  // namespace fiberfem::render
