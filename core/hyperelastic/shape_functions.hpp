#pragma once
/// @file Lagrange shape functions of the linear (4-node) and quadratic (10-node)
/// tetrahedron and of the linear (3-node) and quadratic (6-node) triangle, in gmsh's node
/// order: corners, then mid-edge nodes on edges 0-1, 1-2, 2-0, 0-3, 2-3, 1-3 (tetrahedron,
/// gmsh type 11) and 0-1, 1-2, 2-0 (triangle, gmsh type 9).

#include <Eigen/Core>

#include <array>

namespace fiberfem::core::hyperelastic {

/// Values (rows beyond the element's node count are zero) and reference gradients.
struct TetShape {
  Eigen::Matrix<double, 10, 1> N = Eigen::Matrix<double, 10, 1>::Zero();
  Eigen::Matrix<double, 10, 3> dN = Eigen::Matrix<double, 10, 3>::Zero();  ///< dN_a / dxi_j.
};
struct TriangleShape {
  Eigen::Matrix<double, 6, 1> N = Eigen::Matrix<double, 6, 1>::Zero();
  Eigen::Matrix<double, 6, 2> dN = Eigen::Matrix<double, 6, 2>::Zero();
};

/// Nodes of a tetrahedron of `order` 1 or 2 (4 or 10); of a triangle (3 or 6).
constexpr int tet_nodes(int order) { return order == 1 ? 4 : 10; }
constexpr int triangle_nodes(int order) { return order == 1 ? 3 : 6; }

/// The corner pair of each mid-edge node of the 10-node tetrahedron (node 4 + i sits on
/// kTetEdges[i]) and of the 6-node triangle.
inline constexpr std::array<std::array<int, 2>, 6> kTetEdges{{{0, 1}, {1, 2}, {2, 0}, {0, 3}, {2, 3}, {1, 3}}};
inline constexpr std::array<std::array<int, 2>, 3> kTriangleEdges{{{0, 1}, {1, 2}, {2, 0}}};

/// Shape functions at reference point xi (order 1 or 2; precondition).
TetShape tet_shape(int order, const Eigen::Vector3d& xi);
TriangleShape triangle_shape(int order, const Eigen::Vector2d& xi);

}  // namespace fiberfem::core::hyperelastic
