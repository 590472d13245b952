#pragma once
/// @file The elements of the accurate tier: a TetMesh's corner nodes and, for order 2, one
/// node per edge (the 10-node tetrahedron). Corner nodes keep the TetMesh's numbering and
/// come first, so the first num_corner_nodes() columns of any state are the linear mesh
/// that archives, the renderer and probes already understand.

#include "core/mesh.hpp"
#include "core/types.hpp"

#include <array>
#include <functional>
#include <vector>

namespace fiberfem::core::hyperelastic {

/// Where the mid-edge node between corners a and b goes, given their midpoint (rest
/// positions, m). Used to put nodes of boundary edges on a generator's curved surface.
using EdgePlacement = std::function<Vec3(int a, int b, const Vec3& midpoint)>;

class ElementMesh {
 public:
  /// Order 1: the TetMesh itself; order 2: a node per edge at `place`'s position (the
  /// midpoint when `place` is empty). Edge nodes are numbered from num_corner_nodes() on
  /// in the lexicographic order of their corner pairs (lower corner index first), which
  /// does not depend on the element order; `place` is called with a < b.
  /// @throws std::invalid_argument when order is not 1 or 2, when `place` gives a
  /// non-finite position, or naming an element that the placed nodes curve so much that
  /// det J is not positive at one of its nodes or quadrature points (14-point rule).
  ElementMesh(const TetMesh& corners, int order, const EdgePlacement& place = {});
  /// From a file's 10-node elements (corner indices into `corners`, edge nodes numbered
  /// from corners.num_nodes() on, in gmsh order) and the edge nodes' positions (column i
  /// is node corners.num_nodes() + i). Element e must have the corners of corners.tets()[e]
  /// in any order (TetMesh reorients inverted elements; the edge nodes follow).
  /// @throws std::invalid_argument naming an element whose edge node is shared
  /// inconsistently or out of range, an edge node no element uses, an element whose
  /// corners differ from the TetMesh's, or one with det J <= 0 (as above).
  ElementMesh(const TetMesh& corners, const std::vector<std::array<int, 10>>& elements, const Positions& edge_positions);

  int order() const { return order_; }
  int nodes_per_element() const { return order_ == 1 ? 4 : 10; }
  int num_corner_nodes() const { return num_corners_; }
  int num_nodes() const { return static_cast<int>(rest_.cols()); }
  int num_elements() const { return static_cast<int>(elements_.size()); }
  /// Rest positions of all nodes (corners first), 3 x num_nodes(), m.
  const Positions& rest_positions() const { return rest_; }
  /// Element node indices (gmsh order; order 1 uses the first 4).
  const std::vector<std::array<int, 10>>& elements() const { return elements_; }
  /// Boundary faces in the order of TetMesh::boundary_triangles() (outward), with their
  /// mid-edge nodes (gmsh triangle order; order 1 uses the first 3).
  const std::vector<std::array<int, 6>>& boundary_faces() const { return faces_; }
  /// The two corner nodes of each edge node (index node - num_corner_nodes()).
  const std::vector<std::array<int, 2>>& edge_ends() const { return edge_ends_; }
  /// Per node, per component: fixed when the node is a corner fixed in `corner_fixed_dofs`
  /// (3 x corners) or an edge node both of whose corners are fixed in that component.
  /// Layout 3 i + c, as Model::fixed_dofs. An empty input fixes nothing (3 x num_nodes()
  /// zeros are returned). @throws std::invalid_argument when the size is neither 0 nor
  /// 3 num_corner_nodes().
  std::vector<std::uint8_t> fixed_dofs(const std::vector<std::uint8_t>& corner_fixed_dofs) const;
  /// Rest positions of element e's nodes, one column per node, m; columns beyond
  /// nodes_per_element() are zero, so X * TetShape::dN is the Jacobian at either order.
  Eigen::Matrix<double, 3, 10> element_positions(int e) const;

 private:
  void build_faces(const TetMesh& corners);
  void check_jacobians() const;

  int order_ = 1;
  int num_corners_ = 0;
  Positions rest_;
  std::vector<std::array<int, 10>> elements_;
  std::vector<std::array<int, 6>> faces_;
  std::vector<std::array<int, 2>> edge_ends_;
};

/// Rest volume of each element, m^3: the integral of det J (a cubic polynomial for the
/// 10-node element, so the 14-point rule is exact even for curved elements).
std::vector<double> element_volumes(const ElementMesh& mesh);

/// Lumped node masses of density `rho_kg_m3` per element, kg: rho V / 4 per corner at
/// order 1; HRZ (diagonal-scaling) lumping at order 2, every mass positive: the diagonal
/// of the element's consistent mass (14-point rule, exact for straight-sided elements:
/// corner 1/36, edge node 4/27 of the element's mass) scaled so that the element's total
/// is rho V exactly.
/// @throws std::invalid_argument when the size is not num_elements() or a density is
/// not positive and finite (naming the element).
Eigen::VectorXd lumped_masses(const ElementMesh& mesh, const std::vector<double>& rho_kg_m3);

}  // namespace fiberfem::core::hyperelastic
