#pragma once
/// @file The corotated linear tetrahedron of the dynamic step in closed form: stress,
/// forces, energy and warped stiffness blocks from the rest gradients, the fiber and five
/// material constants, without a stored 12 x 12 K^e.
///
/// A transversely isotropic tensor with unit fiber f (PHYSICS.md section 2) is, in
/// Spencer's form (Spencer 1984; Bonet and Burton 1998),
///
///   C_ijkl = lambda d_ij d_kl + mu_T (d_ik d_jl + d_il d_jk)
///          + alpha (f_i f_j d_kl + d_ij f_k f_l)
///          + gamma (f_i f_k d_jl + f_i f_l d_jk + d_ik f_j f_l + d_il f_j f_k)
///          + beta f_i f_j f_k f_l,
///
/// with, from the local Voigt constants (fiber along local 3): lambda = C12,
/// mu_T = C44 = (C11 - C12)/2, alpha = C13 - C12, gamma = C55 - C44,
/// beta = C33 - C11 - 2 alpha - 4 gamma. It equals T(Q)^T C T(Q) of PHYSICS.md section 3
/// for any frame Q whose third row is f, so the frame's choice of m1, m2 cannot matter.
///
/// With gradients g_a of the shape functions (g_a = row a-1 of Dm^-1, g_0 = -(g_1+g_2+g_3))
/// and volume V, K^e = V B^T C_g B has the node blocks K_ab[i][k] = V g_aj C_ijkl g_bl, and
/// rotating by R (R K R^T) rotates the vectors in them: with p_a = R g_a, h = R f,
/// s_a = f . g_a, w_a = s_a h and G_ab = g_a . g_b,
///
///   R K_ab R^T / V = (lambda p_a + alpha w_a) p_b^T + alpha p_a w_b^T
///                  + (mu_T p_b + gamma w_b) p_a^T + gamma p_b w_a^T
///                  + (mu_T G_ab + gamma s_a s_b) I + (gamma G_ab + beta s_a s_b) h h^T.
///
/// The corotated force f = -R K (R^T x - X) needs no K either: K u = V B^T C_g eps with
/// eps = sym(R^T F) - I exactly for a linear tetrahedron, so f_a = -V R sigma g_a and the
/// energy is V sigma : eps / 2. Per element this reads 22 numbers instead of 144 and
/// costs about 600 multiply-adds. tests/core/spencer_element_test.cpp checks every
/// formula against element_stiffness and corotated_force (spencer_force_lanes against
/// spencer_force and a long double evaluation).

#include "core/material.hpp"
#include "core/types.hpp"

namespace fiberfem::core {

/// Spencer's five constants of a transversely isotropic material, Pa.
struct SpencerConstants {
  double lambda = 0;  ///< C12.
  double mu_t = 0;    ///< Transverse shear modulus C44 = (C11 - C12)/2.
  double alpha = 0;   ///< C13 - C12.
  double gamma = 0;   ///< C55 - C44 (fiber-plane minus transverse shear).
  double beta = 0;    ///< C33 - C11 - 2 alpha - 4 gamma.
  /// From a material's local stiffness (isotropic: alpha = gamma = beta = 0 to round-off).
  static SpencerConstants of(const Material& m);
  /// All five multiplied by s.
  SpencerConstants scaled(double s) const { return {s * lambda, s * mu_t, s * alpha, s * gamma, s * beta}; }
};

/// What the dynamic step reads of an element: rest-shape inverse, unit fiber, volume.
struct SpencerElement {
  Mat3 Dm;           ///< Rest edges [X1-X0, X2-X0, X3-X0], m (F = I + (Ds - Dm) Dm^-1).
  Mat3 Dm_inv;       ///< Rest-shape inverse, 1/m (rows: gradients of shape functions 1..3).
  Vec3 fiber;        ///< Unit fiber direction (ignored by isotropic constants).
  double volume = 0; ///< Rest volume, m^3.
};

/// Gradients of the four shape functions (columns), 1/m.
inline Eigen::Matrix<double, 3, 4> shape_gradients(const Mat3& Dm_inv) {
  Eigen::Matrix<double, 3, 4> g;
  g.rightCols<3>() = Dm_inv.transpose();
  g.col(0) = -(g.col(1) + g.col(2) + g.col(3));
  return g;
}

/// Cauchy-like stress sigma = C : eps of the linear law for a symmetric strain `eps`
/// (tensor components, not engineering shear), in the frame where the fiber is `f`.
inline Mat3 spencer_stress(const SpencerConstants& c, const Vec3& f, const Mat3& eps) {
  const Vec3 ef = eps * f;
  const double tr = eps.trace(), fef = f.dot(ef);
  Mat3 s = (2.0 * c.mu_t) * eps;
  s.diagonal().array() += c.lambda * tr + c.alpha * fef;
  const Mat3 ff = f * f.transpose();
  s += (c.alpha * tr + c.beta * fef) * ff;
  s.noalias() += (2.0 * c.gamma) * (f * ef.transpose() + ef * f.transpose());
  return s;
}

/// Corotated strain sym(R^T F) - I of an element.
inline Mat3 corotated_strain(const Mat3& R, const Mat3& F) {
  const Mat3 S = R.transpose() * F;
  Mat3 eps = 0.5 * (S + S.transpose());
  eps.diagonal().array() -= 1.0;
  return eps;
}

/// The ten upper node blocks of c R K^e R^T, for one element (T = double) or several at
/// once: T is double or a SIMD vector of doubles (one element per
/// lane; GCC/Clang vector extensions), so every operation below is one vector
/// instruction for all lanes. Inputs per lane: k = {lambda, mu_T, alpha, gamma, beta}
/// times c V; R and Dm_inv row-major (entry (r, c) at 3 r + c); f the unit fiber. Output:
/// block k = ElementBatch order ((0,0), (0,1), .., (3,3)), entry (i, j) at out[9 k + 3 i + j].
template <class T>
inline void spencer_upper_blocks(const T k[5], const T R[9], const T Dm_inv[9], const T f[3], T out[90]) {
  T g[4][3], p[4][3], s[4], w[4][3], A[4][3], B[4][3], ap[4][3], gp[4][3], h[3], hh[3][3];
  for (int c = 0; c < 3; ++c) {
    g[1][c] = Dm_inv[c];
    g[2][c] = Dm_inv[3 + c];
    g[3][c] = Dm_inv[6 + c];
    g[0][c] = -(g[1][c] + g[2][c] + g[3][c]);
    h[c] = R[3 * c] * f[0] + R[3 * c + 1] * f[1] + R[3 * c + 2] * f[2];
  }
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) hh[i][j] = h[i] * h[j];
  for (int a = 0; a < 4; ++a) {
    s[a] = f[0] * g[a][0] + f[1] * g[a][1] + f[2] * g[a][2];
    for (int c = 0; c < 3; ++c) {
      p[a][c] = R[3 * c] * g[a][0] + R[3 * c + 1] * g[a][1] + R[3 * c + 2] * g[a][2];
      w[a][c] = s[a] * h[c];
      A[a][c] = k[0] * p[a][c] + k[2] * w[a][c];
      B[a][c] = k[1] * p[a][c] + k[3] * w[a][c];
      ap[a][c] = k[2] * p[a][c];
      gp[a][c] = k[3] * p[a][c];
    }
  }
  int blk = 0;
  for (int a = 0; a < 4; ++a)
    for (int b = a; b < 4; ++b, ++blk) {
      const T G = g[a][0] * g[b][0] + g[a][1] * g[b][1] + g[a][2] * g[b][2], ss = s[a] * s[b];
      const T e = k[3] * G + k[4] * ss, d = k[1] * G + k[3] * ss;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
          T v = A[a][i] * p[b][j] + ap[a][i] * w[b][j] + B[b][i] * p[a][j] + gp[b][i] * w[a][j] + e * hh[i][j];
          if (i == j) v += d;
          out[9 * blk + 3 * i + j] = v;
        }
    }
}

/// spencer_force for one element (T = double) or one per lane (T a SIMD vector of doubles,
/// as in spencer_upper_blocks). Inputs per lane: k = {lambda, mu_T, alpha, gamma, beta}
/// times V; R, Dm_inv and D = Ds - Dm row-major (D's column j is
/// (x_{j+1} - x_0) - Dm.col(j), so F = I + D Dm^-1); f the unit fiber. Output:
/// fe[3 a + c] = component c of f_a = -V R sigma g_a, and energy = V sigma : eps / 2
/// (assigned, not added). The strain is sym(R^T D Dm^-1) + sym(R^T) - I, never formed
/// through I + D Dm^-1: its round-off is relative to the displacement, and it is exactly
/// zero at rest (D = 0, R = I). The stress is kept negated (S = -sigma) so the forces
/// need no sign flips. About 160 multiplies per call.
template <class T>
inline void spencer_force_lanes(const T k[5], const T R[9], const T Dm_inv[9], const T D[9], const T f[3], T fe[12],
                                T& energy) {
  T M[3][3], N[3][3], e[3][3], ef[3], u[3], S[3][3], P[3][3];
  // M = R^T D, N = M Dm^-1 = R^T (F - I).
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) M[i][j] = R[i] * D[j] + R[3 + i] * D[3 + j] + R[6 + i] * D[6 + j];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) N[i][j] = M[i][0] * Dm_inv[j] + M[i][1] * Dm_inv[3 + j] + M[i][2] * Dm_inv[6 + j];
  for (int i = 0; i < 3; ++i) {
    e[i][i] = N[i][i] + (R[4 * i] - 1.0);
    for (int j = i + 1; j < 3; ++j) e[i][j] = e[j][i] = 0.5 * ((N[i][j] + N[j][i]) + (R[3 * i + j] + R[3 * j + i]));
  }
  // -sigma = -2 mu_T eps - (lambda tr + alpha fef) I - (f u^T + u f^T),
  // u = (alpha tr + beta fef) / 2 f + 2 gamma eps f (spencer_stress).
  for (int i = 0; i < 3; ++i) ef[i] = e[i][0] * f[0] + e[i][1] * f[1] + e[i][2] * f[2];
  const T tr = e[0][0] + e[1][1] + e[2][2], fef = f[0] * ef[0] + f[1] * ef[1] + f[2] * ef[2];
  const T m2 = -2.0 * k[1], g2 = -2.0 * k[3];
  const T nd = -(k[0] * tr + k[2] * fef), hb = -0.5 * (k[2] * tr + k[4] * fef);
  for (int i = 0; i < 3; ++i) u[i] = hb * f[i] + g2 * ef[i];  // -u
  for (int i = 0; i < 3; ++i) {
    const T fu = f[i] * u[i];
    S[i][i] = m2 * e[i][i] + nd + (fu + fu);
    for (int j = i + 1; j < 3; ++j) S[i][j] = S[j][i] = m2 * e[i][j] + (f[i] * u[j] + u[i] * f[j]);
  }
  // sigma : eps / 2 with sigma = -S (k carries V).
  energy = -0.5 * (S[0][0] * e[0][0] + S[1][1] * e[1][1] + S[2][2] * e[2][2]) -
           (S[0][1] * e[0][1] + S[0][2] * e[0][2] + S[1][2] * e[1][2]);
  // P = R S = -V R sigma; f_a = P g_a for a = 1..3 (rows of Dm^-1), f_0 = -(f_1 + f_2 + f_3).
  for (int c = 0; c < 3; ++c)
    for (int j = 0; j < 3; ++j) P[c][j] = R[3 * c] * S[0][j] + R[3 * c + 1] * S[1][j] + R[3 * c + 2] * S[2][j];
  for (int c = 0; c < 3; ++c) {
    for (int a = 1; a < 4; ++a)
      fe[3 * a + c] = P[c][0] * Dm_inv[3 * a - 3] + P[c][1] * Dm_inv[3 * a - 2] + P[c][2] * Dm_inv[3 * a - 1];
    fe[c] = -(fe[3 + c] + fe[6 + c] + fe[9 + c]);
  }
}

/// Elastic force f_a = -V R sigma g_a of the four nodes (12), with sigma the stress of the
/// corotated strain; adds V sigma : eps / 2 (the energy, J) to `energy`.
inline void spencer_force(const SpencerConstants& c, const SpencerElement& el, const Mat3& R, const Mat3& F,
                          Vec12& fe, double& energy) {
  const Mat3 eps = corotated_strain(R, F);
  const Mat3 sigma = spencer_stress(c, el.fiber, eps);
  energy += 0.5 * el.volume * sigma.cwiseProduct(eps).sum();
  // P = -V R sigma; f_a = P g_a for a = 1..3 (rows of Dm^-1), f_0 = -(f_1 + f_2 + f_3).
  const Mat3 P = (-el.volume) * (R * sigma);
  const Mat3 f123 = P * el.Dm_inv.transpose();
  fe.segment<3>(3) = f123.col(0);
  fe.segment<3>(6) = f123.col(1);
  fe.segment<3>(9) = f123.col(2);
  fe.segment<3>(0) = -(f123.col(0) + f123.col(1) + f123.col(2));
}

/// Elastic energy V sigma : eps / 2 of an element, J.
inline double spencer_energy(const SpencerConstants& c, const SpencerElement& el, const Mat3& R, const Mat3& F) {
  const Mat3 eps = corotated_strain(R, F);
  return 0.5 * el.volume * spencer_stress(c, el.fiber, eps).cwiseProduct(eps).sum();
}

}  // namespace fiberfem::core
