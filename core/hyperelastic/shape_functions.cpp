#include "core/hyperelastic/shape_functions.hpp"

namespace fiberfem::core::hyperelastic {

// Both elements in barycentric coordinates L: L0 = 1 - sum xi, L_k = xi_k. Order 1:
// N_a = L_a. Order 2: corner a, N_a = L_a (2 L_a - 1); the
// node on edge (a, b), N = 4 L_a L_b. The gradients follow from dL0/dxi = -1,
// dL_k/dxi_j = delta_kj. The edge order is gmsh's (MTetrahedron10 and MTriangle6:
// kTetEdges, kTriangleEdges); VTK_QUADRATIC_TETRA (cell type 24) lists the last two
// edges the other way round (0-1, 1-2, 2-0, 0-3, 1-3, 2-3), so a reader or writer of VTK
// swaps nodes 8 and 9.
namespace {

template <int Dim, int Nodes, std::size_t Edges>
void lagrange(int order, const Eigen::Matrix<double, Dim, 1>& xi, const std::array<std::array<int, 2>, Edges>& edges,
              Eigen::Matrix<double, Nodes, 1>& N, Eigen::Matrix<double, Nodes, Dim>& dN) {
  constexpr int kCorners = Dim + 1;
  Eigen::Matrix<double, kCorners, 1> L;
  Eigen::Matrix<double, kCorners, Dim> dL = Eigen::Matrix<double, kCorners, Dim>::Zero();
  L(0) = 1 - xi.sum();
  L.template tail<Dim>() = xi;
  dL.row(0).setConstant(-1);
  dL.template bottomRows<Dim>().setIdentity();
  N.setZero();
  dN.setZero();
  if (order == 1) {
    N.template head<kCorners>() = L;
    dN.template topRows<kCorners>() = dL;
    return;
  }
  for (int a = 0; a < kCorners; ++a) {
    N(a) = L(a) * (2 * L(a) - 1);
    dN.row(a) = (4 * L(a) - 1) * dL.row(a);
  }
  for (std::size_t e = 0; e < Edges; ++e) {
    const int a = edges[e][0], b = edges[e][1], node = kCorners + static_cast<int>(e);
    N(node) = 4 * L(a) * L(b);
    dN.row(node) = 4 * (L(b) * dL.row(a) + L(a) * dL.row(b));
  }
}

}  // namespace

TetShape tet_shape(int order, const Eigen::Vector3d& xi) {
  TetShape s;
  lagrange<3, 10>(order, xi, kTetEdges, s.N, s.dN);
  return s;
}

TriangleShape triangle_shape(int order, const Eigen::Vector2d& xi) {
  TriangleShape s;
  lagrange<2, 6>(order, xi, kTriangleEdges, s.N, s.dN);
  return s;
}

}  // namespace fiberfem::core::hyperelastic
