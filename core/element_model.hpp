#pragma once
/// @file The seam between an element family and the integrator and solvers: what the
/// elements contribute to a step (forces, tangent blocks, stiffness damping, energy,
/// inverted elements, element and node rotations), behind one interface that the
/// integrator (Simulator::advance) calls once per element pass.
///
/// An implementation owns its per-element caches and material constants and does its own
/// loop over the elements (SparseSystem::assemble_batched or assemble): the dispatch is one
/// virtual call per pass, never per element. The corotated linear tetrahedron
/// (core/corotated_linear_model.hpp) is the engine's family; another (other element
/// orders, hyperelastic laws with Newton iterations) implements the same interface beside
/// it, without touching that fast path.

#include "core/material.hpp"
#include "core/rotation.hpp"
#include "core/simulator_state.hpp"
#include "core/sparse_system.hpp"
#include "core/types.hpp"

#include <Eigen/Core>

namespace fiberfem::core {

/// How the integrator asks for one element pass (set for every pass).
struct ElementPass {
  /// Step size, s, > 0: the tangent blocks are (h beta_e + h^2) K_T (PHYSICS.md section 5).
  double h_s = 0;
  /// false: element rotations are the identity (plain linear FEM). Default true.
  bool corotation = true;
  /// How element rotations are extracted when they are computed.
  RotationMethod rotation = RotationMethod::polar;
  /// Convergence of the warm-started polar rotation, rad.
  double polar_tolerance_rad = 1e-9;
  /// The active force acts along the rest fiber (ContractionMode::nodal_forces) instead of
  /// the rotated one.
  bool rest_frame_active = false;
  /// Also sum the active-stress forces alone into `f_active` (the energy check's work).
  bool track_active_work = false;
};

/// What an element family contributes to the step, as the integrator and the solvers see
/// it. The state it reads and updates is the element part of SimulatorState: positions x,
/// element rotations R with their warm starts q, rotations_current, inverted_current, the
/// active tension per element, and the node-block rotations block_R (block_q).
class ElementModel {
 public:
  virtual ~ElementModel() = default;

  /// One pass over every element at the positions st.x. Computes the element rotations
  /// (st.R, st.q) and counts inverted elements into st.inverted_current unless
  /// st.rotations_current, and sets st.rotations_current. Replaces the values of `sys`
  /// with the sum of the elements' tangent blocks (h beta_e + h^2) K_T (the mass terms are
  /// the integrator's), `f` (3N) with the elastic plus active-stress forces (tension
  /// st.active_tension_pa, when not empty), and, with pass.track_active_work, `f_active`
  /// (3N) with the active forces alone. Allocates nothing after its first call.
  /// @return the elastic energy of st.x, J.
  virtual double assemble(const ElementPass& pass, SimulatorState& st, SparseSystem& sys, Eigen::VectorXd& f,
                          Eigen::VectorXd& f_active) = 0;

  /// Elastic energy at positions x (3N, m), with exact rotations (no warm start), J.
  virtual double elastic_energy(const Eigen::VectorXd& x, bool corotation) const = 0;
  /// Elements with det F <= 0 at positions x (3N, m).
  virtual int count_inverted(const Eigen::VectorXd& x) const = 0;
  /// The element rotations st.R and their warm starts st.q from the shape at st.x, exact
  /// (after the state jumped); identity when not `corotation`.
  virtual void seed_rotations(SimulatorState& st, bool corotation) const = 0;
  /// The rotation of each free node block (st.block_R, warm start st.block_q) from the
  /// element rotations st.R around its node, for the warp preconditioner
  /// (LinearSolver::set_block_rotations); identity when not `corotation`.
  virtual void update_node_rotations(SimulatorState& st, bool corotation) const = 0;

  /// Parameter changes between steps (validated by the caller); each rebuilds only the
  /// constants it touches.
  virtual void set_region_material(int region, const Material& material) = 0;
  /// Stiffness-proportional damping beta of the elements of `region`, s.
  virtual void set_region_stiffness_damping(int region, double beta_s) = 0;
  /// Unit fiber of element e.
  virtual void set_fiber(int e, const Vec3& unit_fiber) = 0;
};

}  // namespace fiberfem::core
