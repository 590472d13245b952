#include "core/circulation/windkessel.hpp"

#include <cmath>
#include <stdexcept>

namespace fiberfem::core::circulation {

void Windkessel::validate() const {
  if (!(characteristic_pa_s_m3 >= 0) || !std::isfinite(characteristic_pa_s_m3))
    throw std::invalid_argument("windkessel: characteristic resistance must be >= 0");
  if (!(compliance_m3_pa > 0) || !std::isfinite(compliance_m3_pa))
    throw std::invalid_argument("windkessel: compliance must be > 0");
  if (!(peripheral_pa_s_m3 > 0) || !std::isfinite(peripheral_pa_s_m3))
    throw std::invalid_argument("windkessel: peripheral resistance must be > 0");
  if (!std::isfinite(venous_pa)) throw std::invalid_argument("windkessel: venous pressure must be finite");
}

double Windkessel::step(double p_c, double q_end, double h) const {
  // C (p1 - p0) / h = q1 - (p1 - p_ven) / R_p, solved for p1.
  const double c_h = compliance_m3_pa / h;
  return (c_h * p_c + q_end + venous_pa / peripheral_pa_s_m3) / (c_h + 1.0 / peripheral_pa_s_m3);
}

}  // namespace fiberfem::core::circulation
