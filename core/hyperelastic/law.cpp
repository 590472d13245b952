// Hyperelastic laws: the formulas and their tests are listed in docs/hyperelastic-laws.md.
#include "core/hyperelastic/law.hpp"

#include <Eigen/LU>

#include <cmath>
#include <stdexcept>
#include <string>

namespace fiberfem::core::hyperelastic {
namespace {

using Vec9 = Eigen::Matrix<double, 9, 1>;

// Fourth-order tensors are 9 x 9 matrices in the file's column-major convention: entry
// (I + 3 J, K + 3 L) holds T_IJKL, so vec(X)_(I + 3 J) = X(I, J) and the dyadic product
// (X (x) Y)_IJKL = X_IJ Y_KL is vec(X) vec(Y)^T.
Eigen::Map<const Vec9> vec(const Mat3& X) { return Eigen::Map<const Vec9>(X.data()); }

Mat3 sym_dyad(const Vec3& a, const Vec3& b) { return 0.5 * (a * b.transpose() + b * a.transpose()); }

// ---------------------------------------------------------------------------------------
// The laws, each as psi(Ebar) with Ebar = (Cbar - I)/2, Cbar = J^(-2/3) C:
//   Sbar = dpsi/dEbar (= 2 dpsi/dCbar), CCbar = d2psi/dEbar2 (= 4 d2psi/dCbar2),
// CCbar with both minor symmetries so that the push-forward below may contract it with
// F^T dF unsymmetrised.
struct IsochoricDerivatives {
  double psi = 0;
  Mat3 S = Mat3::Zero();
  Mat9 CC = Mat9::Zero();
};

// exp(x) with its first and second derivatives, continued past kExpCap by its second-order
// Taylor polynomial: identical to exp in every realistic state (stresses of C e^100 are
// beyond any heart), finite and still consistent (value, slope, curvature) far beyond, so
// a wild Newton iterate gets a huge but finite stress instead of inf and then NaN.
constexpr double kExpCap = 100;
struct GuardedExp {
  double value, d1, d2;
};
GuardedExp guarded_exp(double x) {
  if (x <= kExpCap) {
    const double e = std::exp(x);
    return {e, e, e};
  }
  const double e = std::exp(kExpCap), t = x - kExpCap;
  return {e * (1 + t + 0.5 * t * t), e * (1 + t), e};
}

// A term psi(x) of a linear invariant x = M : Ebar (M symmetric):
//   dpsi/dEbar = psi'(x) M,  d2psi/dEbar2 = psi''(x) M (x) M.
struct ScalarTerm {
  double psi, d1, d2;
};
void add_term(const ScalarTerm& t, const Mat3& M, bool with_tangent, IsochoricDerivatives& d) {
  d.psi += t.psi;
  d.S += t.d1 * M;
  if (with_tangent) d.CC.noalias() += t.d2 * vec(M) * vec(M).transpose();
}

// a/(2b) (exp(b x) - 1): psi' = a/2 exp(b x), psi'' = a b/2 exp(b x).
ScalarTerm exponential_term(double a, double b, double x) {
  const GuardedExp e = guarded_exp(b * x);
  return {a / (2 * b) * (e.value - 1), 0.5 * a * e.d1, 0.5 * a * b * e.d2};
}

// a/(2b) (exp(b x^2) - 1): psi' = a x exp(b x^2), psi'' = a (exp + 2 b x^2 exp'').
ScalarTerm exponential_square_term(double a, double b, double x) {
  const GuardedExp e = guarded_exp(b * x * x);
  return {a / (2 * b) * (e.value - 1), a * x * e.d1, a * (e.d1 + 2 * b * x * x * e.d2)};
}

// Neo-Hookean: psi = mu/2 (I1bar - 3), I1bar - 3 = 2 I : Ebar.
IsochoricDerivatives neo_hookean(const LawParameters& law, const Mat3& Ebar, bool with_tangent) {
  IsochoricDerivatives d;
  const double x = 2 * Ebar.trace();
  add_term({0.5 * law.mu_pa * x, 0.5 * law.mu_pa, 0}, 2 * Mat3::Identity(), with_tangent, d);
  return d;
}

// Guccione (Land et al. 2015): psi = C/2 (exp(Q) - 1) with
//   Q = b_f E_ff^2 + b_t (E_ss^2 + E_nn^2 + 2 E_sn^2) + b_fs (2 E_fs^2 + 2 E_fn^2),
// E_ab = a . Ebar b = M_ab : Ebar for the structure tensors M_ab = sym(a (x) b). So
//   Q = sum_k w_k e_k^2,  dQ = sum_k 2 w_k e_k M_k,  d2Q = sum_k 2 w_k M_k (x) M_k,
//   dpsi = C/2 e^Q dQ,    d2psi = C/2 e^Q (dQ (x) dQ + d2Q).
IsochoricDerivatives guccione(const LawParameters& law, const MaterialAxes& ax, const Mat3& Ebar, bool with_tangent) {
  const Mat3 M[6] = {ax.f * ax.f.transpose(), ax.s * ax.s.transpose(), ax.n * ax.n.transpose(),
                     sym_dyad(ax.s, ax.n),    sym_dyad(ax.f, ax.s),    sym_dyad(ax.f, ax.n)};
  const double w[6] = {law.guccione_b_f,      law.guccione_b_t,      law.guccione_b_t,
                       2 * law.guccione_b_t,  2 * law.guccione_b_fs, 2 * law.guccione_b_fs};
  double Q = 0;
  Mat3 dQ = Mat3::Zero();
  double e[6];
  for (int k = 0; k < 6; ++k) {
    e[k] = (M[k].array() * Ebar.array()).sum();
    Q += w[k] * e[k] * e[k];
    dQ += 2 * w[k] * e[k] * M[k];
  }
  const GuardedExp g = guarded_exp(Q);
  const double half_c = 0.5 * law.guccione_c_pa;
  IsochoricDerivatives d;
  d.psi = half_c * (g.value - 1);
  d.S = half_c * g.d1 * dQ;
  if (with_tangent) {
    d.CC.noalias() = half_c * g.d2 * vec(dQ) * vec(dQ).transpose();
    for (int k = 0; k < 6; ++k) d.CC.noalias() += (half_c * g.d1 * 2 * w[k]) * vec(M[k]) * vec(M[k]).transpose();
  }
  return d;
}

// Holzapfel-Ogden 2009 in the modified invariants, each a linear invariant of Ebar:
//   I1bar - 3 = 2 I : Ebar,  I4f - 1 = 2 f f^T : Ebar,  I4s - 1 = 2 s s^T : Ebar,
//   I8fs = 2 sym(f s^T) : Ebar  (f . s = 0).
// The fiber and sheet terms act only in tension (I4 > 1); (I4 - 1)^2 makes the switch C^1.
IsochoricDerivatives holzapfel_ogden(const LawParameters& law, const MaterialAxes& ax, const Mat3& Ebar,
                                     bool with_tangent) {
  IsochoricDerivatives d;
  const Mat3 M1 = 2 * Mat3::Identity();
  const Mat3 Mf = 2 * ax.f * ax.f.transpose();
  const Mat3 Ms = 2 * ax.s * ax.s.transpose();
  const Mat3 Mfs = 2 * sym_dyad(ax.f, ax.s);
  add_term(exponential_term(law.ho_a_pa, law.ho_b, 2 * Ebar.trace()), M1, with_tangent, d);
  const double x_f = (Mf.array() * Ebar.array()).sum();
  if (x_f > 0) add_term(exponential_square_term(law.ho_a_f_pa, law.ho_b_f, x_f), Mf, with_tangent, d);
  const double x_s = (Ms.array() * Ebar.array()).sum();
  if (x_s > 0) add_term(exponential_square_term(law.ho_a_s_pa, law.ho_b_s, x_s), Ms, with_tangent, d);
  const double x_fs = (Mfs.array() * Ebar.array()).sum();
  add_term(exponential_square_term(law.ho_a_fs_pa, law.ho_b_fs, x_fs), Mfs, with_tangent, d);
  return d;
}

IsochoricDerivatives law_derivatives(const LawParameters& law, const MaterialAxes& axes, const Mat3& Ebar,
                                     bool with_tangent) {
  switch (law.kind) {
    case LawKind::neo_hookean: return neo_hookean(law, Ebar, with_tangent);
    case LawKind::guccione: return guccione(law, axes, Ebar, with_tangent);
    case LawKind::holzapfel_ogden: return holzapfel_ogden(law, axes, Ebar, with_tangent);
  }
  throw std::logic_error("hyperelastic law: unknown LawKind");
}

// ---------------------------------------------------------------------------------------
// The isochoric projection (Holzapfel, Nonlinear Solid Mechanics, 6.88 and 6.168).
// With Cbar = J^(-2/3) C, dCbar/dC = J^(-2/3) P^T where P = II - 1/3 C^-1 (x) C:
//   S_iso = J^(-2/3) Dev(Sbar),  Dev(X) = X - 1/3 (X : C) C^-1,
//   CC_iso = P : CCbar_J : P^T + 2/3 Tr(J^(-2/3) Sbar) Ptilde
//            - 2/3 (C^-1 (x) S_iso + S_iso (x) C^-1),
// with CCbar_J = J^(-4/3) CCbar, Tr(X) = X : C and
//   Ptilde = C^-1 (.) C^-1 - 1/3 C^-1 (x) C^-1,  (A (.) B)_IJKL = (A_IK B_JL + A_IL B_JK)/2.
struct IsochoricStress {
  Mat3 S;
  Mat9 CC;
};

Mat9 projected(const Mat9& X, const Vec9& ci, const Vec9& c) {
  // (II - 1/3 ci c^T) X (II - 1/3 c ci^T); X already has minor symmetries, so the
  // symmetric identity II acts on it as the plain identity.
  const Vec9 Xc = X * c;
  const Vec9 cX = X.transpose() * c;
  const double cXc = c.dot(Xc);
  Mat9 out = X;
  out.noalias() -= (1.0 / 3.0) * ci * cX.transpose();
  out.noalias() -= (1.0 / 3.0) * Xc * ci.transpose();
  out.noalias() += (cXc / 9.0) * ci * ci.transpose();
  return out;
}

Mat9 sym_product(const Mat3& A) {
  Mat9 out;
  for (int L = 0; L < 3; ++L)
    for (int K = 0; K < 3; ++K)
      for (int J = 0; J < 3; ++J)
        for (int I = 0; I < 3; ++I) out(I + 3 * J, K + 3 * L) = 0.5 * (A(I, K) * A(J, L) + A(I, L) * A(J, K));
  return out;
}

IsochoricStress isochoric_projection(const IsochoricDerivatives& d, const Mat3& C, const Mat3& Cinv, double J,
                                     bool with_tangent) {
  const double j23 = std::pow(J, -2.0 / 3.0);
  const Mat3 Sbar_J = j23 * d.S;
  const double tr = (Sbar_J.array() * C.array()).sum();
  IsochoricStress out;
  out.S = Sbar_J - (tr / 3.0) * Cinv;
  if (!with_tangent) return out;
  const Vec9 ci = vec(Cinv), c = vec(C), s = vec(out.S);
  out.CC = projected(j23 * j23 * d.CC, ci, c);
  out.CC += (2.0 / 3.0) * tr * (sym_product(Cinv) - (1.0 / 3.0) * ci * ci.transpose());
  out.CC.noalias() -= (2.0 / 3.0) * (ci * s.transpose() + s * ci.transpose());
  return out;
}

// Push to the first Piola-Kirchhoff stress: P = F S and
//   A(iJ, kL) = dP_iJ / dF_kL = delta_ik S_JL + F_iM CC_MJNL F_kN.
Mat9 first_piola_tangent(const Mat3& F, const Mat3& S, const Mat9& CC) {
  // B(M + 3 J, k + 3 L) = sum_N CC(M + 3 J, N + 3 L) F_kN, then A = F applied on the left.
  Mat9 B;
  for (int L = 0; L < 3; ++L) B.middleCols<3>(3 * L).noalias() = CC.middleCols<3>(3 * L) * F.transpose();
  Mat9 A;
  for (int J = 0; J < 3; ++J) A.middleRows<3>(3 * J).noalias() = F * B.middleRows<3>(3 * J);
  for (int L = 0; L < 3; ++L)
    for (int J = 0; J < 3; ++J)
      for (int i = 0; i < 3; ++i) A(i + 3 * J, i + 3 * L) += S(J, L);
  return A;
}

void require(bool ok, const char* message) {
  if (!ok) throw std::invalid_argument(message);
}
bool positive(double x) { return x > 0 && std::isfinite(x); }
bool non_negative(double x) { return x >= 0 && std::isfinite(x); }

}  // namespace

void LawParameters::validate() const {
  switch (kind) {
    case LawKind::neo_hookean: require(positive(mu_pa), "material.mu must be > 0 (Pa)"); break;
    case LawKind::guccione:
      require(positive(guccione_c_pa), "material.C must be > 0 (Pa)");
      require(non_negative(guccione_b_f), "material.b_f must be >= 0");
      require(non_negative(guccione_b_t), "material.b_t must be >= 0");
      require(non_negative(guccione_b_fs), "material.b_fs must be >= 0");
      break;
    case LawKind::holzapfel_ogden:
      require(positive(ho_a_pa), "material.a must be > 0 (Pa)");
      require(positive(ho_b), "material.b must be > 0");
      require(non_negative(ho_a_f_pa), "material.a_f must be >= 0 (Pa)");
      require(positive(ho_b_f), "material.b_f must be > 0");
      require(non_negative(ho_a_s_pa), "material.a_s must be >= 0 (Pa)");
      require(positive(ho_b_s), "material.b_s must be > 0");
      require(non_negative(ho_a_fs_pa), "material.a_fs must be >= 0 (Pa)");
      require(positive(ho_b_fs), "material.b_fs must be > 0");
      break;
    default: throw std::invalid_argument("material.law is not a known law");
  }
  if (!incompressible)
    require(positive(bulk_modulus_pa), "material.bulk_modulus must be > 0 (Pa) unless material.incompressible");
}

MaterialAxes MaterialAxes::from(const Vec3& fiber, const Vec3& sheet) {
  const double length = fiber.norm();
  if (!(length > 0) || !std::isfinite(length)) throw std::invalid_argument("material axes: the fiber direction is zero");
  MaterialAxes ax;
  ax.f = fiber / length;
  Vec3 s = sheet - sheet.dot(ax.f) * ax.f;
  // Parallel (to rounding) or absent sheet: any unit vector orthogonal to the fiber.
  const bool usable = std::isfinite(s.norm()) && s.norm() > 1e-9 * sheet.norm() && sheet.norm() > 0;
  ax.s = usable ? Vec3(s.normalized()) : Vec3(ax.f.unitOrthogonal());
  ax.n = ax.f.cross(ax.s);
  return ax;
}

Response isochoric_response(const LawParameters& law, const MaterialAxes& axes, const Mat3& F, bool with_tangent) {
  const Mat3 C = F.transpose() * F;
  const double J = F.determinant();
  const Mat3 Cinv = C.inverse();
  const Mat3 Ebar = 0.5 * (std::pow(J, -2.0 / 3.0) * C - Mat3::Identity());
  const IsochoricDerivatives d = law_derivatives(law, axes, Ebar, with_tangent);
  const IsochoricStress iso = isochoric_projection(d, C, Cinv, J, with_tangent);
  Response r;
  r.energy_j_m3 = d.psi;
  r.P = F * iso.S;
  if (with_tangent) r.A = first_piola_tangent(F, iso.S, iso.CC);
  return r;
}

// U(J) = kappa/4 (J^2 - 1 - 2 ln J): U' = kappa/2 (J - 1/J), U'' = kappa/2 (1 + 1/J^2).
// Zero with zero slope at J = 1, convex, and infinite as J -> 0 (resists inversion).
Volumetric volumetric_penalty(double bulk_modulus_pa, double J) {
  const double k = bulk_modulus_pa;
  return {0.25 * k * (J * J - 1 - 2 * std::log(J)), 0.5 * k * (J - 1 / J), 0.5 * k * (1 + 1 / (J * J))};
}

// Cofactor columns: cof(F) e_I = F e_(I+1) x F e_(I+2), so F^T cof(F) = det(F) I; defined
// for singular F too.
Mat3 cofactor(const Mat3& F) {
  Mat3 cof;
  cof.col(0) = F.col(1).cross(F.col(2));
  cof.col(1) = F.col(2).cross(F.col(0));
  cof.col(2) = F.col(0).cross(F.col(1));
  return cof;
}

// P_vol = pi G with G = cof(F) = J F^-T = dJ/dF. With cof_iJ = 1/2 e_ikm e_JLN F_kL F_mN,
//   dG_iJ/dF_kL = e_ikm e_JLN F_mN   (= J (F^-T_iJ F^-T_kL - F^-T_iL F^-T_kJ)),
//   dP_vol(iJ)/dF(kL) = dpi_dJ G_iJ G_kL + pi e_ikm e_JLN F_mN,
// written without a division so that it stays finite as J -> 0.
void add_volumetric_stress(double pi, double dpi_dJ, const Mat3& F, Response& r, bool with_tangent) {
  const Mat3 G = cofactor(F);
  r.P += pi * G;
  if (!with_tangent) return;
  r.A.noalias() += dpi_dJ * vec(G) * vec(G).transpose();
  // Levi-Civita symbol of distinct a, b (the third index is 3 - a - b).
  const auto eps = [](int a, int b) { return (b - a + 3) % 3 == 1 ? 1.0 : -1.0; };
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) {
      if (i == k) continue;
      for (int J = 0; J < 3; ++J)
        for (int L = 0; L < 3; ++L) {
          if (J == L) continue;
          r.A(i + 3 * J, k + 3 * L) += pi * eps(i, k) * eps(J, L) * F(3 - i - k, 3 - J - L);
        }
    }
}

// S_a = T_a f0 (x) f0, P_a = F S_a, and with T_a fixed dP_a(iJ)/dF(kL) = delta_ik S_a,JL.
void add_active_stress(double tension_pa, const Vec3& f0, const Mat3& F, Response& r, bool with_tangent) {
  const Mat3 Sa = tension_pa * f0 * f0.transpose();
  r.P.noalias() += F * Sa;
  if (!with_tangent) return;
  for (int L = 0; L < 3; ++L)
    for (int J = 0; J < 3; ++J)
      for (int i = 0; i < 3; ++i) r.A(i + 3 * J, i + 3 * L) += Sa(J, L);
}

}  // namespace fiberfem::core::hyperelastic
