#include "core/solvers/pcg_solver.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <type_traits>

namespace fiberfem::core::detail {

SolveStats PcgSolver::solve(const SparseMatrix& A, const Eigen::VectorXd& b_in, Eigen::VectorXd& x) {
  if (!s_.warm_start || x.size() != b_in.size()) x = Eigen::VectorXd::Zero(b_in.size());
  // Solve for x / |b| with a unit right-hand side: CG's squared norms would underflow
  // below DBL_MIN for a body decaying to rest (|b| ~ 1e-154) and stop it early.
  const double bn = b_in.norm();
  if (bn == 0.0) {
    x.setZero();
    SolveStats st;
    st.ok = true;
    return st;
  }
  if (!std::isfinite(bn)) return failed({});
  scaled_b_ = b_in / bn;
  const Eigen::VectorXd& b = scaled_b_;
  // The upper block store when it holds this matrix (the simulator's step) and this
  // solver's passes have a block form (the cholesky and block-Jacobi preconditioners; the
  // projection with eight recycled solutions); otherwise the CSR values, synced.
  use_blocks_ = system_ && system_->blocks_current() && &A == &system_->matrix() &&
                s_.preconditioner != PreconditionerKind::amg && (!s_.warm_start || s_.recycled_solutions == 8);
  if (system_ && system_->blocks_current() && !use_blocks_) system_->sync_matrix();
  pcg_.blocks_ = use_blocks_ ? system_ : nullptr;
  x /= bn;
  const Eigen::VectorXd* Ax0 = s_.warm_start ? recycler_.project(A, b, x, use_blocks_ ? system_ : nullptr) : nullptr;
  SolveStats st = solve_scaled(A, b, x, Ax0);
  if (st.ok && s_.warm_start) recycler_.remember(x);
  x *= bn;
  rotations_given_ = false;
  return st;
}

SolveStats PcgSolver::solve_same_matrix(const SparseMatrix& A, const Eigen::VectorXd& b_in, Eigen::VectorXd& x) {
  if (!s_.warm_start || s_.recycled_solutions == 0) {
    rotations_given_ = true;  // the last solve's matrix, so its rotations
    return solve(A, b_in, x);
  }
  if (x.size() != b_in.size()) x = Eigen::VectorXd::Zero(b_in.size());
  const double bn = b_in.norm();
  if (bn == 0.0 || !std::isfinite(bn)) {
    if (bn == 0.0) x.setZero();
    SolveStats st;
    st.ok = bn == 0.0;
    return st;
  }
  scaled_b_ = b_in / bn;
  use_blocks_ = system_ && system_->blocks_current() && &A == &system_->matrix() &&
                s_.preconditioner != PreconditionerKind::amg && s_.recycled_solutions == 8;
  if (system_ && system_->blocks_current() && !use_blocks_) system_->sync_matrix();
  pcg_.blocks_ = use_blocks_ ? system_ : nullptr;
  x /= bn;
  rotations_given_ = true;  // the last solve's matrix, so its rotations
  SolveStats st = solve_scaled(A, scaled_b_, x, nullptr);
  rotations_given_ = false;
  x *= bn;
  return st;
}

template <class Preconditioner>
SolveStats PcgSolver::run(Preconditioner& pre, const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                          const Eigen::VectorXd* Ax0, int max_iterations) {
  if constexpr (std::is_same_v<Preconditioner, BlockJacobiPreconditioner>) {
    if (use_blocks_)
      pre.compute_from_blocks(*system_);  // the diagonal blocks where the step left them
    else
      pre.compute(A);
  } else {
    pre.compute(A);
  }
  const int cap = max_iterations > 0 ? max_iterations : s_.max_iterations;
  return pcg_.solve(
      A, b, x, s_.tolerance, cap, [&](const Eigen::VectorXd& r, Eigen::VectorXd& z) { pre._solve_impl(r, z); }, Ax0);
}

// SolverSettings::jacobi_first: block Jacobi with the iterations it may take before the
// run's summed excess over the break-even passes the allowance; the excess counted.
bool PcgSolver::jacobi_first_solve(const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                                   const Eigen::VectorXd* Ax0, SolveStats& cg) {
  const double even = jacobi_first_even(A);
  const int cap =
      std::max(1, static_cast<int>(std::min<double>(s_.max_iterations, even + jacobi_first_allowance(even) - jacobi_excess_)));
  first_guess_ = x;
  cg = run(jacobi_pre_, A, b, x, Ax0, cap);
  if (cg.ok) {
    jacobi_excess_ = std::max(0.0, jacobi_excess_ + cg.iterations - even);
    return true;
  }
  jacobi_first_ = false;  // the factor from here on, from the same guess
  x = first_guess_;
  return false;
}

SolveStats PcgSolver::solve_scaled(const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                                   const Eigen::VectorXd* Ax0) {
  if (s_.preconditioner == PreconditionerKind::block_jacobi) return run(jacobi_pre_, A, b, x, Ax0);
  int tried = 0;  // block-Jacobi iterations of a solve cut off (jacobi_first)
  // Where first factors are made beside the steps, the solves run block Jacobi uncut until
  // that factor's turn (solve_factored: no switch may wait for a factorisation that has not
  // started), their iterations beyond the break-even counted. When its turn comes, block
  // Jacobi goes on if they stayed within the allowance, the factor held for the switch.
  if (jacobi_first_ && lagged_.first_factors_beside(A)) {
    if (!lagged_.beside_due()) {
      SolveStats st = solve_factored(A, b, x, Ax0);
      const bool on_factor = lagged_.warp().slot && LaggedFactors::ok(*lagged_.warp().slot);
      if (on_factor || st.factorizations > 0) {
        jacobi_first_ = false;  // block Jacobi fell short: the factor took over
      } else if (st.ok) {
        jacobi_excess_ = std::max(0.0, jacobi_excess_ + st.iterations - jacobi_first_even(A));
      }
      return st;
    }
    const double even = jacobi_first_even(A);
    if (jacobi_excess_ > jacobi_first_allowance(even)) jacobi_first_ = false;
  }
  if (jacobi_first_) {
    SolveStats cg;
    if (jacobi_first_solve(A, b, x, Ax0, cg)) return cg;
    tried = cg.iterations;
  }
  SolveStats st = solve_factored(A, b, x, Ax0);
  st.iterations += tried;
  return st;
}

// With a lagged factor: the slot of this matrix family, refactorised when stale; a solve
// that fails with an old factor refactorises and starts again from the same guess. A
// slot's first factor may be made beside the steps, which solve with block Jacobi until
// it takes over (FirstFactorisation::beside).
SolveStats PcgSolver::solve_factored(const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                                     const Eigen::VectorXd* Ax0) {
  SolveStats st;
  SparseSystem* sync = use_blocks_ ? system_ : nullptr;
  FactorSlot* slot = &lagged_.select_slot(st);
  const bool beside = lagged_.factor_beside(A, *slot);
  // Not on the run's first solve (no solution remembered yet), which solves with block
  // Jacobi on every thread and leaves them to the rest of its step (the energy check's
  // element pass): the first stepped state comes without the matrix's copy and with a
  // pass on two threads (about 80 ms sooner at 252,368 tets). Its next solve starts it.
  const bool defer = beside && takes_guess();
  const bool start = beside && !defer;
  // The copy to factorise reads the CSR values (block Jacobi reads the blocks).
  if (start && sync) sync->sync_matrix();
  int fallback = 0;  // iterations of block Jacobi that fell short
  if (start || defer || slot->beside) {
    first_guess_ = x;
    const SolveStats cg = run(jacobi_pre_, A, b, x, Ax0);
    if (defer) {
      if (cg.ok) return cg;
      x = first_guess_;  // block Jacobi fell short: the factor now, waited for
      ensure_rotations();
      SolveStats now = solve_lagged(*slot, A, b, x, Ax0, st);
      now.iterations += cg.iterations;
      return now;
    }
    if (start) {
      // The factorisation of this step's matrix starts after its solve, which had every
      // thread (the factor takes over after the same count of iterations). The rest
      // of this step leaves its core to the new thread, as the next steps will
      // (Simulator::step counts threads_beside()): three threads on two cores made block
      // products wait for a descheduled one (1.5 s at 250,000 tets).
      ensure_rotations();  // the factor is made at them
      lagged_.start_beside(A, *slot);
      omp_set_num_threads(std::max(1, omp_get_max_threads() - 1));
    }
    LaggedFactors::note_fallback(*slot, cg.iterations, !cg.ok);
    if (cg.ok) return cg;
    x = first_guess_;  // the factor takes over now, from the same guess
    fallback = cg.iterations;
    slot = &lagged_.select_slot(st);
  }
  ensure_rotations();
  SolveStats cg = solve_lagged(*slot, A, b, x, Ax0, st);
  cg.iterations += fallback;
  return cg;
}

// The warp needs this state's node rotations, which a caller skips while block Jacobi
// runs first (uses_block_rotations()): from the rotation source, once per solve.
void PcgSolver::ensure_rotations() {
  if (!rotations_given_ && rotation_source_) lagged_.warp().current = rotation_source_();
  rotations_given_ = true;
}

double PcgSolver::jacobi_first_even(const SparseMatrix& A) const {
  return s_.jacobi_first > 0 ? s_.jacobi_first : jacobi_first_iterations(A.rows());
}

SolveStats PcgSolver::solve_lagged(FactorSlot& slot, const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                                   const Eigen::VectorXd* Ax0, SolveStats& st) {
  WarpState& warp = lagged_.warp();
  SparseSystem* sync = use_blocks_ ? system_ : nullptr;
  warp.slot = &slot;
  if (slot.stale || !LaggedFactors::ok(slot) || slot.rows != A.rows()) lagged_.refactor(A, slot, st, sync);
  if (!LaggedFactors::ok(slot)) return failed(st);
  warp.update_warp();
  first_guess_ = x;
  const Eigen::VectorXd& x0 = first_guess_;
  SolveStats cg = run(warp_pre_, A, b, x, Ax0);
  int first = 0;  // iterations of a first attempt with the old factor
  if (!cg.ok && st.factorizations == 0) {
    // The old factor was too far from this matrix: refresh it and solve again.
    lagged_.refactor(A, slot, st, sync);
    if (!LaggedFactors::ok(slot)) return failed(st);
    warp.update_warp();
    first = cg.iterations;
    x = x0;
    cg = run(warp_pre_, A, b, x, Ax0);
  }
  lagged_.note_iterations(slot, cg.iterations);  // with the factor now in the slot
  cg.iterations += first;
  cg.factorizations = st.factorizations;
  slot.stale = slot.stale || cg.iterations > s_.refresh_iterations;
  return cg;
}

SolveStats PcgSolver::failed(SolveStats st) {
  st.ok = false;
  st.relative_residual = std::numeric_limits<double>::infinity();
  return st;
}

LinearSolverState PcgSolver::save_state() const {
  LinearSolverState st;
  st.solver_name = name();
  recycler_.save(st);
  lagged_.save(st);
  st.jacobi_first = jacobi_first_;
  st.jacobi_first_excess = jacobi_excess_;
  return st;
}

void PcgSolver::load_state(const LinearSolverState& st, const SparseMatrix& pattern) {
  if (st.solver_name != name())
    throw std::invalid_argument("linear solver state: saved by '" + st.solver_name + "', restoring into '" + name() + "'");
  SolutionRecycler::check(st);
  lagged_.check(st, pattern);
  recycler_.load(st);
  lagged_.load(st, pattern);
  // A run saved on block Jacobi goes on with it where this solver allows it; one saved
  // after the switch (or before jacobi_first existed: absent, false) with the factor.
  jacobi_first_ = st.jacobi_first && s_.preconditioner == PreconditionerKind::cholesky && s_.jacobi_first != 0;
  jacobi_excess_ = st.jacobi_first_excess;
}

}  // namespace fiberfem::core::detail
