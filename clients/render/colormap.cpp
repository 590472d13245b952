#include "clients/render/colormap.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace fiberfem::render {
namespace {

// c0 + t (c1 + t (c2 + ...)): the polynomial fit of matplotlib's viridis, per channel.
constexpr double kViridis[7][3] = {
    {0.2777273272234177, 0.005407344544966578, 0.3340998053353061},
    {0.1050930431085774, 1.404613529898575, 1.384590162594685},
    {-0.3308618287255563, 0.214847559468213, 0.09509516302823659},
    {-4.634230498983486, -5.799100973351585, -19.33244095627987},
    {6.228269936347081, 14.17993336680509, 56.69055260068105},
    {4.776384997670288, -13.74514537774601, -65.35303263337234},
    {-5.435455855934631, 4.645852612178535, 26.3124352495832},
};

std::array<Rgba, 256> make_table() {
  std::array<Rgba, 256> table{};
  for (int i = 0; i < 256; ++i) {
    const double t = i / 255.0;
    std::uint8_t c[3];
    for (int k = 0; k < 3; ++k) {
      double v = kViridis[6][k];
      for (int j = 5; j >= 0; --j) v = kViridis[j][k] + t * v;
      c[k] = static_cast<std::uint8_t>(std::lround(255 * std::clamp(v, 0.0, 1.0)));
    }
    table[static_cast<size_t>(i)] = {c[0], c[1], c[2], 255};
  }
  return table;
}

}  // namespace

Rgba viridis(double t) {
  static const std::array<Rgba, 256> table = make_table();
  if (std::isnan(t)) return {128, 128, 128, 255};
  const double x = std::clamp(t, 0.0, 1.0) * 255.0;
  return table[static_cast<size_t>(std::lround(x))];
}

Rgba region_colour(int k) {
  static constexpr Rgba kTableau10[10] = {{78, 121, 167, 255}, {242, 142, 43, 255}, {225, 87, 89, 255},  {118, 183, 178, 255},
                                          {89, 161, 79, 255},  {237, 201, 72, 255}, {176, 122, 161, 255}, {255, 157, 167, 255},
                                          {156, 117, 95, 255}, {186, 176, 172, 255}};
  return kTableau10[static_cast<size_t>(std::max(k, 0) % 10)];
}

Rgba plain_colour() { return {214, 170, 160, 255}; }

}  // namespace fiberfem::render
