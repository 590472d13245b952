// Tetrahedron quality measures (core/mesh_quality.hpp) against angles and radii derived by
// hand: the regular tetrahedron, the right-corner tetrahedron, the Kuhn tetrahedra of
// make_box, a sliver; invariance under motion and scale; the worst element of a mesh.

#include "core/mesh_quality.hpp"
#include "core/box_generator.hpp"
#include "test_support.hpp"

#include <algorithm>
#include <cmath>
#include <random>

namespace core = fiberfem::core;
using core::Vec3;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = 180.0 / kPi;

core::TetMesh single(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  core::Positions x(3, 4);
  x << a, b, c, d;
  return core::TetMesh(std::move(x), {core::Tet{0, 1, 2, 3}});
}

// Regular tetrahedron: alternate corners of the cube [-1, 1]^3 (edge 2 sqrt 2).
const Vec3 kRegular[4] = {{1, 1, 1}, {1, -1, -1}, {-1, 1, -1}, {-1, -1, 1}};

// Sliver of half-height eps: a square's corners (+-1, 0) lifted by +eps, (0, +-1) by -eps.
std::array<Vec3, 4> sliver(double eps) {
  return {Vec3(1, 0, eps), Vec3(0, 1, -eps), Vec3(-1, 0, eps), Vec3(0, -1, -eps)};
}

}  // namespace

// Regular tetrahedron: every dihedral angle is acos(1/3) = 70.53 degrees (the faces' unit
// normals n_i sum to zero, so n_i . n_j = -1/3 and the interior angle is acos(1/3)), and
// the inradius is a quarter of the height, R three quarters: 3 r / R = 1.
TEST(MeshQuality, RegularTetrahedron) {
  const auto angles = core::dihedral_angles_deg(kRegular[0], kRegular[1], kRegular[2], kRegular[3]);
  for (double a : angles) EXPECT_NEAR(a, std::acos(1.0 / 3.0) * kDeg, 1e-12);
  EXPECT_NEAR(core::radius_ratio(kRegular[0], kRegular[1], kRegular[2], kRegular[3]), 1.0, 1e-14);
  const core::MeshQuality q = core::mesh_quality(single(kRegular[0], kRegular[1], kRegular[2], kRegular[3]));
  EXPECT_NEAR(q.min_dihedral_deg, 70.528779365509308, 1e-11);
  EXPECT_NEAR(q.max_dihedral_deg, 70.528779365509308, 1e-11);
  EXPECT_NEAR(q.min_radius_ratio, 1.0, 1e-14);
  EXPECT_EQ(q.worst_element, 0);
}

// Corner tetrahedron (0, e1, e2, e3). At the three edges along the axes two coordinate
// planes meet: 90 degrees. At the edge e1 e2 the planes z = 0 and x + y + z = 1 meet, with
// unit normals (0, 0, 1) and (1, 1, 1)/sqrt 3: interior angle acos(1/sqrt 3) = 54.74 degrees
// (likewise e1 e3, e2 e3). V = 1/6, faces 3 x 1/2 + sqrt(3)/2, so r = 3V/A = 1/(3 + sqrt 3);
// the circumcentre is (1/2, 1/2, 1/2), R = sqrt(3)/2; 3 r / R = 2/(1 + sqrt 3) = sqrt 3 - 1.
TEST(MeshQuality, RightCornerTetrahedron) {
  const Vec3 o(0, 0, 0), e1(1, 0, 0), e2(0, 1, 0), e3(0, 0, 1);
  const auto angles = core::dihedral_angles_deg(o, e1, e2, e3);  // o e1, o e2, o e3, e1 e2, e1 e3, e2 e3
  const double slanted = std::acos(1.0 / std::sqrt(3.0)) * kDeg;
  const double expected[6] = {90, 90, 90, slanted, slanted, slanted};
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(angles[static_cast<size_t>(i)], expected[i], 1e-12) << "edge " << i;
  EXPECT_NEAR(core::radius_ratio(o, e1, e2, e3), std::sqrt(3.0) - 1, 1e-14);
  const core::MeshQuality q = core::mesh_quality(single(o, e1, e2, e3));
  EXPECT_NEAR(q.min_dihedral_deg, 54.735610317245346, 1e-11);
  EXPECT_NEAR(q.max_dihedral_deg, 90, 1e-11);
  EXPECT_NEAR(q.min_radius_ratio, std::sqrt(3.0) - 1, 1e-14);
}

// Kuhn tetrahedra of a unit cube, e.g. A = 0, B = e1, C = e1 + e2, D = e1 + e2 + e3 (the
// others are images of it under the cube's symmetries, so all six have the same angles).
// Dihedral angle at an edge = angle between the other two vertices projected on the plane
// normal to the edge:
//   AB (along x): C, D project to (y, z) = (1, 0), (1, 1) -> 45;
//   CD (along z): A - C, B - C project to (-1, -1), (0, -1) -> 45;
//   BC (along y): A - B, D - B project to (x, z) = (-1, 0), (0, 1) -> 90;
//   AC (along (1,1,0)): B - A -> (1/2, -1/2, 0), D - A -> (0, 0, 1) -> 90;
//   BD (along (0,1,1)): A - B -> (-1, 0, 0), C - B -> (0, 1/2, -1/2) -> 90;
//   AD (along (1,1,1)): B - A -> (2,-1,-1)/3, C - A -> (1,1,-2)/3, cos = (1/3)/(2/3) -> 60.
// So min 45, max 90. Radius ratio: V = 1/6; faces ABC, BCD 1/2 each, ABD, ACD sqrt(2)/2
// each, r = 3V/A = 1/(2 (1 + sqrt 2)); the circumsphere is the cube's, R = sqrt(3)/2;
// 3 r / R = sqrt(3)/(1 + sqrt 2) = sqrt(3) (sqrt 2 - 1) = 0.7174.
TEST(MeshQuality, KuhnTetrahedraOfABoxMesh) {
  const double kuhn_ratio = std::sqrt(3.0) * (std::sqrt(2.0) - 1);
  {
    auto angles = core::dihedral_angles_deg(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(1, 1, 1));
    const double expected[6] = {45, 90, 60, 90, 90, 45};  // AB, AC, AD, BC, BD, CD
    for (int i = 0; i < 6; ++i) EXPECT_NEAR(angles[static_cast<size_t>(i)], expected[i], 1e-12) << "edge " << i;
  }
  for (double edge : {1.0, 0.005}) {
    core::BoxSpec s;
    s.size_m = Vec3::Constant(3 * edge);
    s.cells = {3, 3, 3};
    s.origin_m = Vec3(-1, 2, 0.5);
    const core::TetMesh m = core::make_box(s);
    const core::MeshQuality q = core::mesh_quality(m);
    EXPECT_NEAR(q.min_dihedral_deg, 45, 1e-9) << "edge " << edge;
    EXPECT_NEAR(q.max_dihedral_deg, 90, 1e-9) << "edge " << edge;
    EXPECT_NEAR(q.min_radius_ratio, kuhn_ratio, 1e-9) << "edge " << edge;
    for (int e = 0; e < m.num_elements(); ++e) {
      const core::Tet& t = m.tets()[static_cast<size_t>(e)];
      const auto& x = m.rest_positions();
      auto angles = core::dihedral_angles_deg(x.col(t[0]), x.col(t[1]), x.col(t[2]), x.col(t[3]));
      std::sort(angles.begin(), angles.end());
      const double expected[6] = {45, 45, 60, 90, 90, 90};
      for (int i = 0; i < 6; ++i) EXPECT_NEAR(angles[static_cast<size_t>(i)], expected[i], 1e-9) << "element " << e;
    }
  }
}

// Sliver (see sliver()): the faces meeting at the four side edges are nearly coplanar.
// Unit normals of the faces at edge (1,0,e)-(0,1,-e): (0, 4e, 2) and (-4e, 0, 2) up to
// scale, so the interior angle there is acos(1/(1 + 4 e^2)) ~ 2 sqrt(2) e; at the two
// diagonals, the other two vertices seen along the diagonal are (y, z) = (+-1, -2e) from
// (0, 0, e): 180 - 2 atan(2e). V = 4e/3, four faces of area sqrt(1 + 4e^2), so
// r = e / sqrt(1 + 4 e^2); the circumcentre is the origin, R = sqrt(1 + e^2).
TEST(MeshQuality, SliverHasSmallAndLargeAngles) {
  for (double eps : {0.1, 1e-2, 1e-4}) {
    const auto p = sliver(eps);
    const double small = std::acos(1 / (1 + 4 * eps * eps)) * kDeg;
    const double large = 180 - 2 * std::atan(2 * eps) * kDeg;
    const double ratio = 3 * eps / (std::sqrt(1 + 4 * eps * eps) * std::sqrt(1 + eps * eps));
    auto angles = core::dihedral_angles_deg(p[0], p[1], p[2], p[3]);  // 01 02 03 12 13 23
    const double expected[6] = {small, large, small, small, large, small};
    // acos loses accuracy near 1: compare the small angles to a relative 1e-6.
    for (int i = 0; i < 6; ++i)
      EXPECT_NEAR(angles[static_cast<size_t>(i)], expected[i], 1e-6 * expected[i]) << "eps " << eps << " edge " << i;
    EXPECT_NEAR(core::radius_ratio(p[0], p[1], p[2], p[3]), ratio, 1e-12 * ratio) << "eps " << eps;
    const core::MeshQuality q = core::mesh_quality(single(p[0], p[1], p[2], p[3]));
    EXPECT_NEAR(q.min_dihedral_deg, small, 1e-6 * small);
    EXPECT_NEAR(q.max_dihedral_deg, large, 1e-9);
    EXPECT_LT(q.min_dihedral_deg, 3 * eps * kDeg);
  }
  // Flat: zero volume gives a zero ratio and angles of 0 and 180.
  const auto flat = sliver(0);
  EXPECT_EQ(core::radius_ratio(flat[0], flat[1], flat[2], flat[3]), 0.0);
  auto angles = core::dihedral_angles_deg(flat[0], flat[1], flat[2], flat[3]);
  std::sort(angles.begin(), angles.end());
  EXPECT_NEAR(angles.front(), 0, 1e-12);
  EXPECT_NEAR(angles.back(), 180, 1e-12);
}

// Angles and ratio do not change under rotation, translation, scaling, reflection or a
// reordering of the vertices; the six angles' sum is bounded (between 2 pi and 3 pi for
// every tetrahedron).
TEST(MeshQuality, InvariantUnderMotionScaleAndOrder) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int trial = 0; trial < 50; ++trial) {
    std::array<Vec3, 4> p;
    for (Vec3& v : p) v = Vec3(u(rng), u(rng), u(rng));
    const core::Mat3 R = fiberfem::testing::random_rotation(rng);
    const double scale = std::pow(10.0, 3 * u(rng));
    const Vec3 shift(u(rng), u(rng), u(rng));
    std::array<Vec3, 4> q;
    for (int i = 0; i < 4; ++i) q[static_cast<size_t>(i)] = scale * (R * p[static_cast<size_t>(i)]) + shift;
    auto a = core::dihedral_angles_deg(p[0], p[1], p[2], p[3]);
    // Order (1, 0, 3, 2) is negatively oriented; its edges 10 13 12 03 02 32 are ab bd bc ad ac cd.
    const auto b = core::dihedral_angles_deg(q[1], q[0], q[3], q[2]);
    const double b_in_a_order[6] = {b[0], b[4], b[3], b[2], b[1], b[5]};
    double sum = 0;
    for (int i = 0; i < 6; ++i) {
      EXPECT_NEAR(a[static_cast<size_t>(i)], b_in_a_order[i], 1e-7) << "trial " << trial;
      sum += a[static_cast<size_t>(i)];
    }
    EXPECT_GT(sum, 360 - 1e-9);
    EXPECT_LT(sum, 540 + 1e-9);
    const double ra = core::radius_ratio(p[0], p[1], p[2], p[3]);
    EXPECT_NEAR(ra, core::radius_ratio(q[1], q[0], q[3], q[2]), 1e-9 * std::max(ra, 1e-3));
    EXPECT_GT(ra, 0);
    EXPECT_LE(ra, 1 + 1e-12);
  }
}

// The worst element is the one holding the smallest angle, wherever it sits in the mesh.
TEST(MeshQuality, WorstElementIsTheSliver) {
  const auto s = sliver(0.05);
  core::Positions x(3, 12);
  x << kRegular[0], kRegular[1], kRegular[2], kRegular[3], s[0] + Vec3(5, 0, 0), s[1] + Vec3(5, 0, 0),
      s[2] + Vec3(5, 0, 0), s[3] + Vec3(5, 0, 0), Vec3(0, 0, 9), Vec3(1, 0, 9), Vec3(0, 1, 9), Vec3(0, 0, 10);
  const core::TetMesh m(x, {core::Tet{0, 1, 2, 3}, core::Tet{8, 9, 10, 11}, core::Tet{4, 5, 6, 7}});
  const core::MeshQuality q = core::mesh_quality(m);
  EXPECT_EQ(q.worst_element, 2);
  EXPECT_NEAR(q.min_dihedral_deg, std::acos(1 / (1 + 4 * 0.05 * 0.05)) * kDeg, 1e-9);
  EXPECT_NEAR(q.max_dihedral_deg, 180 - 2 * std::atan(0.1) * kDeg, 1e-9);
  EXPECT_NEAR(q.min_radius_ratio, core::radius_ratio(s[0], s[1], s[2], s[3]), 1e-15);
}
