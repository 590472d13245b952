// The three-element Windkessel's backward-Euler step against its closed-form solution for a
// steady plus sinusoidal inflow.
#include "core/circulation/windkessel.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace cc = fiberfem::core::circulation;

namespace {

constexpr double kPi = 3.14159265358979323846;

// C p' + (p - p_v) / R_p = q0 + q1 sin(w t), p(0) = p0: particular solution plus the
// decaying homogeneous one (tau = R_p C).
double exact(const cc::Windkessel& w, double p0, double q0, double q1, double om, double t) {
  const double tau = w.peripheral_pa_s_m3 * w.compliance_m3_pa;
  const double a = q1 * w.peripheral_pa_s_m3 / (1 + om * om * tau * tau), b = -om * tau * a;
  const double steady = w.venous_pa + q0 * w.peripheral_pa_s_m3;
  const double part0 = steady + b;
  return steady + a * std::sin(om * t) + b * std::cos(om * t) + (p0 - part0) * std::exp(-t / tau);
}

double error_at(const cc::Windkessel& w, double h, double until) {
  const double q0 = 80e-6, q1 = 60e-6, om = 2 * kPi / 0.8, p0 = 8000;
  double p = p0, worst = 0;
  const int n = static_cast<int>(std::lround(until / h));
  for (int i = 1; i <= n; ++i) {
    const double t = i * h;
    p = w.step(p, q0 + q1 * std::sin(om * t), h);
    worst = std::max(worst, std::abs(p - exact(w, p0, q0, q1, om, t)));
  }
  return worst;
}

}  // namespace

TEST(Windkessel, BackwardEulerMatchesTheClosedFormAtFirstOrder) {
  cc::Windkessel w;
  w.characteristic_pa_s_m3 = 0.03 * 133.322 / 1e-6;
  w.compliance_m3_pa = 1.5e-6 / 133.322;
  w.peripheral_pa_s_m3 = 1.0 * 133.322 / 1e-6;
  w.venous_pa = 500;
  w.validate();
  const double e1 = error_at(w, 1.0 / 60, 4.0), e2 = error_at(w, 1.0 / 120, 4.0), e3 = error_at(w, 1e-4, 4.0);
  EXPECT_GT(e1 / e2, 1.8);
  EXPECT_LT(e1 / e2, 2.2);
  EXPECT_LT(e3, 1e-3 * 13000);  // < 0.1 % of the pressure at a fine step
  EXPECT_LT(e1, 0.05 * 13000);  // < 5 % at the engine's step
  // Inlet pressure: R_c in series.
  EXPECT_DOUBLE_EQ(w.inlet_pressure(1000, 1e-4), 1000 + w.characteristic_pa_s_m3 * 1e-4);
}

TEST(Windkessel, RefusesANegativeCompliance) {
  cc::Windkessel w;
  w.compliance_m3_pa = -1;
  w.peripheral_pa_s_m3 = 1;
  EXPECT_THROW(w.validate(), std::invalid_argument);
}
