#pragma once
/// @file What is drawn over the rendered surface: a colour bar with tick labels (or a
/// region legend) and a caption line.

#include "clients/render/field.hpp"
#include "clients/render/font.hpp"
#include "clients/render/image.hpp"

#include <string>

namespace fiberfem::render {

/// The field's colour-bar title with its unit: "activation (1)", "fiber strain (1)",
/// "displacement (mm)".
std::string field_title(Field field);

/// Value shown on the colour bar for a field value (displacement in mm, else unchanged).
double field_label_value(Field field, double value);

/// A vertical viridis bar at the right edge, `lo` at the bottom and `hi` at the top (in
/// the field's SI unit), with five tick labels and the field's title above it.
void draw_colour_bar(Image& image, Font& font, Field field, double lo, double hi, Rgba text);

/// Swatches with "region 0" .. "region n-1" at the right edge (at most 10 listed).
void draw_region_legend(Image& image, Font& font, int num_regions, Rgba text);

/// One line of text at the top left.
void draw_caption(Image& image, Font& font, const std::string& caption, Rgba text);

}  // namespace fiberfem::render
