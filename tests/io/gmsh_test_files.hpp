#pragma once
/// @file gmsh files shared by the mesh reader tests (tests/io/mesh_io_test.cpp,
/// tests/io/mesh_io_order2_test.cpp) and a check of their refusals.

#include "io/mesh_io.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <initializer_list>
#include <string>

namespace fiberfem::testing {

// Two tetrahedra sharing the face (2, 3, 4) of a unit-ish bipyramid, in millimetres, with
// non-contiguous node ids, a named physical surface group and a line element to ignore.
inline const char* kTwoTets = R"($MeshFormat
2.2 0 8
$EndMeshFormat
$PhysicalNames
2
2 7 "base"
3 9 "tissue"
$EndPhysicalNames
$Nodes
5
10 0 0 -1
20 1 0 0
30 0 1 0
40 -1 -1 0
50 0 0 1
$EndNodes
$Elements
4
1 1 2 0 1 20 30
2 2 2 7 1 20 30 40
3 4 2 9 1 10 20 40 30
4 4 2 9 1 50 40 30 20
$EndElements
)";

// The same two tetrahedra in MSH 4.1: entities carry the physical tags; nodes and elements
// come in blocks (nodes in another order).
inline const char* kTwoTets41 = R"($MeshFormat
4.1 0 8
$EndMeshFormat
$PhysicalNames
2
2 7 "base"
3 9 "tissue"
$EndPhysicalNames
$Entities
0 0 1 1
1 -1 -1 0 1 1 0 1 7 0
1 -1 -1 -1 1 1 1 1 9 1 1
$EndEntities
$Nodes
2 5 10 50
2 1 0 3
20
30
40
1 0 0 0
0 1 0
-1 -1 0
3 1 0 2
10
50
0 0 -1
0 0 1
$EndNodes
$Elements
2 3 2 4
2 1 2 1
2 20 30 40
3 1 4 2
3 10 20 40 30
4 50 40 30 20
$EndElements
)";

/// Expects `read` to throw io::MeshFileError whose message holds every fragment.
template <class F>
void expect_mesh_error(F&& read, const std::string& text, std::initializer_list<std::string> fragments) {
  try {
    read();
    ADD_FAILURE() << "expected a MeshFileError for:\n" << text;
  } catch (const io::MeshFileError& e) {
    const std::string msg = e.what();
    for (const auto& f : fragments) EXPECT_NE(msg.find(f), std::string::npos) << "'" << msg << "' lacks '" << f << "'";
  }
}

// kTwoTets (mm; a bipyramid split at z = 0, the first tetrahedron given inverted) at
// order 2: its 9 edge nodes 101..109 at the midpoints, except 101 on edge 10-20, moved
// outwards to (0.55, 0, -0.55); the shared face as a 6-node triangle in physical group
// "base", and a 3-node line in group 0. Lines 30 and 31 are the tetrahedra.
inline const std::string kTwoQuadraticTets = replace_once(
    replace_once(replace_once(kTwoTets, "$Nodes\n5\n", "$Nodes\n14\n"), "50 0 0 1\n",
                 "50 0 0 1\n101 0.55 0 -0.55\n102 0 -0.5 0\n103 -0.5 -0.5 -0.5\n104 0 0.5 -0.5\n105 -0.5 0 0\n"
                 "106 0.5 0.5 0\n107 -0.5 -0.5 0.5\n108 0 0.5 0.5\n109 0.5 0 0.5\n"),
    "1 1 2 0 1 20 30\n2 2 2 7 1 20 30 40\n3 4 2 9 1 10 20 40 30\n4 4 2 9 1 50 40 30 20\n",
    "1 8 2 0 1 20 30 106\n2 9 2 7 1 20 30 40 106 105 102\n3 11 2 9 1 10 20 40 30 101 102 103 104 105 106\n"
    "4 11 2 9 1 50 40 30 20 107 105 108 109 106 102\n");

}  // namespace fiberfem::testing
