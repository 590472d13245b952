#include "clients/render/pv_loop.hpp"

#include "clients/render/overlay.hpp"
#include "core/circulation/circulation.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <tuple>

namespace fiberfem::render {
namespace {

namespace cc = core::circulation;

const Rgba kLvColour{200, 40, 40, 255}, kRvColour{40, 80, 200, 255};

// The plot's data ranges: volume (mL) over every point, padded by 5 %; pressure (mmHg)
// from 0 (or the lowest point) to the highest.
struct Ranges {
  double v0 = std::numeric_limits<double>::infinity(), v1 = -std::numeric_limits<double>::infinity();
  double p0 = 0, p1 = -std::numeric_limits<double>::infinity();
  explicit Ranges(const PvLoop& loop) {
    for (const auto* trace : {&loop.lv, &loop.rv})
      for (const auto& [v, p] : *trace) {
        v0 = std::min(v0, v / cc::kM3PerMl), v1 = std::max(v1, v / cc::kM3PerMl);
        p0 = std::min(p0, p / cc::kPaPerMmHg), p1 = std::max(p1, p / cc::kPaPerMmHg);
      }
    const double dv = std::max(v1 - v0, 1e-3 * std::max(1.0, std::abs(v1)));
    v0 -= 0.05 * dv, v1 += 0.05 * dv;
    p1 = std::max(p1, p0 + 1e-3 * std::max(1.0, std::abs(p0)));
    p1 += 0.05 * (p1 - p0);
  }
};

void dot(Image& image, double cx, double cy, int radius, Rgba c) {
  for (int y = -radius; y <= radius; ++y)
    for (int x = -radius; x <= radius; ++x)
      if (x * x + y * y <= radius * radius) image.blend(static_cast<int>(std::lround(cx)) + x, static_cast<int>(std::lround(cy)) + y, c, 1.0);
}

}  // namespace

PvInsetBox PvInsetBox::in(int width, int height) {
  PvInsetBox b;
  const int margin = std::max(6, height / 40);
  b.size = std::min(height / 3, width / 3);
  b.x0 = margin;
  b.y0 = height - margin - b.size;
  return b;
}

void draw_pv_inset(Image& image, Font& font, const PvLoop& loop, Rgba text) {
  const PvInsetBox box = PvInsetBox::in(image.width, image.height);
  const int x_end = box.x0 + box.size, y_end = box.y0 + box.size;
  for (int y = box.y0; y < y_end; ++y)  // a pale panel: the heart shows through faintly
    for (int x = box.x0; x < x_end; ++x) image.blend(x, y, {255, 255, 255, 255}, 0.85);
  const Ranges r(loop);
  double v_step = 1, p_step = 1;
  const std::vector<double> v_ticks = round_ticks(r.v0, r.v1, v_step), p_ticks = round_ticks(r.p0, r.p1, p_step);
  int label_w = 0;
  for (double p : p_ticks) label_w = std::max(label_w, font.text_width(tick_text(p, p_step)));
  const int pad = std::max(3, font.pixel_size() / 2), line = font.ascent() + pad;
  // The plot area: y labels on the left, the axis title and legend above, x labels and
  // title below.
  const int px0 = box.x0 + pad + label_w + pad, px1 = x_end - pad;
  const int py0 = box.y0 + pad + line, py1 = y_end - pad - 2 * line;
  if (px1 - px0 < 8 || py1 - py0 < 8) return;  // too small an image for a plot
  const auto X = [&](double v_ml) { return px0 + (v_ml - r.v0) / (r.v1 - r.v0) * (px1 - px0); };
  const auto Y = [&](double p_mmhg) { return py1 - (p_mmhg - r.p0) / (r.p1 - r.p0) * (py1 - py0); };
  image.draw_line(px0, py0, px0, py1, text);
  image.draw_line(px0, py1, px1, py1, text);
  for (double p : p_ticks) {
    const double y = Y(p);
    image.draw_line(px0 - pad / 2, y, px0, y, text);
    const std::string s = tick_text(p, p_step);
    font.draw(image, px0 - pad - font.text_width(s), static_cast<int>(std::lround(y)) + font.ascent() / 2, s, text);
  }
  for (double v : v_ticks) {
    const double x = X(v);
    image.draw_line(x, py1, x, py1 + pad / 2, text);
    const std::string s = tick_text(v, v_step);
    font.draw(image, static_cast<int>(std::lround(x)) - font.text_width(s) / 2, py1 + line, s, text);
  }
  font.draw(image, box.x0 + pad, box.y0 + pad + font.ascent(), "p (mmHg)", text);
  const std::string v_title = "V (mL)";
  font.draw(image, (px0 + px1 - font.text_width(v_title)) / 2, py1 + 2 * line, v_title, text);
  int legend_x = px1;
  for (const auto& [trace, colour, name] : {std::make_tuple(&loop.rv, kRvColour, "RV"), std::make_tuple(&loop.lv, kLvColour, "LV")}) {
    legend_x -= font.text_width(name) + pad;
    font.draw(image, legend_x, box.y0 + pad + font.ascent(), name, colour);
    for (size_t i = 1; i < trace->size(); ++i)
      image.draw_line(X((*trace)[i - 1][0] / cc::kM3PerMl), Y((*trace)[i - 1][1] / cc::kPaPerMmHg), X((*trace)[i][0] / cc::kM3PerMl),
                      Y((*trace)[i][1] / cc::kPaPerMmHg), colour, 2);
    if (!trace->empty())
      dot(image, X(trace->back()[0] / cc::kM3PerMl), Y(trace->back()[1] / cc::kPaPerMmHg), std::max(3, pad), colour);
  }
}

}  // namespace fiberfem::render
