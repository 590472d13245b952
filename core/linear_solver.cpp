#include "core/linear_solver.hpp"

#include "core/amg_preconditioner.hpp"
#include "core/solvers/direct_solver.hpp"
#include "core/solvers/pcg_solver.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

// The solvers' implementations, one file per job, are in core/solvers/: the PCG solver
// (pcg_solver), its iteration (pcg.hpp), solution recycling (solution_recycler), the warp
// preconditioner and its lagged factors (warp_preconditioner.hpp, lagged_factors), block
// Jacobi (block_jacobi.hpp), the Cholesky factor (cholesky_factor) with its
// single-precision copy (single_precision_solve), and the direct solver (direct_solver).

namespace fiberfem::core {

const char* to_string(PreconditionerKind k) {
  switch (k) {
    case PreconditionerKind::block_jacobi: return "block_jacobi";
    case PreconditionerKind::cholesky: return "cholesky";
    case PreconditionerKind::amg: return "amg";
  }
  return "?";
}

const char* to_string(LinearSolverKind k) { return k == LinearSolverKind::pcg ? "pcg" : "direct"; }

bool has_cholmod() {
#ifdef FIBERFEM_HAVE_CHOLMOD
  return true;
#else
  return false;
#endif
}

SolverSettings with_cost_refresh(SolverSettings s) {
  s.refresh_iterations = 32;
  s.refresh_budget = 1.0;
  return s;
}

int jacobi_first_iterations(Eigen::Index rows) {
  return std::clamp(static_cast<int>(std::lround(std::cbrt(static_cast<double>(std::max<Eigen::Index>(rows, 1))))), 12, 100);
}

double jacobi_first_allowance(double even) { return std::max(2 * even, even * even / 4); }

const char* to_string(FirstFactorisation f) {
  switch (f) {
    case FirstFactorisation::automatic: return "auto";
    case FirstFactorisation::wait: return "wait";
    case FirstFactorisation::beside: return "beside";
  }
  return "auto";
}

void SolverSettings::validate() const {
  if (refresh_iterations < 1)
    throw std::invalid_argument("solver: refresh_iterations must be >= 1, got " + std::to_string(refresh_iterations));
  if (!(refresh_budget >= 0 && std::isfinite(refresh_budget)))
    throw std::invalid_argument("solver: refresh_budget must be finite and >= 0, got " + std::to_string(refresh_budget));
  if (!(tolerance > 0 && tolerance < 1))
    throw std::invalid_argument("solver: tolerance must be in (0, 1), got " + std::to_string(tolerance));
  if (max_iterations < 1)
    throw std::invalid_argument("solver: max_iterations must be >= 1, got " + std::to_string(max_iterations));
  if (recycled_solutions < 0 || recycled_solutions > 64)
    throw std::invalid_argument("solver: recycled_solutions must be in [0, 64], got " + std::to_string(recycled_solutions));
  if (jacobi_first < kJacobiFirstAuto)
    throw std::invalid_argument("solver: jacobi_first must be auto (-1), 0 (off) or a count of iterations, got " +
                                std::to_string(jacobi_first));
  if (!(failure_residual > 0 && std::isfinite(failure_residual)))
    throw std::invalid_argument("solver: failure_residual must be > 0, got " + std::to_string(failure_residual));
  if (method == LinearSolverKind::pcg && preconditioner == PreconditionerKind::amg && !has_amg())
    throw std::invalid_argument(
        "solver: preconditioner amg needs a build with AMGCL (Debian's libamgcl-dev, scripts/setup.sh); use cholesky");
}

void LinearSolver::load_state(const LinearSolverState& state, const SparseMatrix& /*pattern*/) {
  if (state.solver_name != name())
    throw std::invalid_argument("linear solver state: saved by '" + state.solver_name + "', restoring into '" + name() + "'");
}

bool direct_solver_uses_cholmod() {
#ifdef FIBERFEM_HAVE_CHOLMOD
  return true;
#else
  return false;
#endif
}

std::unique_ptr<LinearSolver> make_linear_solver(const SolverSettings& settings) {
  settings.validate();
  if (settings.method == LinearSolverKind::direct) return std::make_unique<detail::DirectSolver>();
  return std::make_unique<detail::PcgSolver>(settings);
}

}  // namespace fiberfem::core
