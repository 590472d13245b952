#include "core/hyperelastic/quadrature.hpp"

#include <Eigen/Eigenvalues>

#include <cmath>
#include <stdexcept>
#include <string>

namespace fiberfem::core::hyperelastic {

namespace {

// Symmetric rules are given by orbits in barycentric coordinates (l0, l1, l2, l3); the
// reference point is (l1, l2, l3) since vertex 0 is the origin and vertex k is e_k.
void add_tet(TetRule& r, double l1, double l2, double l3, double w) {
  r.points.emplace_back(l1, l2, l3);
  r.weights.push_back(w);
}
// The centroid (orbit of size 1).
void tet_s4(TetRule& r, double w) { add_tet(r, 0.25, 0.25, 0.25, w); }
// One barycentric coordinate 1 - 3a, the three others a (4 points).
void tet_s31(TetRule& r, double a, double w) {
  const double b = 1 - 3 * a;
  add_tet(r, a, a, a, w);
  add_tet(r, b, a, a, w);
  add_tet(r, a, b, a, w);
  add_tet(r, a, a, b, w);
}
// Two barycentric coordinates a, two 1/2 - a (6 points, one per edge).
void tet_s22(TetRule& r, double a, double w) {
  const double b = 0.5 - a;
  add_tet(r, a, a, b, w);
  add_tet(r, a, b, a, w);
  add_tet(r, b, a, a, w);
  add_tet(r, b, b, a, w);
  add_tet(r, b, a, b, w);
  add_tet(r, a, b, b, w);
}

void add_triangle(TriangleRule& r, double l1, double l2, double w) {
  r.points.emplace_back(l1, l2);
  r.weights.push_back(w);
}
// Two barycentric coordinates a, one 1 - 2a (3 points).
void triangle_s21(TriangleRule& r, double a, double w) {
  const double b = 1 - 2 * a;
  add_triangle(r, a, a, w);
  add_triangle(r, b, a, w);
  add_triangle(r, a, b, w);
}

[[noreturn]] void no_tet_rule(int n) {
  throw std::invalid_argument("tetrahedron_rule: no rule with " + std::to_string(n) + " points (1, 4, 11, 14 or " +
                              std::to_string(kReferenceTetPoints) + ")");
}
[[noreturn]] void no_triangle_rule(int n) {
  throw std::invalid_argument("triangle_rule: no rule with " + std::to_string(n) + " points (1, 3, 6 or 7)");
}

TetRule make_tet_rule(int n) {
  TetRule r;
  switch (n) {
    case 1:
      tet_s4(r, 1.0 / 6);
      r.degree = 1;
      break;
    case 4:
      // a = (5 - sqrt 5) / 20, the degree-2 rule (Keast 1986, rule 2).
      tet_s31(r, (5 - std::sqrt(5.0)) / 20, 1.0 / 24);
      r.degree = 2;
      break;
    case 11:
      // Keast 1986 (CMAME 55: 339-348), the 11-point degree-4 rule; the centroid weight
      // is negative. Weights for volume 1/6: -74/5625, 343/45000, 56/2250.
      tet_s4(r, -74.0 / 5625);
      tet_s31(r, 1.0 / 14, 343.0 / 45000);
      tet_s22(r, (1 - std::sqrt(5.0 / 14)) / 4, 56.0 / 2250);
      r.degree = 4;
      break;
    case 14:
      // Walkington's fifth-degree 14-point rule ("Quadrature on simplices of arbitrary
      // dimension", 2000; also Gellert and Harbord 1991), all weights positive.
      tet_s31(r, 0.31088591926330060980, 0.018781320953002641800);
      tet_s31(r, 0.092735250310891226402, 0.012248840519393658257);
      tet_s22(r, 0.045503704125649649492, 0.0070910034628469110730);
      r.degree = 5;
      break;
    default:
      no_tet_rule(n);
  }
  return r;
}

// Gauss-Jacobi points and weights on [0, 1] for the weight (1 - c)^alpha: n points, exact
// for polynomials of degree 2 n - 1 times the weight. Golub-Welsch: the points are the
// eigenvalues of the Jacobi matrix of the monic Jacobi polynomials P^(alpha, 0) on
// [-1, 1], the weights mu0 times the squared first components of the eigenvectors; then
// c = (1 + t) / 2 and w = w_t / 2^(alpha + 1).
void gauss_jacobi(int n, double alpha, std::vector<double>& points, std::vector<double>& weights) {
  const double beta = 0;
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(n, n);
  for (int k = 0; k < n; ++k) {
    const double s = 2.0 * k + alpha + beta;
    J(k, k) = k == 0 ? (beta - alpha) / (alpha + beta + 2) : (beta * beta - alpha * alpha) / (s * (s + 2));
    if (k + 1 < n) {
      const double m = k + 1, t = 2 * m + alpha + beta;
      const double b = 4 * m * (m + alpha) * (m + beta) * (m + alpha + beta) / (t * t * (t + 1) * (t - 1));
      J(k, k + 1) = J(k + 1, k) = std::sqrt(b);
    }
  }
  const double mu0 = std::pow(2.0, alpha + beta + 1) * std::tgamma(alpha + 1) * std::tgamma(beta + 1) /
                     std::tgamma(alpha + beta + 2);
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(J);
  points.resize(static_cast<size_t>(n));
  weights.resize(static_cast<size_t>(n));
  for (int k = 0; k < n; ++k) {
    const double v0 = eig.eigenvectors()(0, k);
    points[static_cast<size_t>(k)] = 0.5 * (1 + eig.eigenvalues()(k));
    weights[static_cast<size_t>(k)] = mu0 * v0 * v0 / std::pow(2.0, alpha + 1);
  }
}

// The conical product rule (Stroud 1971): the cube (a, b, c) in [0, 1]^3 collapses onto
// the tetrahedron by z = c, y = b (1 - c), x = a (1 - b)(1 - c), with Jacobian
// (1 - b)(1 - c)^2, so Gauss-Legendre in a, Gauss-Jacobi with weight (1 - b) in b and
// (1 - c)^2 in c. A polynomial of total degree d in (x, y, z) has degree <= d in each of
// a, b, c after the weights are taken out: n points per direction are exact to 2 n - 1.
TetRule make_conical_rule(int n) {
  std::vector<double> pa, wa, pb, wb, pc, wc;
  gauss_jacobi(n, 0, pa, wa);
  gauss_jacobi(n, 1, pb, wb);
  gauss_jacobi(n, 2, pc, wc);
  TetRule r;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < n; ++k) {
        const double a = pa[static_cast<size_t>(i)], b = pb[static_cast<size_t>(j)], c = pc[static_cast<size_t>(k)];
        add_tet(r, a * (1 - b) * (1 - c), b * (1 - c), c,
                wa[static_cast<size_t>(i)] * wb[static_cast<size_t>(j)] * wc[static_cast<size_t>(k)]);
      }
  r.degree = 2 * n - 1;
  return r;
}

constexpr int kReferencePointsPerDirection = 5;
static_assert(kReferencePointsPerDirection * kReferencePointsPerDirection * kReferencePointsPerDirection ==
              kReferenceTetPoints);

TriangleRule make_triangle_rule(int n) {
  TriangleRule r;
  switch (n) {
    case 1:
      add_triangle(r, 1.0 / 3, 1.0 / 3, 0.5);
      r.degree = 1;
      break;
    case 3:
      triangle_s21(r, 1.0 / 6, 1.0 / 6);
      r.degree = 2;
      break;
    case 6:
      // Cowper 1973 / Dunavant 1985, degree 4 (weights for area 1/2).
      triangle_s21(r, 0.091576213509770743460, 0.054975871827660933819);
      triangle_s21(r, 0.44594849091596488632, 0.11169079483900573285);
      r.degree = 4;
      break;
    case 7: {
      // Radon's degree-5 rule: the centroid and a = (6 -+ sqrt 15) / 21.
      const double s15 = std::sqrt(15.0);
      add_triangle(r, 1.0 / 3, 1.0 / 3, 9.0 / 80);
      triangle_s21(r, (6 - s15) / 21, (155 - s15) / 2400);
      triangle_s21(r, (6 + s15) / 21, (155 + s15) / 2400);
      r.degree = 5;
      break;
    }
    default:
      no_triangle_rule(n);
  }
  return r;
}

}  // namespace

const TetRule& tetrahedron_rule(int num_points) {
  // Built once each (thread-safe static initialisation), then shared read-only.
  static const TetRule r1 = make_tet_rule(1), r4 = make_tet_rule(4), r11 = make_tet_rule(11),
                       r14 = make_tet_rule(14), reference = make_conical_rule(kReferencePointsPerDirection);
  switch (num_points) {
    case 1: return r1;
    case 4: return r4;
    case 11: return r11;
    case 14: return r14;
    case kReferenceTetPoints: return reference;
    default: no_tet_rule(num_points);
  }
}

const TriangleRule& triangle_rule(int num_points) {
  static const TriangleRule r1 = make_triangle_rule(1), r3 = make_triangle_rule(3), r6 = make_triangle_rule(6),
                            r7 = make_triangle_rule(7);
  switch (num_points) {
    case 1: return r1;
    case 3: return r3;
    case 6: return r6;
    case 7: return r7;
    default: no_triangle_rule(num_points);
  }
}

}  // namespace fiberfem::core::hyperelastic
