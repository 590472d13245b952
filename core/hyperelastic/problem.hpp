#pragma once
/// @file A boundary-value problem of the accurate tier: hyperelastic laws per region on
/// linear or quadratic tetrahedra, with fixed components, body force, pressure loads
/// (follower or dead) and an active fiber tension, all scaled by one load factor.

#include "core/hyperelastic/element_mesh.hpp"
#include "core/hyperelastic/law.hpp"

#include <memory>
#include <vector>

namespace fiberfem::core::hyperelastic {

/// A pressure on boundary faces, along the inward normal of each face, Pa.
struct PressureLoad {
  std::vector<int> faces;     ///< Indices into ElementMesh::boundary_faces().
  double pressure_pa = 0.0;   ///< At load factor 1, Pa.
  /// true: on the deformed faces (current normal and area, with its load stiffness);
  /// false: dead (the rest faces). Default true.
  bool follower = true;
};

/// Everything the accurate-tier solvers need. validate() checks sizes and ranges.
struct Problem {
  explicit Problem(std::shared_ptr<const ElementMesh> m) : mesh(std::move(m)) {}

  std::shared_ptr<const ElementMesh> mesh;
  /// One law per region id; `element_region` (size elements) picks it.
  std::vector<LawParameters> region_laws;
  std::vector<int> element_region;
  /// Density per region, kg/m^3 (body force and mass); empty: 0.
  std::vector<double> region_density_kg_m3;
  /// Material axes per element (size elements) or per quadrature point (elements x
  /// points, element-major); empty: fiber along x everywhere.
  std::vector<MaterialAxes> axes;
  /// Active fiber tension T_a per element at load factor 1, Pa (S_a = T_a f0 (x) f0);
  /// empty: none.
  std::vector<double> active_tension_pa;
  /// Gravity, m/s^2 (body force rho g at load factor 1).
  Vec3 gravity_m_s2 = Vec3::Zero();
  std::vector<PressureLoad> pressures;
  /// Fixed flag per displacement component (3 x nodes); fixed components stay at rest.
  std::vector<std::uint8_t> fixed_dofs;
  /// Quadrature points per element: 1, 4, 11 or 14; 0 picks the default for the order
  /// (kDefaultPoints). Default 0.
  int quadrature_points = 0;

  /// Default rule per order (order 1: 1 point, exact for its constant strain; order 2: 4).
  static int default_points(int order) { return order == 1 ? 1 : 4; }
  int points() const { return quadrature_points > 0 ? quadrature_points : default_points(mesh->order()); }
  /// Whether any region is incompressible (a mixed displacement-pressure problem).
  bool mixed() const;
  /// @throws std::invalid_argument naming the field.
  void validate() const;
};

}  // namespace fiberfem::core::hyperelastic
