#pragma once
/// @file The residual and consistent tangent of a Problem (ACCURATE.md sections 1-2): the
/// internal force of the laws at every quadrature point, the mixed pressure's coupling
/// when a region is incompressible, the follower-pressure load and its load stiffness,
/// body force and active tension, all at one load factor.
///
/// Elements are assembled colour by colour (no two elements of a colour share a node), so
/// every entry of R and K is summed in the same order on any number of threads: results do
/// not depend on the thread count, and a checkpointed run resumes bit for bit.
///
/// Unknowns ("equations") are the free displacement components, numbered node-major, then
/// the pressures of a mixed problem: one per corner node of an incompressible element at
/// order 2 (Taylor-Hood P2/P1), one per incompressible element at order 1 (P1/P0, which
/// locks; kept so the convergence tables can show it).

#include "core/hyperelastic/problem.hpp"
#include "core/thread_governor.hpp"

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <vector>

namespace fiberfem::core::hyperelastic {

using SparseMatrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

/// What one evaluation found.
struct Evaluation {
  double energy_j = 0;          ///< Stored strain energy (laws and penalty), J.
  int inverted_elements = 0;    ///< Elements with det F <= 0 at a quadrature point.
  bool finite = true;           ///< Every residual entry finite.
};

/// How much of each load acts in one evaluation: a static solve scales them all by one
/// load factor; a time step takes each at its time.
struct Loading {
  double body_factor = 1.0;                ///< Scales gravity.
  std::vector<double> pressure_factors;    ///< Per PressureLoad (empty: all 1).
  double pressure_factor = 1.0;            ///< Scales every pressure (times its own factor).
  /// Active tension per element, Pa, in place of the problem's (nullptr: the problem's
  /// times active_factor).
  const std::vector<double>* active_tension_pa = nullptr;
  double active_factor = 1.0;
  /// Forces on nodes (3 x nodes, N, at their full value, no factor scales them); nullptr:
  /// none. Fixed components take no force.
  const Positions* nodal_forces_n = nullptr;
  /// All loads at one load factor.
  static Loading at_factor(double lambda) { return {lambda, {}, lambda, nullptr, lambda}; }
};

class Assembler {
 public:
  /// Precomputes the quadrature data, the unknown numbering and the tangent's pattern.
  /// @throws std::invalid_argument for an invalid problem or an element whose rest
  /// Jacobian is not positive at a quadrature point (named by index).
  explicit Assembler(const Problem& problem);

  int num_nodes() const { return num_nodes_; }
  int num_pressures() const { return num_pressures_; }
  int num_free_displacements() const { return num_free_u_; }
  int num_equations() const { return num_free_u_ + num_pressures_; }

  /// Residual R = f_int - f_ext (size num_equations()) at positions x (3 x nodes, m) and
  /// pressures p (num_pressures(), Pa), load factor `lambda`; with `K`, also the
  /// consistent tangent dR/d(unknowns) (its pattern set on the first call, values after).
  Evaluation evaluate(const Positions& x, const Eigen::VectorXd& p, double lambda, Eigen::VectorXd& R,
                      SparseMatrix* K) const {
    return evaluate(x, p, Loading::at_factor(lambda), R, K);
  }
  /// The same with each load at its own factor (a time step).
  Evaluation evaluate(const Positions& x, const Eigen::VectorXd& p, const Loading& loading, Eigen::VectorXd& R,
                      SparseMatrix* K) const;

  /// Adds the inertia of a backward-Euler step to a residual and tangent just evaluated:
  /// R += M (c (x - x0) - v0 / h) and K += c M on the free displacement rows (lumped masses,
  /// HRZ at order 2), with c = 1/h^2 + alpha/h for mass-proportional damping alpha (1/s).
  void add_inertia(const Positions& x, const Positions& x0, const Positions& v0, double h_s, double alpha_1_s,
                   Eigen::VectorXd& R, SparseMatrix* K) const;
  /// Lumped mass of each node, kg.
  const Eigen::VectorXd& node_masses() const { return masses_; }

  /// The residual of pressure load `k` at 1 Pa on the faces at positions x (its part of
  /// R, in equation rows, N/Pa): dR / d(its pressure), for unknown pressures bordered onto
  /// Newton (newton_iterate_bordered).
  Eigen::VectorXd unit_pressure_residual(const Positions& x, int k) const;
  /// A per-node field's free components in equation rows (zero pressure rows).
  Eigen::VectorXd equation_rows(const Positions& field) const;

  /// x += alpha * (displacement part of delta) on free components; p += alpha * (pressure part).
  void add_increment(const Eigen::VectorXd& delta, double alpha, Positions& x, Eigen::VectorXd& p) const;
  /// Norm of the displacement rows (N) and of the pressure rows (m^3) of a residual.
  double displacement_norm(const Eigen::VectorXd& R) const { return R.head(num_free_u_).norm(); }
  double pressure_norm(const Eigen::VectorXd& R) const { return R.tail(num_pressures_).norm(); }
  /// The external load at load factor 1 on the rest shape (displacement rows), N: a scale
  /// for convergence tests.
  double reference_load_norm() const { return reference_load_; }
  /// Total rest volume, m^3.
  double volume_m3() const { return volume_; }
  /// Threads of the element loop: N, or 0 for the engine's choice from measured evaluation
  /// times (core/thread_governor.hpp: fewer where more do not pay, or beside a busy core).
  void set_threads(int threads) { threads_ = threads; }
  /// The threads the next element loop runs on (the set count, or the engine's choice now).
  int threads() const { return threads_ > 0 ? threads_ : governor_.threads(); }

 private:
  struct PointData {
    Eigen::Matrix<double, 10, 3> dNdX;  ///< Gradients of the shape functions at the point.
    double dV = 0;                      ///< Weight times rest Jacobian, m^3.
  };
  void build_pattern();
  void build_colours();
  int equation_of_dof(int dof) const { return free_eq_[static_cast<size_t>(dof)]; }
  void add_faces(const Positions& x, const Loading& loading, Eigen::VectorXd& R, SparseMatrix* K) const;

  const Problem& problem_;
  int order_ = 1;
  int nodes_per_element_ = 4;
  int points_ = 1;
  int num_nodes_ = 0;
  int num_free_u_ = 0;
  int num_pressures_ = 0;
  double reference_load_ = 0;
  double volume_ = 0;
  std::vector<int> free_eq_;                     ///< Per displacement dof: equation or -1.
  std::vector<std::array<int, 4>> pressure_eq_;  ///< Per element: equations of its pressure dofs (or -1).
  int pressures_per_element_ = 0;                ///< 0, 1 (P0) or 4 (P1 on corners).
  std::vector<Eigen::Vector4d> pressure_shape_;  ///< Per point: pressure shape values.
  std::vector<PointData> points_data_;           ///< elements x points.
  Eigen::VectorXd body_force_;                   ///< rho g N_a integrated, per free equation, at lambda 1.
  std::vector<int> slots_;                       ///< Per element, local (row, col) -> value index.
  mutable SparseMatrix pattern_;
  /// Patches (of patch_ consecutive elements) by colour: no two of one colour share a
  /// node (build_colours).
  std::vector<std::vector<int>> colours_;
  int patch_ = 1;
  int threads_ = 0;
  Eigen::VectorXd masses_;           ///< Per node, kg.
  std::vector<int> diagonal_slot_;   ///< Per free displacement equation: its diagonal's value index.
  mutable ThreadGovernor governor_;
  int local_size_ = 0;
};

}  // namespace fiberfem::core::hyperelastic
