#include "clients/render/overlay.hpp"

#include "clients/render/colormap.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

namespace fiberfem::render {

std::string field_title(Field field) {
  switch (field) {
    case Field::activation: return "activation (1)";
    case Field::fiber_strain: return "fiber strain (1)";
    case Field::displacement: return "displacement (mm)";
    case Field::region: return "region";
    case Field::none: return "";
  }
  return "";
}

double field_label_value(Field field, double value) { return field == Field::displacement ? 1e3 * value : value; }

std::string tick_text(double v, double step) {
  char buf[32];
  if (std::abs(v) < 1e-9 * std::max(1.0, step)) v = 0;  // no "-0"
  // As many decimals as the step needs (2.5 needs one, 0.25 two).
  int digits = 0;
  while (digits < 6 && std::abs(step * std::pow(10.0, digits) - std::round(step * std::pow(10.0, digits))) > 1e-6 * step * std::pow(10.0, digits)) ++digits;
  std::snprintf(buf, sizeof buf, "%.*f", std::min(digits, 6), v);
  return buf;
}

std::vector<double> round_ticks(double a, double b, double& step) {
  // A step of 1, 2, 2.5 or 5 times a power of ten giving 3 to 6 ticks over [a, b].
  const double span = b - a;
  const double raw = span / 4, p10 = std::pow(10.0, std::floor(std::log10(raw)));
  step = 10 * p10;
  for (double m : {1.0, 2.0, 2.5, 5.0})
    if (m * p10 >= raw * 0.999) {
      step = m * p10;
      break;
    }
  std::vector<double> ticks;
  for (double v = std::ceil(a / step - 1e-9) * step; v <= b + 1e-9 * span; v += step) ticks.push_back(v);
  return ticks;
}

void draw_colour_bar(Image& image, Font& font, Field field, double lo, double hi, Rgba text) {
  const int h = image.height, w = image.width;
  const int bar_h = static_cast<int>(0.55 * h), bar_w = std::max(4, h / 36);
  const std::string title = field_title(field);
  const double a = field_label_value(field, lo), b = field_label_value(field, hi);
  // Ticks at round values, placed by value.
  const double span = b - a;
  double step = 1;
  const std::vector<double> ticks = round_ticks(a, b, step);
  int label_w = 0;
  for (double v : ticks) label_w = std::max(label_w, font.text_width(tick_text(v, step)));
  const int margin = std::max(6, h / 40);
  const int x0 = w - margin - label_w - bar_w / 2 - bar_w;
  const int y0 = (h - bar_h) / 2 + font.ascent();
  for (int y = 0; y < bar_h; ++y) image.fill_rect(x0, y0 + y, x0 + bar_w, y0 + y + 1, viridis(1.0 - y / (bar_h - 1.0)));
  // outline
  image.fill_rect(x0 - 1, y0 - 1, x0 + bar_w + 1, y0, text);
  image.fill_rect(x0 - 1, y0 + bar_h, x0 + bar_w + 1, y0 + bar_h + 1, text);
  image.fill_rect(x0 - 1, y0, x0, y0 + bar_h, text);
  image.fill_rect(x0 + bar_w, y0, x0 + bar_w + 1, y0 + bar_h, text);
  for (double v : ticks) {
    const int y = y0 + bar_h - 1 - static_cast<int>(std::lround((v - a) / span * (bar_h - 1.0)));
    image.fill_rect(x0 + bar_w, y, x0 + bar_w + bar_w / 3 + 1, y + 1, text);
    font.draw(image, x0 + bar_w + bar_w / 2, y + font.ascent() / 2, tick_text(v, step), text);
  }
  const int tw = font.text_width(title);
  font.draw(image, std::min(x0 + bar_w / 2 - tw / 2, w - margin - tw), y0 - font.ascent(), title, text);
}

void draw_region_legend(Image& image, Font& font, int num_regions, Rgba text) {
  const int n = std::clamp(num_regions, 0, 10);
  const int margin = std::max(6, image.height / 40), line = font.pixel_size() * 3 / 2;
  const int label_w = font.text_width("region 0") + (n > 9 ? font.text_width("0") : 0);
  const int x0 = image.width - margin - label_w - line;
  int y = (image.height - n * line) / 2;
  for (int k = 0; k < n; ++k, y += line) {
    image.fill_rect(x0, y, x0 + font.ascent(), y + font.ascent(), region_colour(k));
    font.draw(image, x0 + line, y + font.ascent(), "region " + std::to_string(k), text);
  }
}

void draw_caption(Image& image, Font& font, const std::string& caption, Rgba text) {
  const int margin = std::max(6, image.height / 40);
  font.draw(image, margin, margin + font.ascent(), caption, text);
}

}  // namespace fiberfem::render
