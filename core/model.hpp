#pragma once
/// @file The scene model handed to the engine: mesh, materials per region, fibers per
/// element, constraints and loads. Scene files are parsed outside core/ into this.

#include "core/material.hpp"
#include "core/circulation/coupling.hpp"
#include "core/contraction.hpp"
#include "core/mesh.hpp"

#include <optional>
#include <string>
#include <vector>

namespace fiberfem::core {

/// Rayleigh damping D = alpha M + beta K_t, per region.
struct RayleighDamping {
  double mass_1_s = 0.0;     ///< alpha, 1/s, >= 0. Default 0 (no mass damping).
  double stiffness_s = 0.0;  ///< beta, s, >= 0. Default 0 (no stiffness damping).
  /// @throws std::invalid_argument naming the field.
  void validate() const;
  bool is_zero() const { return mass_1_s == 0.0 && stiffness_s == 0.0; }
};

/// A constant nodal force (dead load), newtons.
struct PointForce {
  int node = 0;              ///< Node index, in [0, N).
  Vec3 force_n = Vec3::Zero();
};

/// A dead surface load on boundary triangles (rest geometry): a pressure along the inward
/// rest normal plus a force per area, both in Pa. Distributed to the three nodes equally
/// (exact for a uniform traction on linear triangles).
struct SurfaceLoad {
  std::vector<Tri> faces;            ///< Triangles, outward counter-clockwise (as boundary_triangles()).
  double pressure_pa = 0.0;          ///< Along the inward normal, Pa.
  Vec3 force_per_area_pa = Vec3::Zero();  ///< Traction vector, Pa.
  /// The pressure follows the deformed faces (their current inward normal and area),
  /// updated every step of a dynamic run (explicitly, from the state the step starts
  /// from). The static solver refuses it. Default false (dead: the rest faces).
  bool follower = false;
  /// The load grows linearly from zero to full over this time, s (>= 0; 0: full at once).
  /// For quasi-static loading in dynamic runs; the static solver takes the full load.
  double ramp_s = 0.0;
  /// Whether the load changes during a run (follower or ramped).
  bool varies() const { return follower || ramp_s > 0; }
};

/// External loads; all dead loads in the rest configuration.
struct Loads {
  Vec3 gravity_m_s2 = Vec3::Zero();  ///< Body acceleration, m/s^2. Default none.
  std::vector<PointForce> point_forces;
  std::vector<SurfaceLoad> surface_loads;
};

/// Everything the engine needs to know about a scene.
struct Model {
  explicit Model(TetMesh m) : mesh(std::move(m)) {}

  TetMesh mesh;
  /// One material per region id (size mesh.num_regions()).
  std::vector<Material> region_materials;
  /// One damping per region id, or empty for none.
  std::vector<RayleighDamping> region_damping;
  /// Fiber direction per element (unit after validate()); empty means (1, 0, 0) everywhere.
  std::vector<Vec3> fibers;
  /// Fixed (Dirichlet, zero displacement) flag per degree of freedom (3N), or empty for none.
  std::vector<std::uint8_t> fixed_dofs;
  Loads loads;
  /// Fiber-directed contraction; off unless a region has a peak tension (no per-step cost).
  Contraction contraction;
  /// Cavity pressures from a lumped closed-loop circulation (core/circulation/); off
  /// unless it names a cavity (no per-step cost then).
  circulation::Coupling circulation;

  /// Fixes the given components (mask bit 0 = x, 1 = y, 2 = z) of each node.
  void fix_nodes(const std::vector<int>& nodes, unsigned component_mask = 0b111);
  /// Sets one fiber direction for every element.
  void set_uniform_fiber(const Vec3& f);
  /// Checks sizes, ranges and finiteness; normalises fibers.
  /// @throws std::invalid_argument naming the offending field and index.
  void validate();
  /// Mass of each node from lumped element masses (rho V / 4 each), kg.
  Eigen::VectorXd lumped_node_masses() const;
  /// External force on every DOF (3N) from the loads at load factor 1, newtons.
  Eigen::VectorXd external_forces() const;
  /// The part of external_forces() that does not change during a run (without the
  /// follower and ramped surface loads).
  Eigen::VectorXd constant_external_forces() const;
};

/// Consistent nodal forces of a surface load, accumulated into `f` (3N), at full load on
/// the rest faces.
void add_surface_load(const Positions& rest, const SurfaceLoad& load, Eigen::VectorXd& f);

/// The same at time `t_s` of a run with positions `x`: scaled by the ramp, and with the
/// pressure on the current faces when the load is a follower.
void add_surface_load_at(const Positions& rest, const Eigen::Ref<const Positions>& x, const SurfaceLoad& load, double t_s,
                         Eigen::VectorXd& f);

}  // namespace fiberfem::core
