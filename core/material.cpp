#include "core/material.hpp"

#include <Eigen/Dense>

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace fiberfem::core {
namespace {

std::string fmt(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

void require_finite(double v, const char* name, const std::string& origin) {
  if (!std::isfinite(v))
    throw std::invalid_argument(origin + ": " + name + " must be finite, got " + fmt(v));
}

void check_density(double rho, const std::string& origin) {
  require_finite(rho, "density", origin);
  if (!(rho > 0)) throw std::invalid_argument(origin + ": density must be > 0 kg/m^3, got " + fmt(rho));
}

bool close(double a, double b) { return std::abs(a - b) <= 1e-12 * std::max(std::abs(a), std::abs(b)); }

}  // namespace

// C has the pattern of PHYSICS.md section 2; it is positive definite exactly when
// C11 > |C12| (the transverse in-plane block), C55 > 0, C33 > 0 and
// (C11 + C12) C33 > 2 C13^2 (the axisymmetric block).
Material::Material(const StiffnessConstants& c, double density_kg_m3, const std::string& origin) {
  require_finite(c.C11, "C11", origin);
  require_finite(c.C12, "C12", origin);
  require_finite(c.C13, "C13", origin);
  require_finite(c.C33, "C33", origin);
  require_finite(c.C55, "C55", origin);
  check_density(density_kg_m3, origin);
  if (!(c.C11 - c.C12 > 0))
    throw std::invalid_argument(origin + ": not positive definite: need C11 > C12 (C44 = (C11 - C12)/2 > 0), got C11=" +
                                fmt(c.C11) + ", C12=" + fmt(c.C12));
  if (!(c.C11 + c.C12 > 0))
    throw std::invalid_argument(origin + ": not positive definite: need C11 + C12 > 0, got C11=" +
                                fmt(c.C11) + ", C12=" + fmt(c.C12));
  if (!(c.C33 > 0))
    throw std::invalid_argument(origin + ": not positive definite: need C33 > 0, got C33=" + fmt(c.C33));
  if (!(c.C55 > 0))
    throw std::invalid_argument(origin + ": not positive definite: need C55 > 0, got C55=" + fmt(c.C55));
  if (!((c.C11 + c.C12) * c.C33 - 2 * c.C13 * c.C13 > 0))
    throw std::invalid_argument(origin + ": not positive definite: need (C11 + C12) C33 > 2 C13^2, got C11=" +
                                fmt(c.C11) + ", C12=" + fmt(c.C12) + ", C13=" + fmt(c.C13) +
                                ", C33=" + fmt(c.C33));
  C_.setZero();
  C_(0, 0) = C_(1, 1) = c.C11;
  C_(0, 1) = C_(1, 0) = c.C12;
  C_(0, 2) = C_(2, 0) = C_(1, 2) = C_(2, 1) = c.C13;
  C_(2, 2) = c.C33;
  C_(3, 3) = 0.5 * (c.C11 - c.C12);
  C_(4, 4) = C_(5, 5) = c.C55;
  S_ = C_.inverse();
  density_ = density_kg_m3;
  isotropic_ = close(c.C11, c.C33) && close(c.C12, c.C13) && close(c.C55, C_(3, 3));
}

Material Material::from_stiffness(const StiffnessConstants& c, double density_kg_m3) {
  return Material(c, density_kg_m3, "material (C form)");
}

Material Material::from_lame(const LameFiberConstants& c, double density_kg_m3) {
  const std::string origin = "material (lame form)";
  require_finite(c.lambda, "lambda", origin);
  require_finite(c.mu, "mu", origin);
  require_finite(c.fiber_factor, "fiber_factor", origin);
  require_finite(c.shear_factor, "shear_factor", origin);
  if (!(c.mu > 0)) throw std::invalid_argument(origin + ": mu must be > 0 Pa, got " + fmt(c.mu));
  if (!(3 * c.lambda + 2 * c.mu > 0))
    throw std::invalid_argument(origin + ": need bulk modulus lambda + 2 mu / 3 > 0, got lambda=" +
                                fmt(c.lambda) + ", mu=" + fmt(c.mu));
  if (!(c.fiber_factor > 0))
    throw std::invalid_argument(origin + ": fiber_factor must be > 0, got " + fmt(c.fiber_factor));
  if (!(c.shear_factor > 0))
    throw std::invalid_argument(origin + ": shear_factor must be > 0, got " + fmt(c.shear_factor));
  StiffnessConstants k;
  k.C11 = c.lambda + 2 * c.mu;
  k.C12 = c.lambda;
  k.C13 = c.lambda;
  k.C33 = (c.lambda + 2 * c.mu) * c.fiber_factor;
  k.C55 = c.mu * c.shear_factor;
  return Material(k, density_kg_m3, origin);
}

// Compliance of PHYSICS.md section 2 (fiber = local axis 3), inverted.
Material Material::from_engineering(const EngineeringConstants& c, double density_kg_m3) {
  const std::string origin = "material (engineering form)";
  require_finite(c.E_L, "E_L", origin);
  require_finite(c.E_T, "E_T", origin);
  require_finite(c.nu_T, "nu_T", origin);
  require_finite(c.nu_LT, "nu_LT", origin);
  require_finite(c.G_L, "G_L", origin);
  if (!(c.E_L > 0)) throw std::invalid_argument(origin + ": E_L must be > 0 Pa, got " + fmt(c.E_L));
  if (!(c.E_T > 0)) throw std::invalid_argument(origin + ": E_T must be > 0 Pa, got " + fmt(c.E_T));
  if (!(c.G_L > 0)) throw std::invalid_argument(origin + ": G_L must be > 0 Pa, got " + fmt(c.G_L));
  if (!(std::abs(c.nu_T) < 1))
    throw std::invalid_argument(origin + ": nu_T must satisfy |nu_T| < 1, got " + fmt(c.nu_T));
  const double det = 1 - c.nu_T - 2 * c.nu_LT * c.nu_LT * c.E_T / c.E_L;
  if (!(det > 0))
    throw std::invalid_argument(origin + ": not positive definite: need 1 - nu_T - 2 nu_LT^2 E_T/E_L > 0, got " +
                                fmt(det) + " (nu_T=" + fmt(c.nu_T) + ", nu_LT=" + fmt(c.nu_LT) +
                                ", E_T=" + fmt(c.E_T) + ", E_L=" + fmt(c.E_L) + ")");
  check_density(density_kg_m3, origin);
  Mat6 S = Mat6::Zero();
  S(0, 0) = S(1, 1) = 1 / c.E_T;
  S(0, 1) = S(1, 0) = -c.nu_T / c.E_T;
  S(0, 2) = S(2, 0) = S(1, 2) = S(2, 1) = -c.nu_LT / c.E_L;
  S(2, 2) = 1 / c.E_L;
  S(3, 3) = 2 * (1 + c.nu_T) / c.E_T;
  S(4, 4) = S(5, 5) = 1 / c.G_L;
  const Mat6 C = S.inverse();
  StiffnessConstants k{C(0, 0), C(0, 1), C(0, 2), C(2, 2), C(4, 4)};
  return Material(k, density_kg_m3, origin);
}

Material Material::isotropic(double E, double nu, double density_kg_m3) {
  const std::string origin = "material (isotropic)";
  require_finite(E, "E", origin);
  require_finite(nu, "nu", origin);
  if (!(E > 0)) throw std::invalid_argument(origin + ": E must be > 0 Pa, got " + fmt(E));
  if (!(nu > -1 && nu < 0.5))
    throw std::invalid_argument(origin + ": nu must be in (-1, 0.5), got " + fmt(nu));
  LameFiberConstants l;
  l.mu = E / (2 * (1 + nu));
  l.lambda = E * nu / ((1 + nu) * (1 - 2 * nu));
  return from_lame(l, density_kg_m3);
}

StiffnessConstants Material::constants() const {
  return {C_(0, 0), C_(0, 1), C_(0, 2), C_(2, 2), C_(4, 4)};
}

EngineeringConstants Material::engineering() const {
  EngineeringConstants e;
  e.E_T = 1 / S_(0, 0);
  e.nu_T = -S_(0, 1) * e.E_T;
  e.E_L = 1 / S_(2, 2);
  e.nu_LT = -S_(0, 2) * e.E_L;
  e.G_L = 1 / S_(4, 4);
  return e;
}

}  // namespace fiberfem::core
