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
  return contraction.activation(regions, tension_pa);
}

}  // namespace fiberfem::render
