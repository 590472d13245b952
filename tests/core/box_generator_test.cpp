// Structured box meshes (core/box_generator.hpp): counts, volumes, grid positions, a
// conformity check that counts face uses independently of TetMesh, boundary area, node
// sets against coordinates, numbering bandwidth, cell-by-cell element order, bad specs.

#include "core/box_generator.hpp"
#include "test_support.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <set>

namespace core = fiberfem::core;
using core::Vec3;
using fiberfem::testing::expect_invalid;

namespace {

core::BoxSpec spec_of(Vec3 size, std::array<int, 3> cells, Vec3 origin = Vec3::Zero()) {
  core::BoxSpec s;
  s.size_m = size;
  s.cells = cells;
  s.origin_m = origin;
  return s;
}

std::vector<core::BoxSpec> specs() {
  return {spec_of({1, 1, 1}, {1, 1, 1}),
          spec_of({0.3, 0.2, 0.5}, {2, 3, 4}, {-1, 2, 0.5}),
          spec_of({0.1, 0.01, 0.01}, {20, 2, 2}),
          spec_of({0.02, 0.05, 0.01}, {1, 5, 2}, {0.01, -0.02, 3}),
          spec_of({2, 2, 2}, {3, 3, 3})};
}

}  // namespace

TEST(MakeBox, CountsVolumesAndPositions) {
  for (const core::BoxSpec& s : specs()) {
    const auto [nx, ny, nz] = s.cells;
    const core::TetMesh m = core::make_box(s);
    SCOPED_TRACE(testing::Message() << "cells " << nx << "x" << ny << "x" << nz);
    ASSERT_EQ(m.num_nodes(), (nx + 1) * (ny + 1) * (nz + 1));
    ASSERT_EQ(m.num_elements(), 6 * nx * ny * nz);
    EXPECT_EQ(m.num_regions(), 1);
    EXPECT_TRUE(m.reoriented_elements().empty());
    const double box_volume = s.size_m.prod();
    EXPECT_NEAR(m.total_volume(), box_volume, 1e-12 * box_volume);
    const double cell_volume = box_volume / (nx * ny * nz);
    for (int e = 0; e < m.num_elements(); ++e) {
      const core::Tet& t = m.tets()[static_cast<size_t>(e)];
      const auto& x = m.rest_positions();
      const double v = core::signed_volume(x.col(t[0]), x.col(t[1]), x.col(t[2]), x.col(t[3]));
      EXPECT_GT(v, 0) << "element " << e;
      // Kuhn tetrahedra all have a sixth of the cell volume.
      EXPECT_NEAR(v, cell_volume / 6, 1e-10 * cell_volume) << "element " << e;
    }
    // Nodes are exactly the grid points, each once.
    std::set<std::array<long, 3>> grid;
    for (int i = 0; i < m.num_nodes(); ++i) {
      std::array<long, 3> ijk{};
      for (int d = 0; d < 3; ++d) {
        const double u = (m.rest_positions()(d, i) - s.origin_m[d]) / s.size_m[d] * s.cells[static_cast<size_t>(d)];
        ijk[static_cast<size_t>(d)] = std::lround(u);
        EXPECT_NEAR(u, static_cast<double>(ijk[static_cast<size_t>(d)]), 1e-9);
        EXPECT_GE(ijk[static_cast<size_t>(d)], 0);
        EXPECT_LE(ijk[static_cast<size_t>(d)], s.cells[static_cast<size_t>(d)]);
      }
      grid.insert(ijk);
    }
    EXPECT_EQ(grid.size(), static_cast<size_t>(m.num_nodes()));
    const auto [lo, hi] = m.bounding_box();
    EXPECT_LT((lo - s.origin_m).norm(), 1e-12);
    EXPECT_LT((hi - s.origin_m - s.size_m).norm(), 1e-12);
  }
}

// Conforming: counting every element face (as a sorted node triple) here, interior faces
// are used exactly twice and the rest once; the once-used ones are the 2 * 2 (nx ny + ny nz
// + nz nx) triangles of the box surface, with total area 2 (ab + bc + ca).
TEST(MakeBox, ConformingWithTheRightBoundary) {
  for (const core::BoxSpec& s : specs()) {
    const auto [nx, ny, nz] = s.cells;
    const core::TetMesh m = core::make_box(s);
    SCOPED_TRACE(testing::Message() << "cells " << nx << "x" << ny << "x" << nz);
    const std::map<std::array<int, 3>, int> uses = fiberfem::testing::face_uses(m.tets());
    int once = 0, twice = 0;
    for (const auto& [f, n] : uses) {
      EXPECT_TRUE(n == 1 || n == 2) << "face used " << n << " times";
      (n == 1 ? once : twice) += 1;
    }
    const int expected_boundary = 4 * (nx * ny + ny * nz + nz * nx);
    EXPECT_EQ(once, expected_boundary);
    EXPECT_EQ(static_cast<int>(m.boundary_triangles().size()), expected_boundary);
    EXPECT_EQ(once + 2 * twice, 4 * m.num_elements());
    double area = 0;
    for (const core::Tri& t : m.boundary_triangles()) {
      const auto& x = m.rest_positions();
      area += 0.5 * (x.col(t[1]) - x.col(t[0])).cross(x.col(t[2]) - x.col(t[0])).norm();
    }
    const Vec3& L = s.size_m;
    const double expected_area = 2 * (L.x() * L.y() + L.y() * L.z() + L.z() * L.x());
    EXPECT_NEAR(area, expected_area, 1e-12 * expected_area);
  }
}

TEST(MakeBox, NodeSetsHoldExactlyTheFaceNodes) {
  for (const core::BoxSpec& s : specs()) {
    const core::TetMesh m = core::make_box(s);
    const char* names[3][2] = {{"xmin", "xmax"}, {"ymin", "ymax"}, {"zmin", "zmax"}};
    EXPECT_EQ(m.node_sets().size(), 6u);
    for (int d = 0; d < 3; ++d)
      for (int side = 0; side < 2; ++side) {
        const double plane = s.origin_m[d] + side * s.size_m[d];
        std::vector<int> expected;
        for (int i = 0; i < m.num_nodes(); ++i)
          if (std::abs(m.rest_positions()(d, i) - plane) < 1e-9 * s.size_m[d]) expected.push_back(i);
        const auto& set = m.node_set(names[d][side]);
        EXPECT_EQ(set, expected) << names[d][side];
        size_t face_nodes = 1;
        for (int o = 0; o < 3; ++o)
          if (o != d) face_nodes *= static_cast<size_t>(s.cells[static_cast<size_t>(o)] + 1);
        EXPECT_EQ(set.size(), face_nodes) << names[d][side];
      }
  }
}

// The axis with the most cells varies slowest, so nodes of one element differ in number by
// at most (one step along each axis) nn1 nn2 + nn2 + 1, nn1 >= nn2 the two other axes' node counts.
TEST(MakeBox, NumberingKeepsTheBandwidthSmall) {
  for (std::array<int, 3> cells : {std::array<int, 3>{20, 2, 2}, {2, 20, 2}, {2, 2, 20}, {3, 10, 5}}) {
    const core::TetMesh m = core::make_box(spec_of({1, 1, 1}, cells));
    std::array<int, 3> nn{cells[0] + 1, cells[1] + 1, cells[2] + 1};
    std::sort(nn.begin(), nn.end());  // nn[2] belongs to the slowest axis
    const int bound = nn[1] * nn[0] + nn[0] + 1;
    int bandwidth = 0;
    for (const core::Tet& t : m.tets())
      for (int a : t)
        for (int b : t) bandwidth = std::max(bandwidth, std::abs(a - b));
    EXPECT_LE(bandwidth, bound) << cells[0] << "x" << cells[1] << "x" << cells[2];
  }
}

// Elements come cell by cell: each run of six covers one cell (8 distinct nodes, bounding
// box one cell) and all six share the cell's main diagonal.
TEST(MakeBox, ElementsAreOrderedCellByCell) {
  const core::BoxSpec s = spec_of({0.3, 0.2, 0.5}, {2, 3, 4}, {-1, 2, 0.5});
  const core::TetMesh m = core::make_box(s);
  const Vec3 cell = s.size_m.cwiseQuotient(Vec3(2, 3, 4));
  for (int c = 0; c < m.num_elements() / 6; ++c) {
    std::map<int, int> count;
    for (int e = 6 * c; e < 6 * c + 6; ++e)
      for (int v : m.tets()[static_cast<size_t>(e)]) count[v] += 1;
    EXPECT_EQ(count.size(), 8u) << "cell " << c;
    int shared_by_all = 0;
    Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
    for (const auto& [v, n] : count) {
      shared_by_all += n == 6;
      lo = lo.cwiseMin(m.rest_positions().col(v));
      hi = hi.cwiseMax(m.rest_positions().col(v));
    }
    EXPECT_EQ(shared_by_all, 2) << "cell " << c;
    EXPECT_LT((hi - lo - cell).norm(), 1e-12) << "cell " << c;
  }
}

TEST(BoxSpec, DefaultsAreTheDocumentedBeam) {
  const core::BoxSpec s;
  EXPECT_EQ(s.size_m, Vec3(0.1, 0.01, 0.01));
  EXPECT_EQ(s.cells, (std::array<int, 3>{20, 2, 2}));
  EXPECT_EQ(s.origin_m, Vec3::Zero());
  EXPECT_NO_THROW(s.validate());
}

TEST(BoxSpec, ValidateNamesTheField) {
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  auto size = [](Vec3 v) { return spec_of(v, {1, 1, 1}); };
  expect_invalid([&] { size({0, 1, 1}).validate(); }, {"size_m.x", "> 0"});
  expect_invalid([&] { size({1, -1, 1}).validate(); }, {"size_m.y", "> 0"});
  expect_invalid([&] { size({1, 1, nan}).validate(); }, {"size_m.z"});
  expect_invalid([&] { size({inf, 1, 1}).validate(); }, {"size_m.x"});
  expect_invalid([&] { spec_of({1, 1, 1}, {0, 1, 1}).validate(); }, {"cells.x", ">= 1"});
  expect_invalid([&] { spec_of({1, 1, 1}, {1, -3, 1}).validate(); }, {"cells.y", "got -3"});
  expect_invalid([&] { spec_of({1, 1, 1}, {1, 1, 0}).validate(); }, {"cells.z"});
  expect_invalid([&] { spec_of({1, 1, 1}, {1, 1, 1}, {0, nan, 0}).validate(); }, {"origin_m.y", "finite"});
  expect_invalid([&] { spec_of({1, 1, 1}, {1, 1, 1}, {0, 0, -inf}).validate(); }, {"origin_m.z", "finite"});
  expect_invalid([&] { spec_of({1, 1, 1}, {1000, 1000, 1000}).validate(); }, {"too many nodes"});
  // make_box validates too.
  expect_invalid([&] { core::make_box(spec_of({1, 1, 1}, {2, 0, 2})); }, {"cells.y"});
}
