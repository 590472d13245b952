#pragma once
/// @file gmsh files shared by the mesh reader tests (tests/io/mesh_io_test.cpp,
/// tests/io/mesh_io_order2_test.cpp) and a check of their refusals.

#include "io/mesh_io.hpp"

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

}  // namespace fiberfem::testing
