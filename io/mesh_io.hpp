#pragma once
/// @file Mesh files (docs/mesh-formats.md): gmsh MSH 2.2 and 4.1 ASCII, TetGen .node/.ele
/// and legacy VTK read; MSH 2.2 written.
/// Linear tetrahedra become elements (their physical tag the region tag); named physical
/// groups of points, lines and triangles become node sets.

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
/// `origin` names it in errors.
core::TetMesh read_gmsh(std::istream& in, const std::string& origin, double scale = 1.0);

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
