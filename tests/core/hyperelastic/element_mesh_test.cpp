// The 10-node element mesh (core/hyperelastic/element_mesh.hpp): one node per edge (count
// checked against Euler's formula), at the midpoint or where a placement puts it, boundary
// faces with their mid-edge nodes on the boundary, exact integration of a P2-interpolated
// quadratic over a distorted mesh, exact volumes of curved elements, the file
// constructor's matching and its errors, fixed DOFs, HRZ lumped masses against the
// consistent mass.

#include "core/box_generator.hpp"
#include "core/hyperelastic/element_mesh.hpp"
#include "core/hyperelastic/quadrature.hpp"
#include "core/hyperelastic/shape_functions.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <Eigen/LU>

#include <algorithm>
#include <numeric>
#include <random>

namespace core = fiberfem::core;
namespace hyper = fiberfem::core::hyperelastic;
using core::Vec3;
using fiberfem::testing::expect_invalid;

namespace {

core::TetMesh box(int nx = 3, int ny = 2, int nz = 2) {
  core::BoxSpec s;
  s.size_m = Vec3(0.3, 0.2, 0.25);
  s.cells = {nx, ny, nz};
  return core::make_box(s);
}

// The box with its interior corner nodes moved at random (by up to 0.2 of a cell), so the
// elements are distorted but the domain is still exactly the box.
core::TetMesh jittered_box() {
  const core::TetMesh m = box(4, 3, 3);
  core::Positions x = m.rest_positions();
  const auto [lo, hi] = m.bounding_box();
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.2, 0.2);
  for (int i = 0; i < m.num_nodes(); ++i) {
    const Vec3 p = x.col(i);
    if (((p - lo).minCoeff() > 1e-12) && ((hi - p).minCoeff() > 1e-12))
      x.col(i) += Vec3(u(rng) * 0.3 / 4, u(rng) * 0.2 / 3, u(rng) * 0.25 / 3);
  }
  return core::TetMesh(x, m.tets());
}

// A quadratic map of space, phi(x) = x + (a y^2, b z^2, c x^2): det D phi = 1 + 8 abc xyz,
// so the image of the box [0, L]^3 has volume V + abc Lx^2 Ly^2 Lz^2.
constexpr double ka = 0.8, kb = -0.6, kc = 0.7;
Vec3 phi(const Vec3& x) { return x + Vec3(ka * x.y() * x.y(), kb * x.z() * x.z(), kc * x.x() * x.x()); }

// Number of distinct edges by Euler's formula for a mesh of a ball: V - E + F - T = 1 with
// F = (4 T + boundary triangles) / 2.
int euler_edges(const core::TetMesh& m) {
  const int faces = (4 * m.num_elements() + static_cast<int>(m.boundary_triangles().size())) / 2;
  return m.num_nodes() + faces - m.num_elements() - 1;
}

std::vector<double> ones(const hyper::ElementMesh& m, double rho) { return std::vector<double>(static_cast<size_t>(m.num_elements()), rho); }

}  // namespace

TEST(ElementMesh, OrderOneIsTheTetMesh) {
  const core::TetMesh m = box();
  const hyper::ElementMesh e(m, 1);
  EXPECT_EQ(e.order(), 1);
  EXPECT_EQ(e.nodes_per_element(), 4);
  EXPECT_EQ(e.num_nodes(), m.num_nodes());
  EXPECT_EQ(e.num_corner_nodes(), m.num_nodes());
  EXPECT_TRUE(e.edge_ends().empty());
  ASSERT_EQ(e.num_elements(), m.num_elements());
  for (int i = 0; i < m.num_elements(); ++i)
    for (int k = 0; k < 4; ++k) EXPECT_EQ(e.elements()[static_cast<size_t>(i)][static_cast<size_t>(k)], m.tets()[static_cast<size_t>(i)][static_cast<size_t>(k)]);
  ASSERT_EQ(e.boundary_faces().size(), m.boundary_triangles().size());
  const std::vector<double> v = hyper::element_volumes(e);
  for (int i = 0; i < m.num_elements(); ++i) EXPECT_NEAR(v[static_cast<size_t>(i)], m.rest_volume(i), 1e-15);
  expect_invalid([&] { hyper::ElementMesh(m, 3); }, {"order", "3"});
}

TEST(ElementMesh, OneNodePerEdgeAtItsMidpoint) {
  const core::TetMesh m = box();
  const hyper::ElementMesh e(m, 2);
  EXPECT_EQ(e.num_nodes() - e.num_corner_nodes(), euler_edges(m));
  EXPECT_EQ(static_cast<int>(e.edge_ends().size()), euler_edges(m));
  EXPECT_TRUE(e.rest_positions().leftCols(m.num_nodes()).isApprox(m.rest_positions()));
  // Lexicographic order of the corner pairs.
  EXPECT_TRUE(std::is_sorted(e.edge_ends().begin(), e.edge_ends().end()));
  for (const auto& [a, b] : e.edge_ends()) EXPECT_LT(a, b);
  for (size_t el = 0; el < e.elements().size(); ++el) {
    const auto& n = e.elements()[el];
    for (size_t k = 0; k < hyper::kTetEdges.size(); ++k) {
      const int a = n[static_cast<size_t>(hyper::kTetEdges[k][0])], b = n[static_cast<size_t>(hyper::kTetEdges[k][1])];
      const int node = n[4 + k];
      ASSERT_GE(node, e.num_corner_nodes());
      const auto ends = e.edge_ends()[static_cast<size_t>(node - e.num_corner_nodes())];
      EXPECT_EQ(std::minmax(a, b), std::minmax(ends[0], ends[1]));
      EXPECT_LT((e.rest_positions().col(node) - 0.5 * (m.rest_positions().col(a) + m.rest_positions().col(b))).norm(), 1e-15);
    }
  }
}

TEST(ElementMesh, BoundaryFacesCarryMidEdgeNodesOnTheBoundary) {
  const core::TetMesh m = box();
  const hyper::ElementMesh e(m, 2);
  const auto [lo, hi] = m.bounding_box();
  ASSERT_EQ(e.boundary_faces().size(), m.boundary_triangles().size());
  for (size_t f = 0; f < e.boundary_faces().size(); ++f) {
    const auto& face = e.boundary_faces()[f];
    const core::Tri& t = m.boundary_triangles()[f];
    for (int k = 0; k < 3; ++k) EXPECT_EQ(face[static_cast<size_t>(k)], t[static_cast<size_t>(k)]);
    for (size_t k = 0; k < hyper::kTriangleEdges.size(); ++k) {
      const Vec3 p = e.rest_positions().col(face[3 + k]);
      const Vec3 mid = 0.5 * (m.rest_positions().col(t[static_cast<size_t>(hyper::kTriangleEdges[k][0])]) +
                              m.rest_positions().col(t[static_cast<size_t>(hyper::kTriangleEdges[k][1])]));
      EXPECT_LT((p - mid).norm(), 1e-15);
      EXPECT_LT(std::min((p - lo).cwiseAbs().minCoeff(), (hi - p).cwiseAbs().minCoeff()), 1e-15) << "face " << f;
    }
  }
}

// Straight-sided distorted elements map affinely, so P2 interpolation reproduces a
// quadratic of physical space exactly and the 14-point rule integrates it exactly:
// int over [0, L]^3 of x^2 + 2 y z - 3 z^2 + x - 1 against its closed form.
TEST(ElementMesh, InterpolatedQuadraticIntegratesExactlyOverADistortedMesh) {
  const core::TetMesh m = jittered_box();
  const hyper::ElementMesh e(m, 2);
  auto f = [](const Vec3& x) { return x.x() * x.x() + 2 * x.y() * x.z() - 3 * x.z() * x.z() + x.x() - 1; };
  const double L[3] = {0.3, 0.2, 0.25}, V = L[0] * L[1] * L[2];
  const double exact = V * (L[0] * L[0] / 3 + L[1] * L[2] / 2 - L[2] * L[2] + L[0] / 2 - 1);
  const hyper::TetRule& rule = hyper::tetrahedron_rule(14);
  double integral = 0, integral_linear = 0;
  const hyper::ElementMesh e1(m, 1);
  for (int el = 0; el < e.num_elements(); ++el) {
    const Eigen::Matrix<double, 3, 10> X = e.element_positions(el), X1 = e1.element_positions(el);
    Eigen::Matrix<double, 10, 1> values = Eigen::Matrix<double, 10, 1>::Zero(), values1 = values;
    for (int a = 0; a < 10; ++a) values(a) = f(X.col(a));
    for (int a = 0; a < 4; ++a) values1(a) = f(X1.col(a));
    for (size_t q = 0; q < rule.points.size(); ++q) {
      const hyper::TetShape s = hyper::tet_shape(2, rule.points[q]), s1 = hyper::tet_shape(1, rule.points[q]);
      integral += rule.weights[q] * s.N.dot(values) * (X * s.dN).determinant();
      integral_linear += rule.weights[q] * s1.N.dot(values1) * (X1 * s1.dN).determinant();
    }
  }
  EXPECT_NEAR(integral, exact, 1e-14 * std::abs(exact));
  EXPECT_GT(std::abs(integral_linear - exact), 1e-5 * std::abs(exact));  // P1 does not
}

// Corners and edge nodes moved by the quadratic map phi: each 10-node element is exactly
// phi of a straight one, so the curved elements tile phi(box) and their volumes sum to its
// closed form.
TEST(ElementMesh, CurvedElementsHaveExactVolumesAndPositiveJacobians) {
  const core::TetMesh flat = box(3, 3, 3);
  core::Positions x = flat.rest_positions();
  for (int i = 0; i < x.cols(); ++i) x.col(i) = phi(flat.rest_positions().col(i));
  const core::TetMesh corners(x, flat.tets());
  const hyper::EdgePlacement on_phi = [&](int a, int b, const Vec3&) {
    return phi(0.5 * (flat.rest_positions().col(a) + flat.rest_positions().col(b)));
  };
  const hyper::ElementMesh e(corners, 2, on_phi);
  const double exact = 0.3 * 0.2 * 0.25 + ka * kb * kc * 0.09 * 0.04 * 0.0625;
  const std::vector<double> v = hyper::element_volumes(e);
  EXPECT_NEAR(std::accumulate(v.begin(), v.end(), 0.0), exact, 1e-14 * exact);
  // The elements are curved: their volumes differ from the straight ones through the
  // same corners (the total does not, since the bulges of opposite box faces cancel).
  double largest_change = 0;
  for (int el = 0; el < e.num_elements(); ++el)
    largest_change = std::max(largest_change, std::abs(v[static_cast<size_t>(el)] / corners.rest_volume(el) - 1));
  EXPECT_GT(largest_change, 1e-3);
  const hyper::TetRule& rule = hyper::tetrahedron_rule(14);
  double lowest = 1e300;
  for (int el = 0; el < e.num_elements(); ++el)
    for (const Eigen::Vector3d& p : rule.points)
      lowest = std::min(lowest, (e.element_positions(el) * hyper::tet_shape(2, p).dN).determinant());
  EXPECT_GT(lowest, 0);
  const Eigen::VectorXd m = hyper::lumped_masses(e, ones(e, 1000.0));
  EXPECT_NEAR(m.sum(), 1000.0 * exact, 1e-12 * 1000.0 * exact);
  EXPECT_GT(m.minCoeff(), 0);
}

TEST(ElementMesh, PlacementThatTanglesAnElementIsRefused) {
  const core::TetMesh m = box(1, 1, 1);
  const hyper::EdgePlacement far = [&](int a, int b, const Vec3& mid) {
    return a == 0 && b == m.num_nodes() - 1 ? Vec3(mid + Vec3(1, 1, 1)) : mid;
  };
  expect_invalid([&] { hyper::ElementMesh(m, 2, far); }, {"element", "tangled"});
  const hyper::EdgePlacement nan = [](int, int, const Vec3&) { return Vec3(std::nan(""), 0, 0); };
  expect_invalid([&] { hyper::ElementMesh(m, 2, nan); }, {"non-finite"});
}

// The file constructor gets the generated mesh back from scrambled input: edge nodes
// renumbered, each element's corners rotated (an even permutation keeps the orientation),
// and one element given inverted (TetMesh swaps its last two corners; its edge nodes must
// follow).
TEST(ElementMesh, FromFileElementsMatchesTheGeneratedMesh) {
  const core::TetMesh m = box();
  const hyper::ElementMesh gen(m, 2);
  const int nc = m.num_nodes(), ne = gen.num_nodes() - nc;
  std::vector<int> perm(static_cast<size_t>(ne));
  std::iota(perm.begin(), perm.end(), 0);
  std::shuffle(perm.begin(), perm.end(), std::mt19937(5));
  core::Positions edge_x(3, ne);
  for (int i = 0; i < ne; ++i) edge_x.col(perm[static_cast<size_t>(i)]) = gen.rest_positions().col(nc + i);
  // Local node k of the rotated element is gen's local node rot[k] (corners 1, 2, 0, 3:
  // an even permutation; its edges 0-1, 1-2, 2-0, 3-0, 3-2, 3-1 are gen's 1-2, 2-0, 0-1,
  // 3-1, 3-0, 3-2).
  const int rot[10] = {1, 2, 0, 3, 5, 6, 4, 9, 7, 8};
  std::vector<std::array<int, 10>> file;
  std::vector<core::Tet> tets = m.tets();
  for (size_t el = 0; el < gen.elements().size(); ++el) {
    std::array<int, 10> n;
    for (int k = 0; k < 10; ++k) {
      const int g = gen.elements()[el][static_cast<size_t>(rot[k])];
      n[static_cast<size_t>(k)] = g < nc ? g : nc + perm[static_cast<size_t>(g - nc)];
    }
    file.push_back(n);
  }
  // Element 0 inverted in the file: corners 2 and 3 swapped, so edges 1-2 <-> 1-3 (nodes
  // 5, 9) and 2-0 <-> 3-0 (nodes 6, 7) swap too.
  std::swap(file[0][2], file[0][3]);
  std::swap(file[0][5], file[0][9]);
  std::swap(file[0][6], file[0][7]);
  tets[0] = {file[0][0], file[0][1], file[0][2], file[0][3]};
  for (size_t el = 1; el < tets.size(); ++el) tets[el] = {file[el][0], file[el][1], file[el][2], file[el][3]};
  const core::TetMesh corners(m.rest_positions(), tets);
  ASSERT_EQ(corners.reoriented_elements(), std::vector<int>{0});
  const hyper::ElementMesh read(corners, file, edge_x);
  ASSERT_EQ(read.num_nodes(), gen.num_nodes());
  for (int el = 0; el < read.num_elements(); ++el) {
    const Eigen::Matrix<double, 3, 10> X = read.element_positions(el);
    for (size_t k = 0; k < hyper::kTetEdges.size(); ++k)
      EXPECT_LT((X.col(4 + static_cast<int>(k)) - 0.5 * (X.col(hyper::kTetEdges[k][0]) + X.col(hyper::kTetEdges[k][1]))).norm(), 1e-15)
          << "element " << el << " edge " << k;
  }
  EXPECT_EQ(read.boundary_faces().size(), gen.boundary_faces().size());
  std::vector<double> v = hyper::element_volumes(read);
  for (int el = 0; el < read.num_elements(); ++el) EXPECT_NEAR(v[static_cast<size_t>(el)], corners.rest_volume(el), 1e-15);
}

TEST(ElementMesh, FromFileElementsRefusesInconsistentEdges) {
  const core::TetMesh m = box(1, 1, 1);
  const hyper::ElementMesh gen(m, 2);
  const int nc = gen.num_corner_nodes();
  const core::Positions edge_x = gen.rest_positions().rightCols(gen.num_nodes() - nc);
  const auto good = gen.elements();
  auto bad = good;
  bad[1][4] = nc + 100;
  expect_invalid([&] { hyper::ElementMesh(m, bad, edge_x); }, {"element 1", "out of range"});
  // Two edge nodes of element 2 exchanged: each now sits on an edge another element gives
  // to the other node.
  bad = good;
  std::swap(bad[2][4], bad[2][5]);
  expect_invalid([&] { hyper::ElementMesh(m, bad, edge_x); }, {"element", "edge node"});
  bad = good;
  bad[3][0] = bad[3][1];
  expect_invalid([&] { hyper::ElementMesh(m, bad, edge_x); }, {"element 3", "corners"});
  core::Positions extra(3, edge_x.cols() + 1);
  extra << edge_x, Vec3::Zero();
  expect_invalid([&] { hyper::ElementMesh(m, good, extra); }, {"used by no element"});
  // The same edge given two nodes: element 0's first edge node replaced by an unused one.
  bad = good;
  bad[0][4] = nc + static_cast<int>(edge_x.cols());
  expect_invalid([&] { hyper::ElementMesh(m, bad, extra); }, {"has two edge nodes"});
  expect_invalid([&] { hyper::ElementMesh(m, std::vector<std::array<int, 10>>(2), edge_x); }, {"10-node elements"});
}

TEST(ElementMesh, EdgeNodesAreFixedWhereBothCornersAre) {
  const core::TetMesh m = box();
  const hyper::ElementMesh e(m, 2);
  std::vector<std::uint8_t> corner(3 * static_cast<size_t>(m.num_nodes()), 0);
  for (int i : m.node_set("xmin")) corner[3 * static_cast<size_t>(i)] = corner[3 * static_cast<size_t>(i) + 2] = 1;
  const std::vector<std::uint8_t> all = e.fixed_dofs(corner);
  ASSERT_EQ(all.size(), 3 * static_cast<size_t>(e.num_nodes()));
  int fixed_edges = 0;
  for (int n = e.num_corner_nodes(); n < e.num_nodes(); ++n) {
    const bool on_face = std::abs(e.rest_positions()(0, n)) < 1e-15;  // both ends on x = 0
    EXPECT_EQ(all[3 * static_cast<size_t>(n)], on_face);
    EXPECT_EQ(all[3 * static_cast<size_t>(n) + 1], 0);
    EXPECT_EQ(all[3 * static_cast<size_t>(n) + 2], on_face);
    fixed_edges += on_face;
  }
  EXPECT_GT(fixed_edges, 0);
  EXPECT_TRUE(std::equal(corner.begin(), corner.end(), all.begin()));
  EXPECT_EQ(e.fixed_dofs({}), std::vector<std::uint8_t>(3 * static_cast<size_t>(e.num_nodes()), 0));
  expect_invalid([&] { e.fixed_dofs({1, 0}); }, {"corner flags"});
}

// One straight element: the consistent mass M_ab = rho int N_a N_b dV from the quadrature
// has the closed-form diagonal rho V (6, 32) / 420 (corner, edge: int L^2 (2L - 1)^2 and
// 16 int L_a^2 L_b^2 by the Dirichlet integral) and row sums rho V (-1/20, 1/5), the
// negative corner masses of row-sum lumping; HRZ scales the diagonal to rho V:
// corner 6/216 = 1/36, edge 32/216 = 4/27.
TEST(LumpedMasses, HrzOfOneElementAgainstItsConsistentMass) {
  core::Positions x(3, 4);
  x << 0, 0.02, 0.003, 0.001, 0, 0.001, 0.018, 0.002, 0, 0.0, 0.001, 0.015;
  const core::TetMesh m(x, {{0, 1, 2, 3}});
  const hyper::ElementMesh e(m, 2);
  const double rho = 1060, mass = rho * m.rest_volume(0);
  const hyper::TetRule& rule = hyper::tetrahedron_rule(14);
  Eigen::Matrix<double, 10, 10> M = Eigen::Matrix<double, 10, 10>::Zero();
  for (size_t q = 0; q < rule.points.size(); ++q) {
    const hyper::TetShape s = hyper::tet_shape(2, rule.points[q]);
    M += rho * rule.weights[q] * (e.element_positions(0) * s.dN).determinant() * s.N * s.N.transpose();
  }
  const Eigen::VectorXd lumped = hyper::lumped_masses(e, {rho});
  EXPECT_NEAR(lumped.sum(), mass, 1e-14 * mass);
  for (int a = 0; a < 10; ++a) {
    const bool corner = a < 4;
    EXPECT_NEAR(M(a, a), mass * (corner ? 6.0 : 32.0) / 420, 1e-13 * mass);
    EXPECT_NEAR(M.row(a).sum(), mass * (corner ? -1.0 / 20 : 1.0 / 5), 1e-13 * mass);
    EXPECT_NEAR(lumped(e.elements()[0][static_cast<size_t>(a)]), M(a, a) * mass / M.diagonal().sum(), 1e-14 * mass);
    EXPECT_NEAR(lumped(e.elements()[0][static_cast<size_t>(a)]), mass * (corner ? 1.0 / 36 : 4.0 / 27), 1e-14 * mass);
  }
  const Eigen::VectorXd linear = hyper::lumped_masses(hyper::ElementMesh(m, 1), {rho});
  for (int a = 0; a < 4; ++a) EXPECT_NEAR(linear(a), mass / 4, 1e-15 * mass);
}

TEST(LumpedMasses, TotalIsExactAndEveryMassPositiveOnADistortedMesh) {
  const hyper::ElementMesh e(jittered_box(), 2);
  std::vector<double> rho(static_cast<size_t>(e.num_elements()));
  for (size_t i = 0; i < rho.size(); ++i) rho[i] = 1000 + 10.0 * static_cast<double>(i % 7);
  const std::vector<double> v = hyper::element_volumes(e);
  double total = 0;
  for (size_t i = 0; i < rho.size(); ++i) total += rho[i] * v[i];
  const Eigen::VectorXd m = hyper::lumped_masses(e, rho);
  EXPECT_NEAR(m.sum(), total, 1e-13 * total);
  EXPECT_GT(m.minCoeff(), 0);
  expect_invalid([&] { hyper::lumped_masses(e, {1.0}); }, {"densities"});
  rho[4] = 0;
  expect_invalid([&] { hyper::lumped_masses(e, rho); }, {"element 4", "> 0"});
}
