#pragma once
/// @file Mesh files (docs/mesh-formats.md): gmsh MSH 2.2 and 4.1 ASCII, TetGen .node/.ele
/// and legacy VTK read; MSH 2.2 written.
/// Linear tetrahedra become elements (their physical tag the region tag); named physical
/// groups of points, lines and triangles become node sets. gmsh files of 10-node
/// tetrahedra are read at order 2 (read_gmsh_any_order).

#include "core/hyperelastic/element_mesh.hpp"
#include "core/mesh.hpp"

#include <iosfwd>
#include <stdexcept>
#include <string>

namespace fiberfem::io {

/// A malformed mesh file: the message starts with "<file>:<line>: ".
class MeshFileError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// Reads a mesh file, choosing the format by extension (.msh; .node or .ele for TetGen,
/// which reads both files of that base name; .vtk). Positions are multiplied
/// by `scale` (file units to metres, > 0). @throws MeshFileError naming file and line,
/// or what TetMesh refuses (degenerate element, ...) with the file name.
core::TetMesh read_mesh(const std::string& path, double scale = 1.0);

/// Reads gmsh MSH 2.2 or 4.1 ASCII from a stream (the version from $MeshFormat);
/// `origin` names it in errors. Linear tetrahedra only: a file of 10-node tetrahedra
/// (type 11) is refused with a message pointing to read_gmsh_any_order (mesh.order: 2).
core::TetMesh read_gmsh(std::istream& in, const std::string& origin, double scale = 1.0);

/// A mesh file's elements at the file's order: the corner mesh (regions, node sets on
/// corner nodes) and its ElementMesh (order 1: the corner mesh itself; order 2: the
/// file's 10-node tetrahedra, their mid-edge nodes numbered after the corners).
struct OrderedMesh {
  core::TetMesh corners;
  core::hyperelastic::ElementMesh elements;
};

/// Reads gmsh MSH 2.2 or 4.1 ASCII of linear (type 4) or 10-node (type 11) tetrahedra,
/// not both. At order 2 the nodes in positions 5 to 10 of a type-11 element are its edge
/// nodes (gmsh order: edges 0-1, 1-2, 2-0, 3-0, 3-2, 3-1) and all other nodes corners;
/// node sets from physical groups (points, 2- or 3-node lines, 3- or 6-node triangles)
/// keep their corner nodes. @throws MeshFileError naming the file (and line, or the node
/// or element that ElementMesh refuses: edge nodes shared inconsistently, det J <= 0).
OrderedMesh read_gmsh_any_order(std::istream& in, const std::string& origin, double scale = 1.0);

/// read_gmsh_any_order for a .msh path; other formats are read by read_mesh (order 1).
OrderedMesh read_mesh_any_order(const std::string& path, double scale = 1.0);

/// Reads a TetGen mesh: the .node file (points, optional attributes and boundary markers)
/// and the .ele file (linear tetrahedra; the first attribute, if any, is the region tag).
/// Comments ('#') and any index base are allowed.
core::TetMesh read_tetgen(std::istream& node, const std::string& node_origin, std::istream& ele,
                          const std::string& ele_origin, double scale = 1.0);

/// Reads a legacy VTK unstructured grid (ASCII): tetrahedra (cell type 10) become
/// elements, the first integer CELL_DATA SCALARS array their region tags.
core::TetMesh read_vtk(std::istream& in, const std::string& origin, double scale = 1.0);

/// Writes gmsh MSH 2.2 ASCII: nodes, tetrahedra with their region id as physical tag (as
/// read back), and each node set as a named physical group of points (tags after the
/// largest region id).
void write_gmsh22(const core::TetMesh& mesh, std::ostream& out);

}  // namespace fiberfem::io
