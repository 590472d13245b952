#pragma once
/// @file The three-element Windkessel (characteristic resistance R_c in series with a
/// compliance C parallel to a peripheral resistance R_p, draining to a venous pressure):
/// the simplest afterload, and a check of backward Euler against a closed form. R_c = 0
/// is the two-element Windkessel. SI units.

namespace fiberfem::core::circulation {

struct Windkessel {
  double characteristic_pa_s_m3 = 0;  ///< R_c, Pa s/m^3 (>= 0).
  double compliance_m3_pa = 0;        ///< C, m^3/Pa (> 0).
  double peripheral_pa_s_m3 = 0;      ///< R_p, Pa s/m^3 (> 0).
  double venous_pa = 0;               ///< Pressure R_p drains to, Pa.
  /// @throws std::invalid_argument naming the field.
  void validate() const;
  /// The compliance's pressure after a backward-Euler step of size h with inflow q_end
  /// (at the step's end), from p_c.
  double step(double p_c, double q_end_m3_s, double h_s) const;
  /// The inlet pressure for the compliance's pressure p_c and inflow q.
  double inlet_pressure(double p_c, double q_m3_s) const { return p_c + characteristic_pa_s_m3 * q_m3_s; }
};

}  // namespace fiberfem::core::circulation
