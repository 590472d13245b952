// Tetrahedral mesh (core/mesh.hpp): validation errors naming the element or node,
// reorientation of inverted elements, outward boundary surfaces checked by the divergence
// theorem on a single tet and on a cube meshed here (not by the box generator), node
// sets, and node renumbering.

#include "core/mesh.hpp"
#include "test_support.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <set>
#include <stdexcept>

namespace core = fiberfem::core;
using core::Positions;
using core::Tet;
using core::Tri;
using core::Vec3;
using fiberfem::testing::expect_invalid;

namespace {

// Independent signed volume: det[b-a, c-a, d-a] / 6.
double det_volume(const Positions& x, const Tet& t) {
  Eigen::Matrix3d D;
  for (int j = 0; j < 3; ++j) D.col(j) = x.col(t[static_cast<size_t>(j) + 1]) - x.col(t[0]);
  return D.determinant() / 6.0;
}

Positions unit_tet_nodes() {
  Positions x(3, 4);
  x << 0, 1, 0, 0,  //
      0, 0, 1, 0,   //
      0, 0, 0, 1;
  return x;
}

struct HandMesh {
  Positions x;
  std::vector<Tet> tets;
  int n = 0;
  double h = 0;
};

// A cube of n^3 cells of edge h, each cell cut into six tetrahedra along its main diagonal
// (one per axis permutation). Tets are left in whatever orientation the path gives.
HandMesh cube_mesh(int n, double h) {
  HandMesh m;
  m.n = n;
  m.h = h;
  const int nn = n + 1;
  auto id = [nn](int i, int j, int k) { return i + nn * (j + nn * k); };
  m.x.resize(3, nn * nn * nn);
  for (int k = 0; k < nn; ++k)
    for (int j = 0; j < nn; ++j)
      for (int i = 0; i < nn; ++i) m.x.col(id(i, j, k)) = Vec3(i * h, j * h, k * h);
  const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i)
        for (const auto& p : perms) {
          int c[3] = {i, j, k};
          Tet t{};
          t[0] = id(c[0], c[1], c[2]);
          for (int s = 0; s < 3; ++s) {
            c[p[s]] += 1;
            t[static_cast<size_t>(s) + 1] = id(c[0], c[1], c[2]);
          }
          m.tets.push_back(t);
        }
  return m;
}

Vec3 tri_normal2(const Positions& x, const Tri& t) {
  return (x.col(t[1]) - x.col(t[0])).cross(x.col(t[2]) - x.col(t[0]));
}

// Volume enclosed by a closed outward surface: sum over triangles of a . (b x c) / 6.
double enclosed_volume(const Positions& x, const std::vector<Tri>& tris) {
  double v = 0;
  for (const Tri& t : tris) v += x.col(t[0]).dot(x.col(t[1]).cross(x.col(t[2]))) / 6.0;
  return v;
}

// A triangle up to cyclic rotation (orientation kept): rotate the smallest index first.
Tri canonical(Tri t) {
  std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
  return t;
}

}  // namespace

TEST(SignedVolume, HandValues) {
  const Vec3 a(0, 0, 0), b(2, 0, 0), c(0, 3, 0), d(0, 0, 4);
  EXPECT_DOUBLE_EQ(core::signed_volume(a, b, c, d), 4.0);  // 2*3*4/6
  EXPECT_DOUBLE_EQ(core::signed_volume(a, c, b, d), -4.0);
  const Vec3 s(1, -2, 5);
  EXPECT_NEAR(core::signed_volume(a + s, b + s, c + s, d + s), 4.0, 1e-14);
}

TEST(TetMesh, SingleTetVolumeAndOutwardBoundary) {
  const core::TetMesh mesh(unit_tet_nodes(), {{0, 1, 2, 3}});
  EXPECT_EQ(mesh.num_nodes(), 4);
  EXPECT_EQ(mesh.num_elements(), 1);
  EXPECT_EQ(mesh.num_regions(), 1);
  EXPECT_DOUBLE_EQ(mesh.rest_volume(0), 1.0 / 6.0);
  EXPECT_DOUBLE_EQ(mesh.total_volume(), 1.0 / 6.0);
  EXPECT_TRUE(mesh.reoriented_elements().empty());
  const auto& tris = mesh.boundary_triangles();
  ASSERT_EQ(tris.size(), 4u);
  const Positions& x = mesh.rest_positions();
  const Vec3 centroid = x.rowwise().mean();
  Vec3 sum = Vec3::Zero();
  std::set<int> opposite;
  for (const Tri& t : tris) {
    const Vec3 n2 = tri_normal2(x, t);
    const Vec3 face_centre = (x.col(t[0]) + x.col(t[1]) + x.col(t[2])) / 3.0;
    EXPECT_GT(n2.dot(face_centre - centroid), 0) << "inward triangle " << t[0] << t[1] << t[2];
    sum += n2;
    opposite.insert(6 - t[0] - t[1] - t[2]);  // the node not on this face
  }
  EXPECT_EQ(opposite.size(), 4u) << "each face appears once";
  EXPECT_LT(sum.norm(), 1e-15);
  EXPECT_NEAR(enclosed_volume(x, tris), 1.0 / 6.0, 1e-15);
  for (int e : mesh.boundary_triangle_elements()) EXPECT_EQ(e, 0);
  EXPECT_EQ(mesh.boundary_nodes(), (std::vector<int>{0, 1, 2, 3}));
}

TEST(TetMesh, InvertedElementIsReorientedAndReported) {
  Positions x(3, 5);
  x << 0, 1, 0, 0, 1,  //
      0, 0, 1, 0, 1,   //
      0, 0, 0, 1, 1;
  // Element 0 positive; element 1 = (1, 3, 2, 4) has det[(-1,0,1), (-1,1,0), (0,1,1)] = -2.
  std::vector<Tet> tets{{0, 1, 2, 3}, {1, 3, 2, 4}};
  const double v1 = det_volume(x, tets[1]);
  ASSERT_NEAR(v1, -2.0 / 6.0, 1e-15);
  const core::TetMesh mesh(x, tets);
  EXPECT_EQ(mesh.reoriented_elements(), std::vector<int>{1});
  EXPECT_DOUBLE_EQ(mesh.rest_volume(1), -v1);
  EXPECT_GT(det_volume(mesh.rest_positions(), mesh.tets()[1]), 0);
  // Same node set, only the order changed.
  Tet a = mesh.tets()[1], b = tets[1];
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  EXPECT_EQ(a, b);
  EXPECT_EQ(mesh.tets()[0], tets[0]);
  // The two tets share face (1, 2, 3): 6 boundary faces enclosing the total volume.
  EXPECT_EQ(mesh.boundary_triangles().size(), 6u);
  EXPECT_NEAR(enclosed_volume(mesh.rest_positions(), mesh.boundary_triangles()), 1.0 / 6.0 - v1, 1e-15);
}

// The cube of side n h has 2 * 6 n^2 boundary triangles (two per cell face), each lying in
// a cube face with its normal along that face's outward axis; area-weighted normals sum to
// zero and the divergence theorem recovers the volume.
TEST(TetMesh, CubeBoundaryIsClosedAndOutward) {
  for (int n : {1, 2, 3}) {
    const HandMesh hm = cube_mesh(n, 0.5);
    std::vector<int> negative;
    for (size_t e = 0; e < hm.tets.size(); ++e)
      if (det_volume(hm.x, hm.tets[e]) < 0) negative.push_back(static_cast<int>(e));
    const core::TetMesh mesh(hm.x, hm.tets);
    const double L = n * hm.h;
    EXPECT_EQ(mesh.reoriented_elements(), negative);
    EXPECT_NEAR(mesh.total_volume(), L * L * L, 1e-14);
    for (int e = 0; e < mesh.num_elements(); ++e) {
      EXPECT_NEAR(mesh.rest_volume(e), hm.h * hm.h * hm.h / 6, 1e-15);
      EXPECT_GT(det_volume(mesh.rest_positions(), mesh.tets()[static_cast<size_t>(e)]), 0);
    }
    const auto& tris = mesh.boundary_triangles();
    ASSERT_EQ(tris.size(), static_cast<size_t>(12 * n * n)) << "n = " << n;
    ASSERT_EQ(mesh.boundary_triangle_elements().size(), tris.size());
    Vec3 sum = Vec3::Zero();
    double area = 0;
    for (size_t i = 0; i < tris.size(); ++i) {
      const Tri& t = tris[i];
      const Vec3 n2 = tri_normal2(mesh.rest_positions(), t);
      sum += n2;
      area += 0.5 * n2.norm();
      Eigen::Index axis = 0;
      n2.cwiseAbs().maxCoeff(&axis);
      EXPECT_NEAR(std::abs(n2(axis)), n2.norm(), 1e-14) << "boundary triangle not axis-aligned";
      const double expected_coord = n2(axis) > 0 ? L : 0.0;
      for (int v : t) EXPECT_NEAR(mesh.rest_positions()(axis, v), expected_coord, 1e-14) << "not on the outward face";
      const Tet& owner = mesh.tets()[static_cast<size_t>(mesh.boundary_triangle_elements()[i])];
      for (int v : t) EXPECT_NE(std::find(owner.begin(), owner.end(), v), owner.end());
    }
    EXPECT_LT(sum.norm(), 1e-13);
    EXPECT_NEAR(area, 6 * L * L, 1e-13);
    EXPECT_NEAR(enclosed_volume(mesh.rest_positions(), tris), L * L * L, 1e-13);
    EXPECT_EQ(mesh.boundary_nodes().size(), static_cast<size_t>((n + 1) * (n + 1) * (n + 1) - (n - 1) * (n - 1) * (n - 1)));
    const auto [lo, hi] = mesh.bounding_box();
    EXPECT_LT(lo.norm(), 1e-15);
    EXPECT_LT((hi - Vec3(L, L, L)).norm(), 1e-15);
  }
}

TEST(TetMesh, ValidationErrorsNameTheElementOrNode) {
  const Positions x4 = unit_tet_nodes();
  Positions x5(3, 5);
  x5 << 0, 1, 0, 0, 1,  //
      0, 0, 1, 0, 1,    //
      0, 0, 0, 1, 1;
  expect_invalid([&] { core::TetMesh(x4.leftCols(3), {{0, 1, 2, 0}}); }, {"at least 4 nodes", "got 3"});
  expect_invalid([&] { core::TetMesh(x4, {}); }, {"no elements"});
  expect_invalid([&] { core::TetMesh(x5, {{0, 1, 2, 3}, {1, 2, 3, 7}}); },
                 {"element 1", "references node 7", "outside [0, 5)"});
  expect_invalid([&] { core::TetMesh(x5, {{0, 1, 2, 3}, {-1, 2, 3, 4}}); }, {"element 1", "references node -1"});
  expect_invalid([&] { core::TetMesh(x5, {{0, 1, 2, 3}, {1, 2, 1, 4}}); }, {"element 1", "uses node 1 twice"});
  Positions bad = x5;
  bad(1, 2) = std::numeric_limits<double>::quiet_NaN();
  expect_invalid([&] { core::TetMesh(bad, {{0, 1, 3, 4}}); }, {"node 2", "non-finite"});
  bad = x5;
  bad(0, 4) = std::numeric_limits<double>::infinity();
  expect_invalid([&] { core::TetMesh(bad, {{0, 1, 2, 3}}); }, {"node 4", "non-finite"});
  expect_invalid([&] { core::TetMesh(x5, {{0, 1, 2, 3}, {1, 2, 3, 4}}, {0, -1}); },
                 {"element 1", "negative region id -1"});
  expect_invalid([&] { core::TetMesh(x5, {{0, 1, 2, 3}, {1, 2, 3, 4}}, {0}); }, {"1 region ids for 2 elements"});
}

TEST(TetMesh, DegenerateElementIsRefusedById) {
  // Element 2 is flat: node 4 lies in the plane of nodes 0, 1, 2.
  Positions x(3, 6);
  x << 0, 1, 0, 0, 0.3, 1,  //
      0, 0, 1, 0, 0.3, 1,   //
      0, 0, 0, 1, 0, 1;
  expect_invalid([&] { core::TetMesh(x, {{0, 1, 2, 3}, {1, 2, 3, 5}, {0, 1, 2, 4}}); },
                 {"element 2", "degenerate"});
  // Nearly flat: height 1e-13 of a unit-size tet is below 1e-12 h^3; 1e-9 is not.
  for (double height : {1e-13, 1e-9}) {
    Positions y = unit_tet_nodes();
    y(2, 3) = height;
    if (height < 1e-12) {
      expect_invalid([&] { core::TetMesh(y, {{0, 1, 2, 3}}); }, {"element 0", "degenerate"});
    } else {
      EXPECT_NO_THROW(core::TetMesh(y, {{0, 1, 2, 3}}));
      // A stricter tolerance refuses it.
      expect_invalid([&] { core::TetMesh(y, {{0, 1, 2, 3}}, {}, 1e-6); }, {"element 0", "degenerate"});
    }
  }
}

TEST(TetMesh, FaceSharedByThreeElementsIsRefused) {
  // Three tets on the face (0, 1, 2): apexes above, below and far above.
  Positions x(3, 6);
  x << 0, 1, 0, 0.2, 0.2, 0.3,  //
      0, 0, 1, 0.2, 0.2, 0.3,   //
      0, 0, 0, 1, -1, 2;
  expect_invalid([&] { core::TetMesh(x, {{0, 1, 2, 3}, {0, 2, 1, 4}, {0, 1, 2, 5}}); },
                 {"face (0, 1, 2)", "more than two elements", "element 2"});
}

TEST(TetMesh, RegionsCountMaxIdPlusOne) {
  const HandMesh hm = cube_mesh(1, 1.0);
  std::vector<int> regions(hm.tets.size(), 0);
  regions[3] = 2;
  const core::TetMesh mesh(hm.x, hm.tets, regions);
  EXPECT_EQ(mesh.num_regions(), 3);
  EXPECT_EQ(mesh.regions(), regions);
  const core::TetMesh plain(hm.x, hm.tets);
  EXPECT_EQ(plain.regions(), std::vector<int>(hm.tets.size(), 0));
}

// Regions set after construction (the scene reader's order: the mesh first, then the
// regions selected on it) keep the shape, the boundary, the reoriented list and the node
// sets; a bad list is refused and leaves the regions as they were.
TEST(TetMesh, RegionsSetLaterKeepTheRestOfTheMesh) {
  Positions x(3, 5);
  x << 0, 1, 0, 0, 1,  //
      0, 0, 1, 0, 1,   //
      0, 0, 0, 1, 1;
  core::TetMesh mesh(x, {{0, 1, 2, 3}, {1, 3, 2, 4}});  // element 1 reoriented
  mesh.set_node_set("top", {4});
  const std::vector<Tri> boundary = mesh.boundary_triangles();
  mesh.set_regions({1, 4});
  EXPECT_EQ(mesh.regions(), (std::vector<int>{1, 4}));
  EXPECT_EQ(mesh.num_regions(), 5);
  EXPECT_EQ(mesh.boundary_triangles(), boundary);
  EXPECT_EQ(mesh.reoriented_elements(), std::vector<int>{1});
  EXPECT_EQ(mesh.node_set("top"), std::vector<int>{4});
  expect_invalid([&] { mesh.set_regions({0, -2}); }, {"element 1", "negative region id -2"});
  expect_invalid([&] { mesh.set_regions({0, 1, 2}); }, {"3 region ids for 2 elements"});
  EXPECT_EQ(mesh.regions(), (std::vector<int>{1, 4}));
  mesh.set_regions({});
  EXPECT_EQ(mesh.regions(), (std::vector<int>{0, 0}));
  EXPECT_EQ(mesh.num_regions(), 1);
}

TEST(TetMesh, NodeSets) {
  const HandMesh hm = cube_mesh(2, 1.0);
  core::TetMesh mesh(hm.x, hm.tets);
  EXPECT_TRUE(mesh.node_sets().empty());
  mesh.set_node_set("top", {8, 3, 8, 0, 26});
  EXPECT_EQ(mesh.node_set("top"), (std::vector<int>{0, 3, 8, 26}));  // sorted, unique
  mesh.set_node_set("top", {5});
  EXPECT_EQ(mesh.node_set("top"), std::vector<int>{5});  // replaced
  EXPECT_EQ(mesh.node_sets().size(), 1u);
  expect_invalid([&] { mesh.set_node_set("bad", {1, 27}); }, {"node set 'bad'", "node 27", "outside [0, 27)"});
  expect_invalid([&] { mesh.set_node_set("bad", {-2}); }, {"node set 'bad'", "node -2"});
  EXPECT_EQ(mesh.node_sets().count("bad"), 0u);
  try {
    mesh.node_set("missing");
    ADD_FAILURE() << "expected std::out_of_range";
  } catch (const std::out_of_range& e) {
    EXPECT_NE(std::string(e.what()).find("'missing'"), std::string::npos) << e.what();
  }
}

TEST(RenumberNodes, PreservesGeometryBoundaryAndNodeSets) {
  const HandMesh hm = cube_mesh(2, 0.25);
  core::TetMesh mesh(hm.x, hm.tets);
  mesh.set_node_set("corner", {0, 2, 26});
  std::vector<int> old_of_new(static_cast<size_t>(mesh.num_nodes()));
  std::iota(old_of_new.begin(), old_of_new.end(), 0);
  std::mt19937 rng(41);
  std::shuffle(old_of_new.begin(), old_of_new.end(), rng);
  const core::TetMesh r = core::renumber_nodes(mesh, old_of_new);
  ASSERT_EQ(r.num_nodes(), mesh.num_nodes());
  ASSERT_EQ(r.num_elements(), mesh.num_elements());
  for (int i = 0; i < r.num_nodes(); ++i)
    EXPECT_EQ(r.rest_positions().col(i), mesh.rest_positions().col(old_of_new[static_cast<size_t>(i)]));
  for (int e = 0; e < r.num_elements(); ++e) {
    EXPECT_DOUBLE_EQ(r.rest_volume(e), mesh.rest_volume(e));
    for (int a = 0; a < 4; ++a)
      EXPECT_EQ(old_of_new[static_cast<size_t>(r.tets()[static_cast<size_t>(e)][static_cast<size_t>(a)])],
                mesh.tets()[static_cast<size_t>(e)][static_cast<size_t>(a)]);
  }
  EXPECT_TRUE(r.reoriented_elements().empty()) << "the original was already reoriented";
  std::set<Tri> before, after;
  for (const Tri& t : mesh.boundary_triangles()) before.insert(canonical(t));
  for (Tri t : r.boundary_triangles()) {
    for (int& v : t) v = old_of_new[static_cast<size_t>(v)];
    after.insert(canonical(t));
  }
  EXPECT_EQ(before.size(), mesh.boundary_triangles().size());
  EXPECT_EQ(before, after);
  std::set<int> corner;
  for (int v : r.node_set("corner")) corner.insert(old_of_new[static_cast<size_t>(v)]);
  EXPECT_EQ(corner, (std::set<int>{0, 2, 26}));
  expect_invalid([&] { core::renumber_nodes(mesh, {0, 1, 2}); }, {"renumber_nodes", "wrong size"});
  std::vector<int> dup = old_of_new;
  dup[5] = dup[6];
  expect_invalid([&] { core::renumber_nodes(mesh, dup); }, {"renumber_nodes", "not a permutation"});
}
