#pragma once
/// @file What is drawn over the rendered surface: a colour bar with tick labels (or a
/// region legend) and a caption line.

#include "clients/render/field.hpp"
#include "clients/render/font.hpp"
#include "clients/render/image.hpp"

#include <string>
#include <vector>

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

/// Ticks at round values over [a, b] (a < b): a step of 1, 2, 2.5 or 5 times a power of
/// ten giving 3 to 6 of them, returned in `step`.
std::vector<double> round_ticks(double a, double b, double& step);
/// A tick's label with as many decimals as the step needs (2.5 needs one, 0.25 two).
std::string tick_text(double v, double step);

/// One line of text at the top left.
void draw_caption(Image& image, Font& font, const std::string& caption, Rgba text);

}  // namespace fiberfem::render
