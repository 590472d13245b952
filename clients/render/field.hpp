#pragma once
/// @file The scalar fields the surface can be coloured by, their units and definitions.

#include "core/contraction.hpp"

#include <string>
#include <vector>

namespace fiberfem::render {

enum class Field {
  activation,    ///< Per element: active tension / the region's peak tension, 1 (0..1).
  fiber_strain,  ///< Per element: |F f| - 1 with F = Ds Dm^-1 and f the rest fiber, 1 (< 0: shortening).
  displacement,  ///< Per node: |x - X|, metres (labelled in mm).
  region,        ///< Per element: region id, categorical colours.
  none,          ///< One plain colour.
};

/// "activation", "fiber_strain", ...
const char* to_string(Field f);
/// @throws std::invalid_argument naming the text and the accepted names.
Field parse_field(const std::string& text);
/// Whether the field has one value per element (else per node, or none).
bool is_per_element(Field f);
/// Whether the field is a scalar shown with the colour map and a colour bar.
bool is_scalar(Field f);

/// Normalised activation per element: tension_pa[e] / contraction.region_peak_pa[region[e]]
/// (0 where the peak is zero), 1. An empty `tension_pa` (contraction off) gives all zeros.
/// @throws std::invalid_argument on size mismatches.
std::vector<double> activation_from_tension(const core::Contraction& contraction, const std::vector<int>& regions,
                                            const std::vector<double>& tension_pa);

}  // namespace fiberfem::render
