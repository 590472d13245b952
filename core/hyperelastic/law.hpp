#pragma once
/// @file Hyperelastic material laws of the accurate tier (ACCURATE.md section 1): the
/// isochoric strain energy of neo-Hookean, Guccione and Holzapfel-Ogden laws in the
/// modified right Cauchy-Green tensor Cbar = J^(-2/3) F^T F, their first Piola-Kirchhoff
/// stress and its derivative dP/dF; the volumetric part (a penalty U(J) or the pressure of
/// a mixed formulation) and the benchmark's active stress S_a = T_a f0 (x) f0 added on top.
///
/// Stateless math (Eigen only). Index convention of the 9 x 9 tangent: vec(F) is
/// column-major, entry i + 3 J for F(i, J), so A(i + 3 J, k + 3 L) = dP(i, J) / dF(k, L).

#include "core/types.hpp"

#include <Eigen/Core>

namespace fiberfem::core::hyperelastic {

using Mat9 = Eigen::Matrix<double, 9, 9>;

/// Which strain-energy function a region uses.
enum class LawKind {
  neo_hookean,      ///< W = mu/2 (tr Cbar - 3).
  guccione,         ///< W = C/2 (exp(Q) - 1), Q in the Green strain of Cbar in the fiber frame.
  holzapfel_ogden,  ///< Holzapfel and Ogden 2009, in Cbar; needs a sheet direction.
};

/// Parameters of one region's law. Every field has a default; validate() names a bad one.
struct LawParameters {
  LawKind kind = LawKind::neo_hookean;
  /// neo_hookean: shear modulus mu, Pa, > 0. Default 0 (must be set).
  double mu_pa = 0;
  /// guccione: C, Pa, > 0; b_f, b_t, b_fs, dimensionless, >= 0. Defaults: Land et al. 2015
  /// problem 1 (C 2 kPa, b_f 8, b_t 2, b_fs 4).
  double guccione_c_pa = 2000;
  double guccione_b_f = 8;
  double guccione_b_t = 2;
  double guccione_b_fs = 4;
  /// holzapfel_ogden: a, a_f, a_s, a_fs, Pa, >= 0 (a > 0); b, b_f, b_s, b_fs,
  /// dimensionless, > 0. Defaults: Holzapfel and Ogden 2009's published fit.
  double ho_a_pa = 59.0;
  double ho_b = 8.023;
  double ho_a_f_pa = 18472.0;
  double ho_b_f = 16.026;
  double ho_a_s_pa = 2481.0;
  double ho_b_s = 11.120;
  double ho_a_fs_pa = 216.0;
  double ho_b_fs = 11.436;
  /// true: exactly incompressible (a mixed displacement-pressure formulation, the pressure
  /// an unknown of the element); false: the volumetric penalty below. Default false.
  bool incompressible = false;
  /// Bulk modulus kappa of the volumetric penalty U(J) = kappa/4 (J^2 - 1 - 2 ln J), Pa,
  /// > 0 when not incompressible. Default 0 (must be set unless incompressible).
  double bulk_modulus_pa = 0;

  /// Whether the law needs a sheet direction (Holzapfel-Ogden).
  bool needs_sheet() const { return kind == LawKind::holzapfel_ogden; }
  /// Checks the fields of `kind` (the other laws' fields are ignored) and the bulk modulus.
  /// @throws std::invalid_argument naming the scene key (e.g. "material.C must be > 0").
  void validate() const;
};

/// Orthonormal material axes at a point of the reference configuration: fiber f, sheet s,
/// sheet-normal n (n = f x s). Laws that are transversely isotropic (Guccione) give the
/// same answer for any s, n orthogonal to f.
struct MaterialAxes {
  Vec3 f = Vec3::UnitX();
  Vec3 s = Vec3::UnitY();
  Vec3 n = Vec3::UnitZ();
  /// Axes from a fiber and an optional sheet (made orthogonal to the fiber; any
  /// orthogonal direction when `sheet` is zero or parallel to the fiber). Neither needs
  /// unit length. @throws std::invalid_argument when `fiber` is zero.
  static MaterialAxes from(const Vec3& fiber, const Vec3& sheet = Vec3::Zero());
};

/// Energy density, stress and tangent at one point.
struct Response {
  double energy_j_m3 = 0;      ///< Strain energy per reference volume, J/m^3.
  Mat3 P = Mat3::Zero();       ///< First Piola-Kirchhoff stress, Pa.
  Mat9 A = Mat9::Zero();       ///< dP/dF (see the file comment for the index), Pa.
};

/// The isochoric part: W_iso(Cbar), P_iso = dW_iso/dF, A_iso = dP_iso/dF.
/// @param F deformation gradient, det F > 0 (precondition; not checked here).
/// @param with_tangent false leaves A zero (forces only).
Response isochoric_response(const LawParameters& law, const MaterialAxes& axes, const Mat3& F, bool with_tangent);

/// The volumetric penalty U(J) = kappa/4 (J^2 - 1 - 2 ln J) and its first two
/// derivatives in J, for J > 0.
struct Volumetric {
  double U = 0;
  double dU = 0;
  double d2U = 0;
};
Volumetric volumetric_penalty(double bulk_modulus_pa, double J);

/// Adds a volumetric stress pi J F^-T to `r` (pi = U'(J) for a penalty, -p for a mixed
/// formulation's pressure p), with its tangent: d(pi J F^-T)/dF where pi depends on J with
/// slope dpi_dJ (U''(J) for a penalty, 0 for a mixed pressure held fixed). The energy is
/// left to the caller.
void add_volumetric_stress(double pi, double dpi_dJ, const Mat3& F, Response& r, bool with_tangent);

/// The cofactor J F^-T (= dJ/dF), the coupling of a mixed pressure with the displacement.
Mat3 cofactor(const Mat3& F);

/// Adds the active stress of Land et al. 2015: S_a = T_a f0 (x) f0, so P_a = T_a F f0 f0^T,
/// and its tangent (T_a fixed). T_a in Pa. The energy is left to the caller (at fixed T_a,
/// S_a is the derivative of T_a/2 (f0 . C f0 - 1)).
void add_active_stress(double tension_pa, const Vec3& f0, const Mat3& F, Response& r, bool with_tangent);

}  // namespace fiberfem::core::hyperelastic
