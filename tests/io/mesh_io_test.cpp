// gmsh MSH 2.2 ASCII: a hand-written file read into exactly the mesh it describes,
// write/read round trips, and malformed files refused with the file and line.

#include "io/mesh_io.hpp"

#include "core/box_generator.hpp"
#include "io/gmsh_test_files.hpp"
#include "test_support.hpp"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <random>
#include <sstream>
#include <typeinfo>

namespace fio = fiberfem::io;
namespace core = fiberfem::core;
using core::Vec3;

namespace {

using fiberfem::testing::kTwoTets;
using fiberfem::testing::kTwoTets41;
using fiberfem::testing::replace_once;

core::TetMesh read(const std::string& text, double scale = 1.0) {
  std::istringstream in(text);
  return fio::read_gmsh(in, "test.msh", scale);
}

void expect_error(const std::string& text, std::initializer_list<std::string> fragments) {
  fiberfem::testing::expect_mesh_error([&] { read(text); }, text, fragments);
}

}  // namespace

TEST(Gmsh22, HandWrittenFileGivesTheMeshItDescribes) {
  const core::TetMesh m = read(kTwoTets, 1e-3);
  ASSERT_EQ(m.num_nodes(), 5);
  ASSERT_EQ(m.num_elements(), 2);
  // Node 40 (index 3) at (-1, -1, 0) mm.
  EXPECT_LT((m.rest_positions().col(3) - Vec3(-1e-3, -1e-3, 0)).norm(), 1e-18);
  // Volumes by hand: base triangle (1,0,0), (0,1,0), (-1,-1,0) has area 1.5 mm^2; apexes at
  // z = -1 and +1 mm: each tet 1.5 * 1 / 3 = 0.5 mm^3.
  EXPECT_NEAR(m.total_volume(), 1e-9, 1e-21);
  EXPECT_EQ(m.regions()[0], 9);
  EXPECT_EQ(m.reoriented_elements(), std::vector<int>{0});  // given with negative volume
  ASSERT_EQ(m.node_sets().count("base"), 1u);
  EXPECT_EQ(m.node_set("base"), (std::vector<int>{1, 2, 3}));
}

TEST(Gmsh22, WriteThenReadIsTheSameMesh) {
  core::BoxSpec b;
  b.size_m = {0.03, 0.01, 0.02};
  b.cells = {3, 2, 2};
  core::TetMesh box = core::make_box(b);
  std::vector<int> regions(static_cast<size_t>(box.num_elements()));
  for (size_t e = 0; e < regions.size(); ++e) regions[e] = static_cast<int>(e % 3);
  core::TetMesh m(box.rest_positions(), box.tets(), regions);
  for (const auto& [name, nodes] : box.node_sets()) m.set_node_set(name, nodes);
  std::stringstream s;
  fio::write_gmsh22(m, s);
  const core::TetMesh r = fio::read_gmsh(s, "roundtrip.msh");
  EXPECT_EQ(r.rest_positions(), m.rest_positions());  // 17 digits: exact
  EXPECT_EQ(r.tets(), m.tets());
  EXPECT_EQ(r.regions(), m.regions());
  EXPECT_EQ(r.node_sets(), m.node_sets());
  // Through a file, by extension.
  const std::string path = ::testing::TempDir() + "/fiberfem_mesh_io_test.msh";
  {
    std::ofstream f(path);
    fio::write_gmsh22(m, f);
  }
  EXPECT_EQ(fio::read_mesh(path, 2.0).rest_positions(), 2.0 * m.rest_positions());
  std::remove(path.c_str());
}

TEST(Gmsh22, MalformedFilesNameTheFileAndLine) {
  const std::string ok = kTwoTets;
  expect_error(replace_once(ok, "2.2 0 8", "3.0 0 8"), {"test.msh:2:", "not supported"});
  expect_error(replace_once(ok, "2.2 0 8", "2.2 1 8"), {"test.msh:2:", "binary"});
  expect_error(replace_once(ok, "20 1 0 0", "20 1 zero 0"), {"test.msh:12:", "'zero'"});
  expect_error(replace_once(ok, "30 0 1 0", "20 0 1 0"), {"test.msh:13:", "given twice"});
  expect_error(replace_once(ok, "4 4 2 9 1 50 40 30 20", "4 4 2 9 1 50 40 30 99"), {"test.msh:22:", "node 99"});
  expect_error(replace_once(ok, "4 4 2 9 1 50 40 30 20", "4 4 2 9 1 50 40 30"), {"test.msh:22:", "needs 4 nodes"});
  expect_error(replace_once(ok, "3 4 2 9 1 10 20 40 30", "3 11 2 9 1 10 20 40 30 1 2 3 4 5 6"), {"10-node tetrahedron", "mesh.order: 2"});
  expect_error(replace_once(ok, "$EndNodes", "$EndNodez"), {"test.msh:16:", "$EndNodes"});
  expect_error(ok.substr(0, ok.find("$Elements") + 12), {"unexpected end of file"});
  expect_error(replace_once(ok, "50 0 0 1", "50 0 0 0"), {"test.msh", "degenerate"});  // flat second tet
  expect_error("hello\n", {"test.msh:1:", "section"});
  // Found by fuzzing: an id too large for an integer (casting it was undefined behaviour).
  expect_error(replace_once(ok, "20 1 0 0", "22222222222222222222222222222222222222222 1 0 0"),
               {"test.msh:12:", "node id must be an integer"});
  expect_error(replace_once(ok, "4 4 2 9 1 50 40 30 20", "4 4 2 3000000000 1 50 40 30 20"),
               {"test.msh:22:", "physical tag must be an integer"});
  expect_error("", {"no $MeshFormat"});
  EXPECT_THROW(fio::read_mesh("/nonexistent/x.msh"), fio::MeshFileError);
  EXPECT_THROW(fio::read_mesh("mesh.stl"), fio::MeshFileError);
}

// The same two tetrahedra in MSH 4.1 (entities carry the physical tags; node and element
// blocks): the same mesh as the 2.2 file.
TEST(Gmsh41, SameMeshAsTheVersion22File) {
  const std::string v41 = kTwoTets41;
  std::istringstream a(kTwoTets), b(v41);
  const core::TetMesh m2 = fio::read_gmsh(a, "v22.msh", 1e-3), m4 = fio::read_gmsh(b, "v41.msh", 1e-3);
  // Nodes come in a different order: compare through positions.
  ASSERT_EQ(m4.num_nodes(), m2.num_nodes());
  ASSERT_EQ(m4.num_elements(), m2.num_elements());
  EXPECT_EQ(m4.regions(), m2.regions());
  EXPECT_NEAR(m4.total_volume(), m2.total_volume(), 1e-24);
  for (int e = 0; e < m2.num_elements(); ++e)
    for (int k = 0; k < 4; ++k)
      EXPECT_EQ(m4.rest_positions().col(m4.tets()[static_cast<size_t>(e)][static_cast<size_t>(k)]),
                m2.rest_positions().col(m2.tets()[static_cast<size_t>(e)][static_cast<size_t>(k)]));
  ASSERT_EQ(m4.node_sets().count("base"), 1u);
  std::vector<Vec3> base2, base4;
  for (int n : m2.node_set("base")) base2.push_back(m2.rest_positions().col(n));
  for (int n : m4.node_set("base")) base4.push_back(m4.rest_positions().col(n));
  auto less = [](const Vec3& p, const Vec3& q) { return std::lexicographical_compare(p.data(), p.data() + 3, q.data(), q.data() + 3); };
  std::sort(base2.begin(), base2.end(), less);
  std::sort(base4.begin(), base4.end(), less);
  EXPECT_EQ(base4, base2);
  // A block that holds fewer nodes than the header claims.
  std::istringstream c(replace_once(v41, "2 5 10 50", "2 6 10 50"));
  EXPECT_THROW(fio::read_gmsh(c, "v41.msh"), fio::MeshFileError);
}

// TetGen: the two tetrahedra again (index base 0, comments, a boundary marker column, a
// region attribute): the same mesh as the gmsh file; and errors name the right file.
TEST(TetGen, SameMeshAsTheGmshFile) {
  const std::string node = "# points\n5 3 0 1\n0 0 0 -1 1\n1 1 0 0 0\n2 0 1 0 0\n3 -1 -1 0 0\n4 0 0 1 1\n";
  const std::string ele = "2 4 1\n0 0 1 3 2 9   # the first, negatively oriented\n1 4 3 2 1 9\n";
  std::istringstream n(node), e(ele), g(kTwoTets);
  const core::TetMesh t = fio::read_tetgen(n, "m.node", e, "m.ele", 1e-3);
  const core::TetMesh m = fio::read_gmsh(g, "m.msh", 1e-3);
  EXPECT_EQ(t.rest_positions(), m.rest_positions());
  EXPECT_EQ(t.tets(), m.tets());
  EXPECT_EQ(t.regions(), m.regions());
  const std::string ele7 = replace_once(ele, "1 4 3 2 1 9", "1 4 3 2 7 9");
  std::istringstream n2(node), e2(ele7);
  fiberfem::testing::expect_mesh_error([&] { fio::read_tetgen(n2, "m.node", e2, "m.ele"); }, ele7, {"m.ele:3:", "point 7"});
  std::istringstream n3(replace_once(node, "1 1 0 0 0", "1 1 0 0")), e3(ele);
  EXPECT_THROW(fio::read_tetgen(n3, "m.node", e3, "m.ele"), fio::MeshFileError);
}

// Point ids need not run consecutively: ids out of sequence (a gap, then a smaller one)
// give the same mesh as the same points numbered from 0, and an id given twice after them
// is refused by line.
TEST(TetGen, PointIdsInAnyOrder) {
  const std::string node = "5 3 0 0\n0 0 0 -1\n1 1 0 0\n2 0 1 0\n3 -1 -1 0\n4 0 0 1\n";
  const std::string ele = "2 4 0\n0 0 1 3 2\n1 4 3 2 1\n";
  const std::string node_ids = "5 3 0 0\n10 0 0 -1\n11 1 0 0\n30 0 1 0\n12 -1 -1 0\n7 0 0 1\n";
  const std::string ele_ids = "2 4 0\n0 10 11 12 30\n1 7 12 30 11\n";
  std::istringstream n(node), e(ele), ni(node_ids), ei(ele_ids);
  const core::TetMesh a = fio::read_tetgen(n, "a.node", e, "a.ele");
  const core::TetMesh b = fio::read_tetgen(ni, "b.node", ei, "b.ele");
  EXPECT_EQ(b.rest_positions(), a.rest_positions());
  EXPECT_EQ(b.tets(), a.tets());
  const std::string twice = replace_once(node_ids, "7 0 0 1", "11 0 0 1");
  std::istringstream nd(twice), ed(ele_ids);
  fiberfem::testing::expect_mesh_error([&] { fio::read_tetgen(nd, "d.node", ed, "d.ele"); }, twice,
                                       {"d.node:6:", "point 11 is given twice"});
  std::istringstream nm(node_ids), em(replace_once(ele_ids, "1 7 12 30 11", "1 7 12 13 11"));
  EXPECT_THROW(fio::read_tetgen(nm, "m.node", em, "m.ele"), fio::MeshFileError);  // no point 13
}

// The numbers of a TetGen file are read as a string stream reads them (the reader parses
// with from_chars): every token below is accepted or refused the same way, and an
// accepted one gives the stream's value, bit for bit.
TEST(TetGen, NumbersReadAsAStringStreamReadsThem) {
  const std::string node = "5 3 0 0\n0 0 0 -1\n1 1 0 0\n2 0 1 0\n3 -1 -1 0\n4 0 0 1\n";
  const std::string ele = "2 4 0\n0 0 1 3 2\n1 4 3 2 1\n";
  for (const std::string tok : {"+1.5", "1.5", "-2.5e-3", "1E2", ".5", "5.", "-0", "1.5x", "x", "nan", "inf", "-inf",
                                "+-1", "++1", "1e400", "0x10", "1..5", "-", "+", "1e", "3.0000000000000004"}) {
    std::istringstream ref(tok);
    double expected = 0;
    const bool stream_reads = static_cast<bool>(ref >> expected) && ref.eof();
    std::istringstream n(replace_once(node, "4 0 0 1\n", "4 0 0 " + tok + "\n")), e(ele);
    try {
      const core::TetMesh m = fio::read_tetgen(n, "f.node", e, "f.ele");
      EXPECT_TRUE(stream_reads) << "'" << tok << "' was read, a stream refuses it";
      EXPECT_EQ(m.rest_positions()(2, 4), expected) << tok;
    } catch (const fio::MeshFileError& err) {
      EXPECT_FALSE(stream_reads && expected > 0) << "'" << tok << "' refused: " << err.what();
    }
  }
  std::istringstream n(node), e(replace_once(ele, "1 4 3 2 1", "1 +4 3 2 1.5"));
  EXPECT_THROW(fio::read_tetgen(n, "f.node", e, "f.ele"), fio::MeshFileError);  // a point id 1.5
}

// Legacy VTK: the two tetrahedra with a triangle cell to ignore and region tags in
// CELL_DATA, points spread over lines as VTK allows: the same mesh as the gmsh file.
TEST(Vtk, SameMeshAsTheGmshFile) {
  const std::string vtk = R"(# vtk DataFile Version 2.0
two tets
ASCII
DATASET UNSTRUCTURED_GRID
POINTS 5 double
0 0 -1 1 0 0
0 1 0 -1 -1 0 0 0 1
CELLS 3 14
3 1 2 3
4 0 1 3 2
4 4 3 2 1
CELL_TYPES 3
5
10
10
CELL_DATA 3
SCALARS region int 1
LOOKUP_TABLE default
7 9 9
)";
  std::istringstream v(vtk), g(kTwoTets);
  const core::TetMesh t = fio::read_vtk(v, "m.vtk", 1e-3);
  const core::TetMesh m = fio::read_gmsh(g, "m.msh", 1e-3);
  EXPECT_EQ(t.rest_positions(), m.rest_positions());
  EXPECT_EQ(t.tets(), m.tets());
  EXPECT_EQ(t.regions(), m.regions());
  auto bad = [&](const std::string& from, const std::string& to, const std::string& fragment) {
    std::istringstream in(replace_once(vtk, from, to));
    try {
      fio::read_vtk(in, "m.vtk");
      ADD_FAILURE() << "expected an error for " << to;
    } catch (const fio::MeshFileError& e) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    }
  };
  bad("4 4 3 2 1", "4 4 3 2 9", "m.vtk:11:");
  bad("ASCII", "BINARY", "only ASCII");
  bad("0 1 0 -1 -1 0 0 0 1", "0 1 0 -1 -1 0 0 0 x", "'x'");
  bad("7 9 9", "7 9 -2", "non-negative");
  // A floating-point array before the tags is data, not tags (found in review).
  std::istringstream with_stress(replace_once(vtk, "SCALARS region int 1", "SCALARS stress double 1\nLOOKUP_TABLE default\n1.5 -2.25 0.5\nSCALARS region int 1"));
  EXPECT_EQ(fio::read_vtk(with_stress, "m.vtk", 1e-3).regions(), m.regions());
  bad("# vtk DataFile Version 2.0", "hello", "not a legacy VTK");
}

// Robustness: thousands of seeded random mutations of valid files (bytes flipped, deleted,
// duplicated, lines swapped, truncation) either read or are refused with MeshFileError;
// nothing else escapes and nothing crashes (run under the sanitizers in the debug preset).
// A libFuzzer target with a kept corpus is still to come (issue 3).
TEST(MeshReaders, RandomMutationsAreReadOrRefusedCleanly) {
  const std::string vtk = "# vtk DataFile Version 2.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 5 double\n"
                          "0 0 -1 1 0 0 0 1 0 -1 -1 0 0 0 1\nCELLS 2 10\n4 0 1 3 2\n4 4 3 2 1\nCELL_TYPES 2\n10\n10\n";
  const std::string node = "5 3 0 0\n0 0 0 -1\n1 1 0 0\n2 0 1 0\n3 -1 -1 0\n4 0 0 1\n";
  const std::string ele = "2 4 1\n0 0 1 3 2 9\n1 4 3 2 1 9\n";
  std::mt19937 rng(2024);
  const std::string alphabet = "0123456789 -.eE$\n\"#abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ";
  auto mutate = [&](std::string s) {
    const int edits = 1 + static_cast<int>(rng() % 4);
    for (int k = 0; k < edits && !s.empty(); ++k) {
      const size_t at = rng() % s.size();
      switch (rng() % 5) {
        case 0: s[at] = alphabet[rng() % alphabet.size()]; break;
        case 1: s.erase(at, 1 + rng() % 8); break;
        case 2: s.insert(at, s.substr(rng() % s.size(), 1 + rng() % 16)); break;
        case 3: s.resize(at); break;
        default: {
          const size_t b = rng() % s.size();
          std::swap(s[at], s[b]);
        }
      }
    }
    return s;
  };
  int read = 0, refused = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    const int which = trial % 4;
    try {
      if (which == 0) {
        std::istringstream in(mutate(kTwoTets));
        fio::read_gmsh(in, "f.msh");
      } else if (which == 1) {
        std::istringstream in(mutate(vtk));
        fio::read_vtk(in, "f.vtk");
      } else if (which == 2) {
        std::istringstream n(mutate(node)), e(ele);
        fio::read_tetgen(n, "f.node", e, "f.ele");
      } else {
        std::istringstream n(node), e(mutate(ele));
        fio::read_tetgen(n, "f.node", e, "f.ele");
      }
      ++read;
    } catch (const fio::MeshFileError&) {
      ++refused;
    } catch (const std::exception& e) {
      ADD_FAILURE() << "trial " << trial << ": a " << typeid(e).name() << " escaped: " << e.what();
    }
  }
  // Absurd counts are refused, not allocated.
  std::istringstream big(replace_once(kTwoTets, "$Nodes\n5", "$Nodes\n999999999999"));
  EXPECT_THROW(fio::read_gmsh(big, "f.msh"), fio::MeshFileError);
  std::istringstream bigv(replace_once(vtk, "POINTS 5", "POINTS 999999999999"));
  EXPECT_THROW(fio::read_vtk(bigv, "f.vtk"), fio::MeshFileError);
  std::istringstream bign(replace_once(node, "5 3 0 0", "999999999999 3 0 0")), e0(ele);
  EXPECT_THROW(fio::read_tetgen(bign, "f.node", e0, "f.ele"), fio::MeshFileError);
  EXPECT_GT(refused, 1000);
  EXPECT_GT(read, 10);  // some mutations are harmless (e.g. in a coordinate's last digit)
}

// The shipped heart mesh (meshes/biventricle.msh) carries two volume tags so that a scene can
// select the RV free wall as a region: tag 2 for every tetrahedron whose centroid lies outside
// the LV epicardium, the ellipsoid of scripts/make_biventricle.py (semi-axes 0.025, 0.025,
// 0.045 m about the origin), tag 1 for the rest (LV free wall and septum). Checked against the
// ellipsoid restated here; the RV free wall is on the +x side and in the RV epicardium's
// ellipsoid (centre (0.012, 0, 0.004), semi-axes 0.032, 0.026, 0.040).
TEST(ShippedMeshes, TheBiventricleTagsTheRvFreeWallOutsideTheLvEpicardium) {
  const core::TetMesh m = fio::read_mesh(std::string(FIBERFEM_SOURCE_DIR) + "/meshes/biventricle.msh");
  auto level = [](const Vec3& p, const Vec3& c, const Vec3& r) { return ((p - c).array() / r.array()).square().sum() - 1.0; };
  const Vec3 origin(0, 0, 0), lv_epi(0.025, 0.025, 0.045), rv_centre(0.012, 0, 0.004), rv_epi(0.032, 0.026, 0.040);
  int count[3] = {0, 0, 0};
  for (int e = 0; e < m.num_elements(); ++e) {
    Vec3 centroid = Vec3::Zero();
    for (int n : m.tets()[static_cast<size_t>(e)]) centroid += m.rest_positions().col(n) / 4.0;
    const int tag = m.regions()[static_cast<size_t>(e)];
    ASSERT_TRUE(tag == 1 || tag == 2) << "element " << e << " has tag " << tag;
    ++count[tag];
    EXPECT_EQ(tag == 2, level(centroid, origin, lv_epi) > 0) << "element " << e;
    if (tag == 2) {
      EXPECT_GT(centroid.x(), 0.0) << "element " << e;
      EXPECT_LT(level(centroid, rv_centre, rv_epi), 0.05) << "element " << e;  // within a tet of the RV epicardium
    }
  }
  EXPECT_GT(count[2], m.num_elements() / 10);
  EXPECT_GT(count[1], m.num_elements() / 2);
}
