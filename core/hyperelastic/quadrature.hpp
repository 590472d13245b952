#pragma once
/// @file Quadrature rules on the reference tetrahedron (vertices 0, e_x, e_y, e_z; volume
/// 1/6) and the reference triangle (vertices 0, e_x, e_y; area 1/2), for the elements of
/// the accurate tier (ACCURATE.md section 3).

#include <Eigen/Core>

#include <vector>

namespace fiberfem::core::hyperelastic {

/// Points in reference coordinates and weights summing to the reference measure.
struct TetRule {
  std::vector<Eigen::Vector3d> points;
  std::vector<double> weights;  ///< Sum 1/6.
  int degree = 0;               ///< Polynomials up to this degree are integrated exactly.
};
struct TriangleRule {
  std::vector<Eigen::Vector2d> points;
  std::vector<double> weights;  ///< Sum 1/2.
  int degree = 0;
};

/// The tetrahedron rule with `num_points` points: 1 (degree 1), 4 (degree 2), 11 (Keast,
/// degree 4), 14 (degree 5), or the conical-product Gauss rule used as an over-integrated
/// reference (kReferenceTetPoints points, degree >= 9).
/// @throws std::invalid_argument naming the count when there is no such rule.
const TetRule& tetrahedron_rule(int num_points);
/// Points of the over-integrated reference rule.
inline constexpr int kReferenceTetPoints = 125;

/// The triangle rule with `num_points` points: 1 (degree 1), 3 (degree 2), 6 (degree 4),
/// 7 (degree 5). @throws std::invalid_argument naming the count.
const TriangleRule& triangle_rule(int num_points);

}  // namespace fiberfem::core::hyperelastic
