#pragma once
/// @file Transversely isotropic linear elastic material (PHYSICS.md section 2).

#include "core/types.hpp"

#include <string>

namespace fiberfem::core {

/// Engineering constants of a transversely isotropic material; the fiber is the axis of
/// symmetry. All moduli in Pa.
struct EngineeringConstants {
  double E_L = 60.0e3;   ///< Young's modulus along the fiber, Pa, > 0.
  double E_T = 20.0e3;   ///< Young's modulus across the fiber, Pa, > 0.
  double nu_T = 0.45;    ///< Poisson's ratio in the transverse plane, |nu_T| < 1.
  double nu_LT = 0.25;   ///< Transverse contraction under fiber stress: eps_T = -nu_LT sigma_L / E_L.
  double G_L = 8.0e3;    ///< Shear modulus in planes containing the fiber, Pa, > 0.
};

/// The paper's parameterisation: isotropic Lame constants, then C33 *= fiber_factor and
/// C55 = C66 *= shear_factor.
struct LameFiberConstants {
  double lambda = 40.0e3;      ///< First Lame constant, Pa; 3 lambda + 2 mu > 0.
  double mu = 10.0e3;          ///< Shear modulus, Pa, > 0.
  double fiber_factor = 1.0;   ///< Multiplier of C33 (along the fiber), > 0.
  double shear_factor = 1.0;   ///< Multiplier of C55 and C66 (fiber-plane shear), > 0.
};

/// The five independent stiffness constants of PHYSICS.md section 2, Pa. C22 = C11,
/// C23 = C13, C66 = C55, C44 = (C11 - C12) / 2 follow.
struct StiffnessConstants {
  double C11 = 0, C12 = 0, C13 = 0, C33 = 0, C55 = 0;
};

/// A validated transversely isotropic material: the 6x6 stiffness in the fiber frame
/// (Voigt order xx, yy, zz, xy, yz, zx; engineering shear; fiber along local z) and the
/// density. Immutable; build it with one of the `from_*` factories.
class Material {
 public:
  /// @throws std::invalid_argument naming the offending constant(s) if not positive definite.
  static Material from_engineering(const EngineeringConstants& c, double density_kg_m3);
  static Material from_lame(const LameFiberConstants& c, double density_kg_m3);
  static Material from_stiffness(const StiffnessConstants& c, double density_kg_m3);
  /// Isotropic material from Young's modulus (Pa, > 0) and Poisson's ratio (-1 < nu < 0.5).
  static Material isotropic(double youngs_modulus_pa, double poisson_ratio, double density_kg_m3);

  /// Local stiffness C (fiber along local axis 3), Pa.
  const Mat6& stiffness() const { return C_; }
  /// Local compliance S = C^-1, 1/Pa.
  const Mat6& compliance() const { return S_; }
  double density_kg_m3() const { return density_; }
  /// True when C is isotropic (to relative 1e-12): the fiber direction then does not matter
  /// and the element precompute skips the frame work.
  bool is_isotropic() const { return isotropic_; }
  /// The five independent constants of this material.
  StiffnessConstants constants() const;
  /// Engineering constants recovered from the compliance.
  EngineeringConstants engineering() const;

 private:
  Material(const StiffnessConstants& c, double density_kg_m3, const std::string& origin);
  Mat6 C_;
  Mat6 S_;
  double density_ = 0;
  bool isotropic_ = false;
};

}  // namespace fiberfem::core
