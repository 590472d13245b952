#include "clients/render/field.hpp"

#include <stdexcept>

namespace fiberfem::render {

const char* to_string(Field f) {
  switch (f) {
    case Field::activation: return "activation";
    case Field::fiber_strain: return "fiber_strain";
    case Field::displacement: return "displacement";
    case Field::region: return "region";
    case Field::none: return "none";
  }
  return "?";
}

Field parse_field(const std::string& text) {
  for (Field f : {Field::activation, Field::fiber_strain, Field::displacement, Field::region, Field::none})
    if (text == to_string(f)) return f;
  throw std::invalid_argument("unknown field '" + text + "' (use activation, fiber_strain, displacement, region or none)");
}

bool is_per_element(Field f) { return f == Field::activation || f == Field::fiber_strain || f == Field::region; }

bool is_scalar(Field f) { return f == Field::activation || f == Field::fiber_strain || f == Field::displacement; }

std::vector<double> activation_from_tension(const core::Contraction& contraction, const std::vector<int>& regions,
                                            const std::vector<double>& tension_pa) {
  std::vector<double> a(regions.size(), 0.0);
  if (tension_pa.empty()) return a;
  if (tension_pa.size() != regions.size())
    throw std::invalid_argument("activation_from_tension: " + std::to_string(tension_pa.size()) + " tensions for " +
                                std::to_string(regions.size()) + " elements");
  for (size_t e = 0; e < regions.size(); ++e) {
    const size_t r = static_cast<size_t>(regions[e]);
    const double peak = r < contraction.region_peak_pa.size() ? contraction.region_peak_pa[r] : 0.0;
    a[e] = peak > 0 ? tension_pa[e] / peak : 0.0;
  }
  return a;
}

}  // namespace fiberfem::render
