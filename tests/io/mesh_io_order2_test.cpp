// gmsh files of 10-node tetrahedra (io/mesh_io.hpp, read_gmsh_any_order): hand-written MSH
// 2.2 and 4.1 files read into exactly the elements they describe (the corner mesh equal to
// the linear file's), malformed ones refused with the file and line or node, random
// mutations refused cleanly; and meshes gmsh itself writes at order 2 (the PyPI gmsh in
// .venv, run at test time): edge nodes on the curved surface, volume closer to the ball's.

#include "io/mesh_io.hpp"

#include "core/hyperelastic/shape_functions.hpp"
#include "io/gmsh_test_files.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <numeric>
#include <random>
#include <sstream>
#include <typeinfo>

namespace fio = fiberfem::io;
namespace core = fiberfem::core;
namespace hyper = fiberfem::core::hyperelastic;
using core::Vec3;
using fiberfem::testing::kTwoTets;
using fiberfem::testing::kTwoTets41;
using fiberfem::testing::kTwoQuadraticTets;
using fiberfem::testing::replace_once;

namespace {

// The same in MSH 4.1: kTwoTets41's entities, then nodes and elements in blocks (nodes in
// another order than the 2.2 file).
const std::string kTwoQuadraticTets41 = std::string(kTwoTets41).substr(0, std::string(kTwoTets41).find("$Nodes")) + R"($Nodes
2 14 10 109
2 1 0 6
20
30
40
102
105
106
1 0 0
0 1 0
-1 -1 0
0 -0.5 0
-0.5 0 0
0.5 0.5 0
3 1 0 8
10
50
101
103
104
107
108
109
0 0 -1
0 0 1
0.55 0 -0.55
-0.5 -0.5 -0.5
0 0.5 -0.5
-0.5 -0.5 0.5
0 0.5 0.5
0.5 0 0.5
$EndNodes
$Elements
2 3 2 4
2 1 9 1
2 20 30 40 106 105 102
3 1 11 2
3 10 20 40 30 101 102 103 104 105 106
4 50 40 30 20 107 105 108 109 106 102
$EndElements
)";

fio::OrderedMesh read_any(const std::string& text, const std::string& origin = "q.msh") {
  std::istringstream in(text);
  return fio::read_gmsh_any_order(in, origin);
}

void expect_error(const std::string& text, std::initializer_list<std::string> fragments) {
  fiberfem::testing::expect_mesh_error([&] { read_any(text); }, text, fragments);
}

// Per element, the positions of its nodes (gmsh order), for comparing two readings whose
// node numbers differ.
std::vector<Eigen::Matrix<double, 3, 10>> element_nodes(const hyper::ElementMesh& m) {
  std::vector<Eigen::Matrix<double, 3, 10>> out;
  for (int e = 0; e < m.num_elements(); ++e) out.push_back(m.element_positions(e));
  return out;
}

}  // namespace

TEST(GmshOrder2, HandWrittenFileGivesTheElementsItDescribes) {
  const fio::OrderedMesh q = read_any(kTwoQuadraticTets);
  std::istringstream lin(kTwoTets);
  const core::TetMesh linear = fio::read_gmsh(lin, "l.msh");
  // The corner mesh is the linear file's mesh: same nodes, tetrahedra (element 0
  // reoriented), regions and node sets (the groups' mid-edge nodes left out).
  EXPECT_EQ(q.corners.rest_positions(), linear.rest_positions());
  EXPECT_EQ(q.corners.tets(), linear.tets());
  EXPECT_EQ(q.corners.regions(), linear.regions());
  EXPECT_EQ(q.corners.reoriented_elements(), std::vector<int>{0});
  EXPECT_EQ(q.corners.node_sets(), linear.node_sets());
  const hyper::ElementMesh& m = q.elements;
  ASSERT_EQ(m.order(), 2);
  ASSERT_EQ(m.num_nodes(), 14);
  ASSERT_EQ(m.num_corner_nodes(), 5);
  // Edge nodes in file order after the corners: 101 is node 5, at (0.55, 0, -0.55).
  EXPECT_EQ(m.rest_positions().col(5), Vec3(0.55, 0, -0.55));
  EXPECT_EQ(m.edge_ends()[0], (std::array<int, 2>{0, 1}));  // 101 on 10-20
  // Every element's edge node k sits on the corner pair kTetEdges[k] of the (reoriented)
  // corners: at its midpoint, except the moved node 101.
  for (int e = 0; e < 2; ++e) {
    const Eigen::Matrix<double, 3, 10> X = m.element_positions(e);
    for (int k = 0; k < 6; ++k) {
      const Vec3 mid = 0.5 * (X.col(hyper::kTetEdges[static_cast<size_t>(k)][0]) + X.col(hyper::kTetEdges[static_cast<size_t>(k)][1]));
      const bool moved = m.elements()[static_cast<size_t>(e)][4 + static_cast<size_t>(k)] == 5;
      EXPECT_LT((X.col(4 + k) - (moved ? Vec3(0.55, 0, -0.55) : mid)).norm(), 1e-15) << e << ", " << k;
    }
  }
  // The curved element holds more than its straight version (the node moved outwards).
  const std::vector<double> v = hyper::element_volumes(m);
  EXPECT_GT(v[0], linear.rest_volume(0) * 1.01);
  EXPECT_NEAR(v[1], linear.rest_volume(1), 1e-15);
  // The linear reader refuses the file, saying how to read it.
  std::istringstream again(kTwoQuadraticTets);
  try {
    fio::read_gmsh(again, "q.msh");
    ADD_FAILURE() << "read_gmsh read 10-node tetrahedra";
  } catch (const fio::MeshFileError& e) {
    EXPECT_NE(std::string(e.what()).find("q.msh:30:"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("mesh.order: 2"), std::string::npos) << e.what();
  }
}

TEST(GmshOrder2, Version41GivesTheSameElements) {
  const fio::OrderedMesh a = read_any(kTwoQuadraticTets), b = read_any(kTwoQuadraticTets41);
  EXPECT_EQ(element_nodes(b.elements), element_nodes(a.elements));
  EXPECT_EQ(b.corners.regions(), a.corners.regions());
  std::vector<Vec3> base_a, base_b;
  for (int n : a.corners.node_set("base")) base_a.push_back(a.corners.rest_positions().col(n));
  for (int n : b.corners.node_set("base")) base_b.push_back(b.corners.rest_positions().col(n));
  auto less = [](const Vec3& p, const Vec3& q) { return std::lexicographical_compare(p.data(), p.data() + 3, q.data(), q.data() + 3); };
  std::sort(base_a.begin(), base_a.end(), less);
  std::sort(base_b.begin(), base_b.end(), less);
  EXPECT_EQ(base_b, base_a);
}

TEST(GmshOrder2, LinearFilesReadAtOrderOne) {
  const fio::OrderedMesh q = read_any(kTwoTets);
  std::istringstream lin(kTwoTets);
  const core::TetMesh linear = fio::read_gmsh(lin, "l.msh");
  EXPECT_EQ(q.elements.order(), 1);
  EXPECT_EQ(q.corners.rest_positions(), linear.rest_positions());
  EXPECT_EQ(q.corners.tets(), linear.tets());
  EXPECT_EQ(q.elements.num_nodes(), 5);
  // Through a file path, by extension (and the scale).
  const std::string path = ::testing::TempDir() + "/fiberfem_order2_test.msh";
  {
    std::ofstream f(path);
    f << kTwoQuadraticTets;
  }
  const fio::OrderedMesh p = fio::read_mesh_any_order(path, 1e-3);
  EXPECT_EQ(p.elements.order(), 2);
  EXPECT_EQ(p.elements.rest_positions(), 1e-3 * read_any(kTwoQuadraticTets).elements.rest_positions());
  std::remove(path.c_str());
  EXPECT_THROW(fio::read_mesh_any_order("/nonexistent/q.msh"), fio::MeshFileError);
}

TEST(GmshOrder2, MalformedFilesAreRefusedNamingWhatIsWrong) {
  const std::string ok = kTwoQuadraticTets;
  const std::string first = "3 11 2 9 1 10 20 40 30 101 102 103 104 105 106";
  expect_error(replace_once(ok, first, "3 4 2 9 1 10 20 40 30"), {"q.msh:31:", "mixes linear"});
  expect_error(replace_once(ok, first, "3 11 2 9 1 10 20 40 30 101 102 103 104 105"), {"q.msh:30:", "needs 10 nodes"});
  expect_error(replace_once(ok, first, "3 29 2 9 1 10 20 40 30 101 102 103 104 105 106 1 2 3 4 5 6 7 8 9 10"),
               {"q.msh:30:", "type 29", "order 1 or 2"});
  // Corner 30 of the second element used as an edge node of the first.
  expect_error(replace_once(ok, first, "3 11 2 9 1 10 20 40 30 101 102 103 104 105 30"), {"node 30", "corner", "mid-edge"});
  // The second element gives the shared edge 30-40 node 109 (which it also puts on 20-50).
  expect_error(replace_once(ok, "107 105 108 109 106 102", "107 109 108 109 106 102"),
               {"q.msh", "element 1: its node 7", "in element 1", "file order"});
  // The first element gives edge 10-20 node 107, which the second puts on 50-40.
  expect_error(replace_once(ok, first, "3 11 2 9 1 10 20 40 30 107 102 103 104 105 106"),
               {"q.msh", "element 1: its node 4", "in element 0"});
  // The second element gives the shared edge 30-40 its own new node (110) instead of 105.
  expect_error(replace_once(replace_once(ok, "107 105 108", "107 110 108"), "14\n10 0 0 -1", "15\n110 -0.5 0 0\n10 0 0 -1"),
               {"q.msh", "has two edge nodes", "element 0", "element 1"});
  // An edge node pulled through the opposite face tangles its element.
  expect_error(replace_once(ok, "101 0.55 0 -0.55", "101 -3 -3 3"), {"q.msh: element mesh: element 0", "tangled"});
}

// Seeded random mutations of the order-2 file are read or refused with MeshFileError (the
// ElementMesh checks behind the reader included); nothing else escapes.
TEST(GmshOrder2, RandomMutationsAreReadOrRefusedCleanly) {
  std::mt19937 rng(77);
  const std::string alphabet = "0123456789 -.$\n";
  const std::string text = kTwoQuadraticTets;
  int read = 0, refused = 0;
  for (int trial = 0; trial < 1500; ++trial) {
    std::string s = text;
    const int edits = 1 + static_cast<int>(rng() % 3);
    for (int k = 0; k < edits; ++k) {
      const size_t at = rng() % s.size();
      switch (rng() % 3) {
        case 0: s[at] = alphabet[rng() % alphabet.size()]; break;
        case 1: s.erase(at, 1 + rng() % 4); break;
        default: s.insert(at, s.substr(rng() % s.size(), 1 + rng() % 8));
      }
    }
    try {
      read_any(s);
      ++read;
    } catch (const fio::MeshFileError&) {
      ++refused;
    } catch (const std::exception& e) {
      ADD_FAILURE() << "trial " << trial << ": a " << typeid(e).name() << " escaped: " << e.what() << "\n" << s;
    }
  }
  EXPECT_GT(read, 0);
  EXPECT_GT(refused, 0);
}

// gmsh 4.13.1 (PyPI, .venv) meshes the unit ball at order 2 in MSH 4.1 and 2.2. gmsh puts
// the mid-edge nodes of boundary edges on the sphere: every node of every boundary face
// is at radius 1 (to gmsh's geometric tolerance), and the curved mesh's volume is far
// closer to 4 pi / 3 than the linear corner mesh's.
TEST(GmshOrder2, FilesGmshWritesAtOrderTwo) {
  const std::string dir = ::testing::TempDir() + "/fiberfem_gmsh_order2";
  ASSERT_EQ(std::system(("mkdir -p " + dir).c_str()), 0);
  {
    std::ofstream f(dir + "/ball.py");
    f << R"(import sys, gmsh
gmsh.initialize()
gmsh.option.setNumber("General.Terminal", 0)
gmsh.option.setNumber("General.NumThreads", 1)
gmsh.option.setNumber("Mesh.RandomSeed", 1)
gmsh.model.add("ball")
gmsh.model.occ.addSphere(0, 0, 0, 1.0)
gmsh.model.occ.synchronize()
gmsh.model.addPhysicalGroup(3, [1], 5, "ball")
gmsh.model.addPhysicalGroup(2, [1], 6, "surface")
gmsh.option.setNumber("Mesh.MeshSizeMin", 0.3)
gmsh.option.setNumber("Mesh.MeshSizeMax", 0.6)
gmsh.option.setNumber("Mesh.ElementOrder", 2)
gmsh.option.setNumber("Mesh.Binary", 0)
gmsh.model.mesh.generate(3)
for version in (4.1, 2.2):
    gmsh.option.setNumber("Mesh.MshFileVersion", version)
    gmsh.write(sys.argv[1] + "/ball%s.msh" % version)
gmsh.finalize()
)";
  }
  const std::string cmd = std::string(FIBERFEM_PYTHON) + " " + dir + "/ball.py " + dir;
  ASSERT_EQ(std::system(cmd.c_str()), 0) << "gmsh not available: run scripts/setup.sh (" << cmd << ")";
  const double ball = 4.0 * std::acos(-1.0) / 3;
  std::vector<double> volumes;
  for (const char* name : {"ball4.1.msh", "ball2.2.msh"}) {
    SCOPED_TRACE(name);
    const fio::OrderedMesh q = fio::read_mesh_any_order(dir + "/" + name);
    const hyper::ElementMesh& m = q.elements;
    ASSERT_EQ(m.order(), 2);
    EXPECT_EQ(q.corners.regions(), std::vector<int>(static_cast<size_t>(m.num_elements()), 5));
    ASSERT_EQ(q.corners.node_sets().count("surface"), 1u);
    EXPECT_EQ(q.corners.node_set("surface"), q.corners.boundary_nodes());
    double worst = 0;
    for (const auto& face : m.boundary_faces())
      for (int n : face) worst = std::max(worst, std::abs(m.rest_positions().col(n).norm() - 1));
    EXPECT_LT(worst, 1e-6);
    const std::vector<double> v = hyper::element_volumes(m);
    const double curved = std::accumulate(v.begin(), v.end(), 0.0);
    const double error2 = std::abs(curved - ball) / ball, error1 = std::abs(q.corners.total_volume() - ball) / ball;
    std::printf("%s: %d elements, volume error linear %.3e, quadratic %.3e\n", name, m.num_elements(), error1, error2);
    EXPECT_GT(error1 / error2, 5);
    volumes.push_back(curved);
    std::ifstream f(dir + "/" + name);
    EXPECT_THROW(fio::read_gmsh(f, name), fio::MeshFileError);
  }
  EXPECT_NEAR(volumes[0], volumes[1], 1e-12);
}
