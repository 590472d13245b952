#pragma once
/// @file Colour maps: viridis (perceptually uniform, sequential) for scalar fields and a
/// categorical palette for region ids.

#include "clients/render/image.hpp"

namespace fiberfem::render {

/// Viridis at t in [0, 1] (clamped; NaN gives grey), read from a 256-entry table.
/// The table samples a degree-6 polynomial fit of matplotlib's viridis (van der Walt and
/// Smith), published by "mattz" (shadertoy WlfXRN): within 6/255 per channel of
/// matplotlib's values at 0, 1/4, 1/2, 3/4 and 1 (tests/render/image_io_test.cpp).
Rgba viridis(double t);

/// A categorical colour for region id `k` (Tableau 10, repeating after 10 ids; k >= 0).
Rgba region_colour(int k);

/// The surface colour when no field is shown (a muscle pink-grey).
Rgba plain_colour();

}  // namespace fiberfem::render
