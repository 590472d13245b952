#pragma once
/// @file The drawable surface of a tetrahedral mesh: its boundary triangles, extracted once,
/// with per-frame normals from the deformed positions (smooth across edges, sharp across
/// creases of the rest shape).

#include "core/mesh.hpp"

#include <Eigen/Core>

#include <vector>

namespace fiberfem::render {

class Surface {
 public:
  /// Crease angle: faces meeting at more than this (in the rest shape) get separate
  /// normals at their shared nodes (box edges stay sharp), degrees.
  static constexpr double kCreaseDeg = 40.0;

  /// Extracts the boundary of `mesh` (TetMesh::boundary_triangles()) and the rest-shape
  /// inverse Dm^-1 of each element under it.
  explicit Surface(const core::TetMesh& mesh);

  /// Number of surface triangles.
  int num_triangles() const { return static_cast<int>(tris_.size()); }
  /// Triangles (mesh node ids, counter-clockwise seen from outside).
  const std::vector<core::Tri>& triangles() const { return tris_; }
  /// Element owning each triangle.
  const std::vector<int>& triangle_elements() const { return elements_; }
  /// The distinct elements under the surface (sorted), and the index into it of each
  /// triangle's element.
  const std::vector<int>& surface_elements() const { return surface_elements_; }
  const std::vector<int>& triangle_surface_element() const { return tri_surface_element_; }
  /// Dm^-1 of each surface element (same order as surface_elements()), 1/m.
  const std::vector<core::Mat3>& surface_dm_inv() const { return dm_inv_; }
  /// Mean rest edge length of the surface triangles, m.
  double mean_edge_m() const { return mean_edge_m_; }

  /// Vertex normals for positions `x` (3 x N), three per triangle (corner order), unit,
  /// as 3 x (3 T) floats: each corner averages the area-weighted normals of the faces
  /// around its node that meet its own face within the crease angle at rest.
  void corner_normals(const Eigen::Ref<const core::Positions>& x, Eigen::Matrix3Xf& out) const;

 private:
  std::vector<core::Tri> tris_;
  std::vector<int> elements_, surface_elements_, tri_surface_element_;
  std::vector<core::Mat3> dm_inv_;
  // For corner c = 3 t + k: the faces smoothed into it are group_faces_[group_start_[c] ..
  // group_start_[c + 1]).
  std::vector<int> group_start_, group_faces_;
  double mean_edge_m_ = 0;
  mutable std::vector<core::Vec3> face_normals_;
};

/// Rest positions of the boundary nodes of `mesh` (3 x M), metres: what a camera frames.
core::Positions surface_points(const core::TetMesh& mesh);

}  // namespace fiberfem::render
