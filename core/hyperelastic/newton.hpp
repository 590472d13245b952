#pragma once
/// @file Static equilibrium of a Problem by Newton's method with the consistent tangent,
/// load stepping and a backtracking line search (ACCURATE.md section 4): a step that
/// inverts an element or gives a non-finite residual is cut back, a load increment that
/// does not converge is halved, and a load that cannot be carried is reported with the
/// load factor reached.

#include "core/hyperelastic/assembly.hpp"
#include "core/hyperelastic/tangent_solver.hpp"

#include <functional>

#include <string>
#include <vector>

namespace fiberfem::core::hyperelastic {

/// Every field has a default; validate() names a bad one by its scene key.
struct NewtonSettings {
  int load_steps = 10;         ///< solver.load_steps: equal increments of the load factor, >= 1. Default 10.
  double tolerance = 1e-9;     ///< solver.newton.tolerance: |R_u| / |f_ref| and the volume residual / V, in (0, 1). Default 1e-9.
  /// solver.newton.increment_tolerance: the same measure for the load increments before
  /// the last (the larger of the two applies), in (0, 1). Default 1e-9 (as tolerance);
  /// a scene whose regions are all incompressible takes kMixedIncrementTolerance.
  double increment_tolerance = 1e-9;
  static constexpr double kMixedIncrementTolerance = 1e-3;
  int max_iterations = 30;     ///< solver.newton.max_iterations per increment, >= 1. Default 30.
  int max_cutbacks = 10;       ///< Halvings of increments over the solve, >= 0. Default 10.
  bool line_search = true;     ///< solver.newton.line_search. Default true.
  int threads = 0;             ///< solver.threads: element-loop threads, 0 the engine's choice. Default 0.
  /// Gives up when the merit is still not below the solve's first after this many
  /// iterations (0: never). Not a scene key: the time steps set it (DynamicSettings), whose
  /// failed steps are retried in substeps; the static load increments do not.
  int give_up_after = 0;
  /// Lets the linear solves of the last iterations stop at what takes the residual below
  /// the tolerance (Forcing in newton.cpp) rather than at the residual itself. Not a scene
  /// key: the time steps set it (DynamicSettings); on the static load increments it cost
  /// more than it saved (Land problem 3 on 48 / 20 / 6: 4 -> 25 factorisations).
  bool forcing_floor = false;
  /// @throws std::invalid_argument naming the key.
  void validate() const;
};

struct NewtonReport {
  bool converged = false;
  double load_factor = 0;             ///< The load factor of the last converged state (1 when converged).
  int load_steps = 0;                 ///< Increments taken (cut-backs included).
  int iterations = 0;                 ///< Newton iterations summed over increments.
  int cutbacks = 0;
  double relative_residual = 0;       ///< Final |R_u| / |f_ref|.
  std::vector<double> residual_history;  ///< |R_u| / |f_ref| after each iteration of the last increment.
  double assembly_s = 0;              ///< Wall time in residual and tangent evaluations, s.
  double factor_s = 0;                ///< Wall time in factorisations and solves, s.
  int factorisations = 0;             ///< Tangents factorised (the others solved on a lagged factor).
  int krylov_iterations = 0;          ///< GMRES iterations on lagged factors.
  int equations = 0;                  ///< Unknowns of the linear systems.
  std::string message;
};

/// Newton's measure of a residual: the force rows against the reference load plus the volume
/// rows (the mixed form's) against the body's volume.
double residual_merit(const Assembler& assembler, const Eigen::VectorXd& R);

/// The residual (and, with K, the tangent) of the equations Newton solves at (x, p).
using ResidualFn = std::function<Evaluation(const Positions& x, const Eigen::VectorXd& p, Eigen::VectorXd& R, SparseMatrix* K)>;

/// Newton's iterations on R(x, p) = 0 from (x, p) (with R, K already evaluated there):
/// inexact linear solves on `linear`, the line search, the round-off floor. Counts into
/// `report` (iterations, residual history of this solve). On return (x, p, R) are the last
/// accepted iterate. @return whether it converged; `singular` when a tangent could not be
/// factorised.
bool newton_iterate(const Assembler& assembler, TangentSolver& linear, const ResidualFn& residual, const NewtonSettings& s,
                    Positions& x, Eigen::VectorXd& p, Eigen::VectorXd& R, SparseMatrix& K, Evaluation& ev,
                    NewtonReport& report, bool& singular);

/// Unknowns bordered onto Newton's iteration: m load magnitudes P (a circulation's cavity
/// pressures, Pa) on which the residual depends linearly, R(x, p; P) = R_0 + sum_k P_k u_k(x),
/// with one constraint each, g(x, P) = 0.
struct Border {
  /// The residual with the loads at P (and, with K, its tangent in x and p).
  std::function<Evaluation(const Positions& x, const Eigen::VectorXd& p, const Eigen::VectorXd& P, Eigen::VectorXd& R,
                           SparseMatrix* K)>
      residual;
  /// u_k(x) = dR/dP_k, each in equation rows.
  std::function<void(const Positions& x, std::vector<Eigen::VectorXd>& u)> unit_residuals;
  /// The constraints g (size m) at (x, P), their gradients in x in equation rows (G[k]),
  /// and dg/dP (m x m). @throws std::runtime_error when they cannot be evaluated there.
  std::function<void(const Positions& x, const Eigen::VectorXd& P, Eigen::VectorXd& g, std::vector<Eigen::VectorXd>& G,
                     Eigen::MatrixXd& dg_dP)>
      constraints;
  /// Converged when also |g_k| <= tolerance(k) for every k.
  Eigen::VectorXd tolerance;
};

/// Newton's iterations on R(x, p; P) = 0, g(x, P) = 0 from (x, p, P), the border eliminated
/// each iteration (one solve for R and one per unknown P_k with the same tangent, then the
/// m x m Schur complement on P), with the line search and round-off floor of
/// newton_iterate. On return (x, p, P) are the last accepted iterate.
/// @return whether it converged; `singular` when a tangent could not be factorised.
bool newton_iterate_bordered(const Assembler& assembler, TangentSolver& linear, const Border& border, const NewtonSettings& s,
                             Positions& x, Eigen::VectorXd& p, Eigen::VectorXd& P, NewtonReport& report, bool& singular);

/// Solves R(x, p) = 0 at load factor 1 from (x, p) (the rest shape and zero pressure when
/// empty). On failure (x, p) hold the last converged load level.
/// @throws std::invalid_argument for an invalid problem or settings.
NewtonReport solve_static(const Problem& problem, Positions& x, Eigen::VectorXd& p, const NewtonSettings& settings = {});

}  // namespace fiberfem::core::hyperelastic
