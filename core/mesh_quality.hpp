#pragma once
/// @file Shape quality of tetrahedra and tetrahedral meshes: dihedral angles, radius ratio.

#include "core/mesh.hpp"

#include <array>

namespace fiberfem::core {

/// Shape quality of a mesh's rest configuration, over all elements. Small dihedral angles
/// (slivers, needles) and large ones (caps) make the element stiffness ill-conditioned and
/// its gradients inaccurate; the radius ratio catches every kind of degeneracy in one number.
struct MeshQuality {
  /// Smallest interior dihedral angle, degrees, in (0, 180). Regular tetrahedron: 70.53.
  double min_dihedral_deg = 0.0;
  /// Largest interior dihedral angle, degrees, in (0, 180). Regular tetrahedron: 70.53.
  double max_dihedral_deg = 0.0;
  /// Smallest radius ratio 3 r / R (r inradius, R circumradius), in (0, 1]; 1 only for the
  /// regular tetrahedron.
  double min_radius_ratio = 0.0;
  /// Element with the smallest dihedral angle (the lowest id if several tie).
  int worst_element = -1;
};

/// The six interior dihedral angles of the tetrahedron (a, b, c, d), degrees, at the edges
/// ab, ac, ad, bc, bd, cd in that order: the angle between the two faces that meet at the
/// edge, measured inside the tetrahedron. Independent of orientation. A degenerate
/// tetrahedron (coplanar or coincident points) gives angles of 0 or 180.
std::array<double, 6> dihedral_angles_deg(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

/// Radius ratio 3 r / R of the tetrahedron (a, b, c, d), r the inradius and R the
/// circumradius: 1 for the regular tetrahedron, tending to 0 as it degenerates (exactly 0
/// when it has zero volume). Dimensionless; independent of orientation and scale.
double radius_ratio(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

/// Dihedral angles and radius ratio over every element of `mesh` (in rest positions).
MeshQuality mesh_quality(const TetMesh& mesh);

}  // namespace fiberfem::core
