#pragma once
/// @file Static equilibrium of the corotational model by Newton's method with load
/// stepping and a line search (PHYSICS.md section 4), for comparisons with analytic answers.

#include "core/model.hpp"
#include "core/rotation.hpp"

#include <string>
#include <vector>

namespace fiberfem::core {

/// Settings of the static solve. Every field has a default; `validate()` names a bad one.
struct StaticSettings {
  int load_steps = 1;                 ///< Equal load increments, >= 1. Default 1.
  int max_newton_iterations = 30;     ///< Per load step, >= 1. Default 30.
  double tolerance = 1e-10;           ///< |residual| / |f_ext| to stop, in (0, 1). Default 1e-10.
  /// Consistent tangent (with dR/dx, non-symmetric, sparse LU) or the warped stiffness
  /// R K R^T alone (symmetric; converges only linearly). Default true.
  bool consistent_tangent = true;
  /// Backtracking (halving the step) when the new residual is not finite or more than
  /// 1e4 times the current one: a safeguard, since Newton on large rotations passes through
  /// larger residuals on its way to quadratic convergence. Default true.
  bool line_search = true;
  int max_cutbacks = 8;               ///< Halvings of a load increment that fails, >= 0. Default 8.
  RotationMethod rotation = RotationMethod::svd;  ///< Default svd.
  bool corotation = true;             ///< false: plain linear FEM. Default true.
  /// @throws std::invalid_argument naming the field.
  void validate() const;
};

struct StaticReport {
  bool converged = false;
  int load_steps = 0;                 ///< Increments taken (including cut-backs).
  int newton_iterations = 0;          ///< Summed over increments.
  double relative_residual = 0;       ///< Final |r| / |f_ext|.
  std::vector<double> residual_history;  ///< |r|/|f_ext| after every Newton iteration.
  std::string message;
};

/// Solves f_int(x) + f_ext = 0 for the model's loads (dead loads, fixed DOFs at rest).
/// @param x in: initial guess (3 x N; the rest shape if empty), out: the solution.
/// @throws std::invalid_argument for an invalid model or settings; numerical failure is
/// reported in StaticReport, with `x` left at the last converged load level.
StaticReport solve_static(Model model, Positions& x, const StaticSettings& settings = {});

}  // namespace fiberfem::core
