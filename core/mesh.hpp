#pragma once
/// @file Tetrahedral mesh: rest shape, connectivity, regions, node sets, boundary surface.

#include "core/types.hpp"

#include <map>
#include <string>
#include <vector>

namespace fiberfem::core {

/// A validated linear-tetrahedron mesh in its rest configuration.
///
/// Construction checks every element: node indices in range and distinct, volume not
/// degenerate (an element whose volume is below `degenerate_tolerance * h^3`, with h its
/// longest edge, is refused by id), and positive orientation (an element given with
/// negative volume is reoriented by swapping its last two nodes and reported in
/// `reoriented_elements()`). The mesh is immutable afterwards.
class TetMesh {
 public:
  /// Relative volume below which an element counts as degenerate: V < tol * (longest edge)^3.
  static constexpr double kDefaultDegenerateTolerance = 1e-12;

  /// @param rest_positions 3 x N rest positions, metres; all finite.
  /// @param tets element connectivity; indices in [0, N).
  /// @param regions region id per element (>= 0), or empty for all zero.
  /// @throws std::invalid_argument naming the offending element or node.
  TetMesh(Positions rest_positions, std::vector<Tet> tets, std::vector<int> regions = {},
          double degenerate_tolerance = kDefaultDegenerateTolerance);

  int num_nodes() const { return static_cast<int>(rest_.cols()); }
  int num_elements() const { return static_cast<int>(tets_.size()); }
  /// Number of distinct region ids (max id + 1).
  int num_regions() const { return num_regions_; }

  /// Rest positions, 3 x N, metres.
  const Positions& rest_positions() const { return rest_; }
  const std::vector<Tet>& tets() const { return tets_; }
  const std::vector<int>& regions() const { return regions_; }
  /// Replaces the region ids (one per element, >= 0); the shape, boundary and node sets stay.
  /// @throws std::invalid_argument naming the first bad id, or a count that does not match.
  void set_regions(std::vector<int> regions);
  /// Rest volume of element `e`, m^3 (positive).
  double rest_volume(int e) const { return volumes_[static_cast<size_t>(e)]; }
  const std::vector<double>& rest_volumes() const { return volumes_; }
  /// Ids of elements that were given with negative orientation and reoriented.
  const std::vector<int>& reoriented_elements() const { return reoriented_; }
  /// Boundary triangles (faces used by exactly one element), oriented outward.
  const std::vector<Tri>& boundary_triangles() const { return boundary_; }
  /// Element owning each boundary triangle (same order as `boundary_triangles()`).
  const std::vector<int>& boundary_triangle_elements() const { return boundary_elements_; }
  /// Nodes on the boundary surface, sorted.
  std::vector<int> boundary_nodes() const;

  /// Named node sets (e.g. "xmin" from the box generator, physical groups from files).
  const std::map<std::string, std::vector<int>>& node_sets() const { return node_sets_; }
  /// Adds or replaces a named node set. @throws std::invalid_argument if a node is out of range.
  void set_node_set(const std::string& name, std::vector<int> nodes);
  /// @throws std::out_of_range naming the set if it does not exist.
  const std::vector<int>& node_set(const std::string& name) const;

  /// Axis-aligned bounding box of the rest shape: (min, max).
  std::pair<Vec3, Vec3> bounding_box() const;
  /// Sum of element rest volumes, m^3.
  double total_volume() const;

 private:
  void build_boundary();

  Positions rest_;
  std::vector<Tet> tets_;
  std::vector<int> regions_;
  int num_regions_ = 1;
  std::vector<double> volumes_;
  std::vector<int> reoriented_;
  std::vector<Tri> boundary_;
  std::vector<int> boundary_elements_;
  std::map<std::string, std::vector<int>> node_sets_;
};

/// Signed volume of the tetrahedron (a, b, c, d): det[b-a, c-a, d-a] / 6.
double signed_volume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

/// A copy of `mesh` with nodes renumbered: new node `i` is old node `old_of_new[i]`.
/// Elements keep their order; node sets are renumbered too. Used by tests and by
/// bandwidth-reducing reorderings.
TetMesh renumber_nodes(const TetMesh& mesh, const std::vector<int>& old_of_new);

}  // namespace fiberfem::core
