#pragma once
/// @file Time steps of the accurate tier: backward Euler with the nonlinear internal force,
/// solved by Newton at every step (ACCURATE.md section 4):
///   M (v1 - v0)/h + alpha M v1 + f_int(x1, p1) = f_ext(t1),   v1 = (x1 - x0)/h,
/// with the consistent tangent K(x1) + (1/h^2 + alpha/h) M, lumped masses (HRZ at order 2)
/// and mass-proportional damping alpha. The incompressibility constraint, when a region
/// has one, holds at every step.

#include "core/circulation/circulation.hpp"
#include "core/hyperelastic/newton.hpp"

#include <string>
#include <vector>

namespace fiberfem::core::hyperelastic {

struct DynamicSettings {
  double dt_s = 1.0 / 60.0;     ///< solver.dt: step, s, > 0.
  double mass_damping_1_s = 0;  ///< Rayleigh alpha, 1/s, >= 0 (one value for the body).
  NewtonSettings newton;        ///< tolerance, max_iterations, line_search, threads per step.
  /// A step's Newton gives up when its merit is not below its start after this many
  /// iterations (NewtonSettings::give_up_after; 0: never): the service's engine then takes
  /// the step in substeps, which is cheaper than the rest of a solve that seldom converges.
  static constexpr int kGiveUpAfter = 4;
  int give_up_after = kGiveUpAfter;
  /// @throws std::invalid_argument naming the key.
  void validate() const;
};

struct DynamicStepReport {
  bool converged = false;
  int iterations = 0;
  std::string message;  ///< Why a step failed ("" when it converged).
};

/// Everything later steps depend on besides the problem and the settings: restoring it
/// into a solver of the same problem continues the run bit for bit.
struct DynamicState {
  Positions x;              ///< Positions, 3 x nodes, m.
  Positions v;              ///< Velocities, 3 x nodes, m/s.
  Eigen::VectorXd p;        ///< Mixed pressures (Assembler::num_pressures()), Pa.
  double time_s = 0;        ///< Simulation time, s.
  long steps = 0;           ///< Steps taken.
  TangentSolver::State linear;  ///< The lagged factor's matrices.
  /// A run coupled to a circulation (circulation_coupling.hpp; DynamicSolver neither writes
  /// nor reads these): the loop's state and each coupled cavity's volume, m^3. Empty cavity
  /// volumes: no circulation.
  circulation::State circulation;
  std::vector<double> cavity_volume_m3;
  /// The time the contraction counts its beats from, s (moved by a rate change so that the
  /// beat keeps its phase; kept by the service's engine, DynamicSolver neither writes nor
  /// reads it).
  double contraction_origin_s = 0;
};

class DynamicSolver {
 public:
  /// Starts at rest (rest positions, zero velocity and pressure). Every region needs a
  /// density > 0. @throws std::invalid_argument for an invalid problem or settings.
  DynamicSolver(const Problem& problem, const DynamicSettings& settings);

  /// One step to time t + dt with the loads at `loading` (their values at the step's end).
  /// A step that does not converge leaves the state unchanged and says why.
  DynamicStepReport step(const Loading& loading);
  /// The same step without changing the state, from the guess `x` (3 x nodes) and `p`: on
  /// convergence they hold the step's end. The guess is replaced by the step's start where
  /// it is not finite, inverts an element, or has the larger residual of the two.
  DynamicStepReport solve_step(const Loading& loading, Positions& x, Eigen::VectorXd& p);
  /// solve_step with unknown load magnitudes bordered onto Newton (newton_iterate_bordered):
  /// P_k is the factor of pressure load loads[k] (set in `loading`); `border`'s constraints
  /// and tolerance are the caller's, its residual and unit residuals this step's. On
  /// convergence (x, p, P) hold the step's end.
  DynamicStepReport solve_step_bordered(Loading loading, const std::vector<int>& loads, Border border, Positions& x,
                                        Eigen::VectorXd& p, Eigen::VectorXd& P);
  /// Makes a converged solve_step's end the state, one step later.
  void accept_step(const Positions& x, const Eigen::VectorXd& p);
  /// The predictor of the next step: the last velocity carried over it.
  Positions predicted_positions() const { return x_ + dt_s() * v_; }
  /// The size of the steps being taken: settings().dt_s, or a substep of it.
  double dt_s() const { return settings_.dt_s / substeps_; }
  /// Takes the following steps as `n` substeps of dt/n (n >= 1; 1: whole steps): each
  /// accept_step advances the time by dt/n, the step count once every n (a step that failed
  /// whole is retried in substeps; set it back to 1 after them).
  /// @throws std::invalid_argument for n < 1 or in the middle of a step's substeps.
  void set_substeps(int n);

  double time_s() const { return t_s_; }
  long steps() const { return steps_; }
  const Positions& positions() const { return x_; }
  const Positions& velocities() const { return v_; }
  const Eigen::VectorXd& pressures() const { return p_; }
  /// Stored strain energy of the state (the laws' and the volumetric penalty's, not the
  /// active tension's), J: from the converged evaluation of the step that made the state
  /// (no extra cost), evaluated anew after a restore.
  double elastic_energy_j() const { return energy_j_; }
  /// The state between steps (copies, including the lagged factor's matrices).
  DynamicState state() const;
  /// Continues from a state() of a solver of the same problem (or of one that differs in
  /// its laws' constants, loads or settings only).
  /// @throws std::invalid_argument on a size mismatch or a non-finite value (the solver is
  /// unchanged then).
  void restore(const DynamicState& state);
  /// Continues from `previous` (a solver of the same mesh and unknowns whose problem's
  /// constants, loads or settings differ): its state, and its lagged factor taken over
  /// without factorising again. @throws std::invalid_argument as restore (nothing moves then).
  void continue_from(DynamicSolver& previous);
  const DynamicSettings& settings() const { return settings_; }
  /// The residual's assembler (its equation numbering and load vectors).
  const Assembler& assembler() const { return assembler_; }
  /// Lumped node masses, kg.
  const Eigen::VectorXd& node_masses() const { return assembler_.node_masses(); }

  /// Totals over the steps so far (iterations, factorisations, times).
  NewtonReport totals() const;

 private:
  // Whether Newton should start from the step's start x_ rather than the guess `x` whose
  // evaluation (ev, R) is given: the guess is not finite, inverts an element, or has the
  // larger residual merit.
  bool start_is_better(const ResidualFn& residual, const Positions& x, const Eigen::VectorXd& p, const Evaluation& ev,
                       const Eigen::VectorXd& R) const;
  // A solve's counters into the totals, and its report (why it failed, if it did).
  DynamicStepReport finish_solve(const NewtonReport& counters, bool converged, bool singular);

  const Problem& problem_;
  DynamicSettings settings_;
  Assembler assembler_;
  TangentSolver linear_;
  SparseMatrix K_;
  Positions x_, v_;
  Eigen::VectorXd p_;
  double t_s_ = 0;
  long steps_ = 0;
  int substeps_ = 1, substep_ = 0;  // substeps per step, and those taken of this step
  double energy_j_ = 0;         // elastic_energy_j() of the state
  double solved_energy_j_ = 0;  // of the last converged solve, taken by accept_step
  NewtonReport totals_;
};

}  // namespace fiberfem::core::hyperelastic
