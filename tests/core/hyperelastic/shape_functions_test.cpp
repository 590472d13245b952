// Lagrange shape functions (core/hyperelastic/shape_functions.hpp): Kronecker delta at the
// nodes of gmsh's reference elements (coordinates written out from gmsh's MTetrahedron10 /
// MTriangle6 figures, not from kTetEdges), partition of unity, gradients against central
// differences, and exact reproduction of quadratic (order 2) and linear (order 1) fields.

#include "core/hyperelastic/shape_functions.hpp"

#include <gtest/gtest.h>

#include <random>
#include <vector>

namespace hyper = fiberfem::core::hyperelastic;
using Eigen::Vector2d;
using Eigen::Vector3d;

namespace {

// gmsh type 11: corners, then 4 (0-1), 5 (1-2), 6 (2-0), 7 (3-0), 8 (3-2), 9 (3-1).
const std::vector<Vector3d> kTetNodes = {{0, 0, 0},     {1, 0, 0},     {0, 1, 0},   {0, 0, 1},     {0.5, 0, 0},
                                         {0.5, 0.5, 0}, {0, 0.5, 0},   {0, 0, 0.5}, {0, 0.5, 0.5}, {0.5, 0, 0.5}};
// gmsh type 9: corners, then 3 (0-1), 4 (1-2), 5 (2-0).
const std::vector<Vector2d> kTriangleNodes = {{0, 0}, {1, 0}, {0, 1}, {0.5, 0}, {0.5, 0.5}, {0, 0.5}};

// Random points inside the reference tetrahedron (and triangle), seeded.
std::vector<Vector3d> tet_points(int n) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Vector3d> p;
  while (static_cast<int>(p.size()) < n) {
    const Vector3d x(u(rng), u(rng), u(rng));
    if (x.sum() < 1) p.push_back(x);
  }
  return p;
}

// A full quadratic in xi with arbitrary coefficients, and its gradient.
double quadratic(const Vector3d& x) {
  return 0.3 - 1.1 * x.x() + 0.7 * x.y() + 2.3 * x.z() + 0.9 * x.x() * x.x() - 1.7 * x.y() * x.y() + 0.4 * x.z() * x.z() +
         1.3 * x.x() * x.y() - 0.6 * x.y() * x.z() + 2.1 * x.x() * x.z();
}
Vector3d quadratic_gradient(const Vector3d& x) {
  return {-1.1 + 1.8 * x.x() + 1.3 * x.y() + 2.1 * x.z(), 0.7 - 3.4 * x.y() + 1.3 * x.x() - 0.6 * x.z(),
          2.3 + 0.8 * x.z() - 0.6 * x.y() + 2.1 * x.x()};
}

}  // namespace

TEST(TetShape, KroneckerDeltaAtTheNodes) {
  for (int order : {1, 2}) {
    const int n = hyper::tet_nodes(order);
    for (int a = 0; a < n; ++a) {
      const hyper::TetShape s = hyper::tet_shape(order, kTetNodes[static_cast<size_t>(a)]);
      for (int b = 0; b < 10; ++b) EXPECT_NEAR(s.N(b), b == a ? 1.0 : 0.0, 1e-15) << order << ": N" << b << " at node " << a;
    }
  }
  for (size_t k = 0; k < hyper::kTetEdges.size(); ++k) {
    const auto [a, b] = hyper::kTetEdges[k];
    EXPECT_TRUE(kTetNodes[4 + k].isApprox(0.5 * (kTetNodes[static_cast<size_t>(a)] + kTetNodes[static_cast<size_t>(b)])));
  }
}

TEST(TriangleShape, KroneckerDeltaAtTheNodes) {
  for (int order : {1, 2}) {
    const int n = hyper::triangle_nodes(order);
    for (int a = 0; a < n; ++a) {
      const hyper::TriangleShape s = hyper::triangle_shape(order, kTriangleNodes[static_cast<size_t>(a)]);
      for (int b = 0; b < 6; ++b) EXPECT_NEAR(s.N(b), b == a ? 1.0 : 0.0, 1e-15) << order << ": N" << b << " at node " << a;
    }
  }
}

TEST(TetShape, PartitionOfUnityAndGradientsByFiniteDifferences) {
  const double h = 1e-6;
  for (int order : {1, 2})
    for (const Vector3d& x : tet_points(20)) {
      const hyper::TetShape s = hyper::tet_shape(order, x);
      EXPECT_NEAR(s.N.sum(), 1.0, 1e-14);
      EXPECT_LT(s.dN.colwise().sum().norm(), 1e-13);
      for (int j = 0; j < 3; ++j) {
        const Vector3d e = Vector3d::Unit(j) * h;
        const Eigen::Matrix<double, 10, 1> fd = (hyper::tet_shape(order, x + e).N - hyper::tet_shape(order, x - e).N) / (2 * h);
        EXPECT_LT((fd - s.dN.col(j)).cwiseAbs().maxCoeff(), 1e-8) << "order " << order << ", direction " << j;
      }
    }
}

TEST(TriangleShape, PartitionOfUnityAndGradientsByFiniteDifferences) {
  const double h = 1e-6;
  for (int order : {1, 2})
    for (const Vector3d& p : tet_points(20)) {
      const Vector2d x = p.head<2>();
      const hyper::TriangleShape s = hyper::triangle_shape(order, x);
      EXPECT_NEAR(s.N.sum(), 1.0, 1e-14);
      for (int j = 0; j < 2; ++j) {
        const Vector2d e = Vector2d::Unit(j) * h;
        const Eigen::Matrix<double, 6, 1> fd = (hyper::triangle_shape(order, x + e).N - hyper::triangle_shape(order, x - e).N) / (2 * h);
        EXPECT_LT((fd - s.dN.col(j)).cwiseAbs().maxCoeff(), 1e-8) << "order " << order << ", direction " << j;
      }
    }
}

// Interpolating nodal values of a quadratic reproduces it and its gradient everywhere at
// order 2; at order 1 only a linear field is reproduced (the quadratic is not: the test
// can tell the two orders apart).
TEST(TetShape, ReproducesQuadraticFieldsAtOrderTwo) {
  Eigen::Matrix<double, 10, 1> values;
  for (int a = 0; a < 10; ++a) values(a) = quadratic(kTetNodes[static_cast<size_t>(a)]);
  const Vector3d c(0.4, -1.2, 2.5);
  Eigen::Matrix<double, 10, 1> linear = Eigen::Matrix<double, 10, 1>::Zero();
  for (int a = 0; a < 4; ++a) linear(a) = 0.8 + c.dot(kTetNodes[static_cast<size_t>(a)]);
  double worst_order1 = 0;
  for (const Vector3d& x : tet_points(30)) {
    const hyper::TetShape s = hyper::tet_shape(2, x);
    EXPECT_NEAR(s.N.dot(values), quadratic(x), 1e-13);
    EXPECT_LT((s.dN.transpose() * values - quadratic_gradient(x)).norm(), 1e-13);
    const hyper::TetShape s1 = hyper::tet_shape(1, x);
    EXPECT_NEAR(s1.N.dot(linear), 0.8 + c.dot(x), 1e-14);
    EXPECT_LT((s1.dN.transpose() * linear - c).norm(), 1e-14);
    worst_order1 = std::max(worst_order1, std::abs(s1.N.dot(values) - quadratic(x)));
  }
  EXPECT_GT(worst_order1, 1e-2);
}

TEST(TriangleShape, ReproducesQuadraticFieldsAtOrderTwo) {
  auto f = [](const Vector2d& x) { return quadratic(Vector3d(x.x(), x.y(), 0)); };
  Eigen::Matrix<double, 6, 1> values;
  for (int a = 0; a < 6; ++a) values(a) = f(kTriangleNodes[static_cast<size_t>(a)]);
  for (const Vector3d& p : tet_points(30)) {
    const Vector2d x = p.head<2>();
    const hyper::TriangleShape s = hyper::triangle_shape(2, x);
    EXPECT_NEAR(s.N.dot(values), f(x), 1e-13);
    EXPECT_LT((s.dN.transpose() * values - quadratic_gradient(Vector3d(x.x(), x.y(), 0)).head<2>()).norm(), 1e-13);
  }
}
