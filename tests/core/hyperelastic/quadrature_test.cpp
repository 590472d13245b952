// Quadrature rules (core/hyperelastic/quadrature.hpp): every monomial up to the stated
// degree integrated exactly against the closed form over the reference simplex, and some
// monomial of the next degree not (so the stated degree is the true one); points inside,
// weights summing to the measure, the signs of the weights, unknown counts refused.

#include "core/hyperelastic/quadrature.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

namespace hyper = fiberfem::core::hyperelastic;
using fiberfem::testing::expect_invalid;

namespace {

double factorial(int n) { return n <= 1 ? 1.0 : n * factorial(n - 1); }

// The integral of x^a y^b z^c over the reference tetrahedron: a! b! c! / (a + b + c + 3)!
// (the Dirichlet integral); over the reference triangle x^a y^b: a! b! / (a + b + 2)!.
double tet_monomial(int a, int b, int c) { return factorial(a) * factorial(b) * factorial(c) / factorial(a + b + c + 3); }
double triangle_monomial(int a, int b) { return factorial(a) * factorial(b) / factorial(a + b + 2); }

// Largest relative error of the rule over the monomials of total degree exactly d.
double worst_tet_error(const hyper::TetRule& r, int d) {
  double worst = 0;
  for (int a = 0; a <= d; ++a)
    for (int b = 0; a + b <= d; ++b) {
      const int c = d - a - b;
      double q = 0;
      for (size_t i = 0; i < r.points.size(); ++i)
        q += r.weights[i] * std::pow(r.points[i].x(), a) * std::pow(r.points[i].y(), b) * std::pow(r.points[i].z(), c);
      worst = std::max(worst, std::abs(q - tet_monomial(a, b, c)) / tet_monomial(a, b, c));
    }
  return worst;
}

double worst_triangle_error(const hyper::TriangleRule& r, int d) {
  double worst = 0;
  for (int a = 0; a <= d; ++a) {
    const int b = d - a;
    double q = 0;
    for (size_t i = 0; i < r.points.size(); ++i)
      q += r.weights[i] * std::pow(r.points[i].x(), a) * std::pow(r.points[i].y(), b);
    worst = std::max(worst, std::abs(q - triangle_monomial(a, b)) / triangle_monomial(a, b));
  }
  return worst;
}

}  // namespace

TEST(TetrahedronRule, ExactToItsDegreeAndNotBeyond) {
  const std::pair<int, int> expected[] = {{1, 1}, {4, 2}, {11, 4}, {14, 5}, {hyper::kReferenceTetPoints, 9}};
  for (const auto& [n, degree] : expected) {
    const hyper::TetRule& r = hyper::tetrahedron_rule(n);
    ASSERT_EQ(static_cast<int>(r.points.size()), n);
    ASSERT_EQ(r.weights.size(), r.points.size());
    EXPECT_EQ(r.degree, degree) << n;
    for (int d = 0; d <= degree; ++d) EXPECT_LT(worst_tet_error(r, d), 1e-12) << n << " points, degree " << d;
    EXPECT_GT(worst_tet_error(r, degree + 1), 1e-6) << n << " points integrate degree " << degree + 1 << " too";
  }
}

TEST(TetrahedronRule, PointsInsideAndWeightSigns) {
  for (int n : {1, 4, 11, 14, hyper::kReferenceTetPoints}) {
    const hyper::TetRule& r = hyper::tetrahedron_rule(n);
    double sum = 0;
    for (size_t i = 0; i < r.points.size(); ++i) {
      const Eigen::Vector3d& p = r.points[i];
      EXPECT_GT(p.minCoeff(), 0) << n;
      EXPECT_LT(p.sum(), 1) << n;
      sum += r.weights[i];
    }
    EXPECT_NEAR(sum, 1.0 / 6, 1e-15) << n;
    const double lowest = *std::min_element(r.weights.begin(), r.weights.end());
    // Keast's 11-point rule has the one negative (centroid) weight; the others are positive.
    if (n == 11)
      EXPECT_NEAR(lowest, -74.0 / 5625, 1e-16);
    else
      EXPECT_GT(lowest, 0) << n;
  }
}

TEST(TetrahedronRule, UnknownCountIsRefused) {
  expect_invalid([] { hyper::tetrahedron_rule(5); }, {"5 points"});
  expect_invalid([] { hyper::tetrahedron_rule(0); }, {"0 points"});
}

TEST(TriangleRule, ExactToItsDegreeAndNotBeyond) {
  const std::pair<int, int> expected[] = {{1, 1}, {3, 2}, {6, 4}, {7, 5}};
  for (const auto& [n, degree] : expected) {
    const hyper::TriangleRule& r = hyper::triangle_rule(n);
    ASSERT_EQ(static_cast<int>(r.points.size()), n);
    EXPECT_EQ(r.degree, degree) << n;
    double sum = 0;
    for (size_t i = 0; i < r.points.size(); ++i) {
      EXPECT_GT(r.points[i].minCoeff(), 0) << n;
      EXPECT_LT(r.points[i].sum(), 1) << n;
      EXPECT_GT(r.weights[i], 0) << n;
      sum += r.weights[i];
    }
    EXPECT_NEAR(sum, 0.5, 1e-15) << n;
    for (int d = 0; d <= degree; ++d) EXPECT_LT(worst_triangle_error(r, d), 1e-12) << n << " points, degree " << d;
    EXPECT_GT(worst_triangle_error(r, degree + 1), 1e-6) << n << " points integrate degree " << degree + 1 << " too";
  }
}

TEST(TriangleRule, UnknownCountIsRefused) { expect_invalid([] { hyper::triangle_rule(4); }, {"4 points"}); }
