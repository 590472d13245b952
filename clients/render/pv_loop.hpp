#pragma once
/// @file The pressure-volume loop drawn beside the heart of a run with a circulation
/// (docs/rendering.md): each ventricle's (volume, pressure) traced so far, as an inset plot
/// at the bottom left with axes in mL and mmHg and the current point marked.

#include "clients/render/font.hpp"
#include "clients/render/image.hpp"

#include <array>
#include <vector>

namespace fiberfem::render {

/// The points of the loops so far, in time order: the newest kMaxPoints (a long run's
/// loop costs what about 17 s of frames at 60/s cost).
struct PvLoop {
  static constexpr size_t kMaxPoints = 1000;
  std::vector<std::array<double, 2>> lv;  ///< Left ventricle (volume m^3, pressure Pa).
  std::vector<std::array<double, 2>> rv;  ///< Right ventricle (volume m^3, pressure Pa).
  /// Appends one sample of each ventricle (SI units), dropping the oldest beyond kMaxPoints.
  void add(double lv_volume_m3, double lv_pressure_pa, double rv_volume_m3, double rv_pressure_pa) {
    lv.push_back({lv_volume_m3, lv_pressure_pa});
    rv.push_back({rv_volume_m3, rv_pressure_pa});
    if (lv.size() > kMaxPoints) lv.erase(lv.begin()), rv.erase(rv.begin());
  }
  bool empty() const { return lv.empty(); }
};

/// Where the inset goes in an image of `width` x `height` pixels: its square's side, px
/// (a third of the height), at `margin` from the left and bottom edges.
struct PvInsetBox {
  int x0 = 0, y0 = 0, size = 0;
  static PvInsetBox in(int width, int height);
};

/// Draws the inset: a pale panel, axes with round ticks over the range of every point so
/// far (volume in mL, pressure in mmHg from 0), the LV loop in red and the RV loop in blue
/// with their newest points as dots, and a legend. Precondition: !loop.empty().
void draw_pv_inset(Image& image, Font& font, const PvLoop& loop, Rgba text);

}  // namespace fiberfem::render
