#pragma once
/// @file Fiber fields on a mesh (PHYSICS.md section 7): the transmural coordinate by a
/// Laplace solve, the ventricular helix rule built on it, and sign-blind interpolation of
/// fiber directions given at some nodes (strokes, per-node files).

#include "core/mesh.hpp"

#include <vector>

namespace fiberfem::core {

/// Nodal solution of the Laplace equation on the mesh (linear tetrahedra) with value 0 on
/// `zero_nodes` and 1 on `one_nodes`: a coordinate that runs smoothly from one surface to
/// the other (the transmural coordinate between endocardium and epicardium).
/// @throws std::invalid_argument if either set is empty, a node is out of range, or the
/// sets share a node.
Eigen::VectorXd laplace_coordinate(const TetMesh& mesh, const std::vector<int>& zero_nodes,
                                   const std::vector<int>& one_nodes);

/// The ventricular helix rule. Per element, with t its transmural coordinate (0 inner,
/// 1 outer):
///   e_n = grad t / |grad t|                      transmural, inner to outer;
///   e_l = -(a - (a . e_n) e_n), normalised       longitudinal, towards the apex
///                                                (a = apex_to_base);
///   e_c = e_n x e_l                              circumferential;
///   alpha = endo_angle + (epi_angle - endo_angle) t;
///   fiber = cos(alpha) e_c + sin(alpha) e_l,     sheet = e_n.
/// With endo 90 and epi -90 degrees this is the field of Land et al. 2015 problem 3
/// (f = sin(a) e_u + cos(a) e_v with e_u towards the apex; REFERENCES.md); the default
/// +60 to -60 is the usual ventricular range. On the z axis (e_n parallel to a) e_l is any
/// unit vector normal to e_n.
struct HelixRule {
  double endo_angle_deg = 60.0;  ///< Helix angle at t = 0, degrees. Default +60.
  double epi_angle_deg = -60.0;  ///< Helix angle at t = 1, degrees. Default -60.
  Vec3 apex_to_base{0.0, 0.0, 1.0};  ///< Long axis, pointing from apex to base. Default +z.
  /// @throws std::invalid_argument naming the field (angles finite, axis non-zero finite).
  void validate() const;
};

/// Per-element fiber and sheet directions with the transmural coordinate they came from.
struct FiberField {
  std::vector<Vec3> fiber;          ///< Unit fiber direction per element.
  std::vector<Vec3> sheet;          ///< Unit sheet (transmural) direction per element.
  std::vector<double> transmural;   ///< Element transmural coordinate (mean of its nodes).
};

/// The helix rule on nodal transmural coordinates `t` (size num_nodes, e.g. from
/// laplace_coordinate). @throws std::invalid_argument for a bad rule or size.
FiberField helix_rule_fibers(const TetMesh& mesh, const Eigen::VectorXd& t, const HelixRule& rule);

/// Sign-blind interpolation of directions given at some nodes: the structure tensor
/// d d^T (the same for d and -d) of every given node is held, the six components are
/// interpolated harmonically (Laplace) over the other nodes, and each element takes the
/// principal eigenvector of the mean of its nodes' tensors. A field that is uniform stays
/// uniform; opposite signs at different nodes do not cancel.
/// @param nodes nodes with a direction (distinct, in range, at least one)
/// @param directions their directions (non-zero, finite; normalised here)
/// @throws std::invalid_argument naming the offending entry.
std::vector<Vec3> interpolate_directions(const TetMesh& mesh, const std::vector<int>& nodes,
                                         const std::vector<Vec3>& directions);

/// Angle between two fiber directions, sign-blind (f and -f are the same fiber), degrees
/// in [0, 90].
double fiber_angle_deg(const Vec3& a, const Vec3& b);

}  // namespace fiberfem::core
