#pragma once
/// @file The lagged factors of the PCG solver's warp preconditioner: one factor (or amg
/// hierarchy) per matrix family, when to refresh it, and its part of LinearSolverState.

#include "core/linear_solver.hpp"
#include "core/solvers/warp_preconditioner.hpp"

#include <chrono>
#include <future>
#include <memory>
#include <vector>

namespace fiberfem::core::detail {

/// A slot's first factor made on a thread beside the steps (FirstFactorisation::beside):
/// a slot of its own, filled by `job` from a copy of the matrix, that replaces the slot
/// which started it once the solves in between have run `left` more fallback iterations.
struct BesideFactor {
  std::unique_ptr<FactorSlot> made = std::make_unique<FactorSlot>();
  SparseMatrix matrix;     // what is factorised (kept for checkpoints)
  double left = 0;         // fallback iterations before it takes over
  std::future<void> job;   // declared last: destroyed, so waited for, first
  bool running() const { return job.valid() && job.wait_for(std::chrono::seconds(0)) != std::future_status::ready; }
};

/// The factor slots of a PCG solver with the cholesky or amg preconditioner, and the warp
/// state its preconditioner reads (WarpCholeskyPreconditioner::set_state(&warp())).
class LaggedFactors {
 public:
  explicit LaggedFactors(const SolverSettings& s) : s_(s) {}
  /// What the preconditioner applies: the slot in use, the node blocks, the rotations.
  WarpState& warp() { return warp_; }
  const WarpState& warp() const { return warp_; }
  /// Current positions of the node blocks (amg), read at the next refactorisation.
  void set_block_positions(const Eigen::VectorXd& positions) { positions_ = &positions; }
  /// Names the family of the next matrices (the step size h): one factor per family.
  void set_key(double key) { key_ = key; }
  /// Every factor is refreshed at its next use.
  void invalidate() {
    for (auto& sl : slots_) {
      sl->stale = true;
      retire(*sl);  // a factor of the old matrices: the next solve starts another
    }
  }
  /// The slot of the current family (least recently used one replaced), marked used. A
  /// factor made beside the steps whose turn has come takes the slot's place here (waited
  /// for if not done; counted in `st`).
  FactorSlot& select_slot(SolveStats& st);
  /// Whether the first factor of `slot` (which has none) is to be made beside the steps.
  bool factor_beside(const SparseMatrix& A, const FactorSlot& slot) const;
  /// Whether first factors of A's size are made beside the steps (the settings' rule).
  bool first_factors_beside(const SparseMatrix& A) const;
  /// Whether the current family's slot has a factor made beside the steps whose turn has
  /// come (its fallback iterations run): the next select_slot adopts it.
  bool beside_due() const;
  /// Starts factorising a copy of A (its CSR values current) beside the steps for `slot`.
  void start_beside(const SparseMatrix& A, FactorSlot& slot) { start_beside(A, slot, warp_.current, beside_iterations(A)); }
  /// Counts a fallback solve's iterations against the slot's factor made beside; a failed
  /// one (`now`) makes it take over at the next select_slot.
  static void note_fallback(FactorSlot& slot, int iterations, bool now) {
    slot.beside->left = now ? 0.0 : slot.beside->left - iterations;
  }
  /// Factorises A into `slot` (an amg setup with PreconditionerKind::amg), counted in
  /// `st`; `sync` (when given) is the system whose CSR values must be synced first.
  void refactor(const SparseMatrix& A, FactorSlot& slot, SolveStats& st, SparseSystem* sync);
  /// Whether `slot` holds a usable factor or hierarchy.
  static bool ok(const FactorSlot& slot) { return slot.amg.ok() || slot.factor.ok(); }
  /// Counts a solve's iterations against the slot's refresh budget (marks it stale).
  void note_iterations(FactorSlot& slot, int iterations) const;
  /// Factorisations running beside the steps now (one thread each).
  int threads_beside() const;
  /// The factor of the slot last used (FactorInfo).
  FactorInfo info() const;
  /// The slots (and their key and clock) into / from LinearSolverState.
  void save(LinearSolverState& st) const;
  /// @throws std::invalid_argument if the saved factors do not fit `pattern`.
  void check(const LinearSolverState& st, const SparseMatrix& pattern) const;
  void load(const LinearSolverState& st, const SparseMatrix& pattern);

 private:
  // Factors are kept per matrix family (the step size): a step retried with substeps, and
  // the full step after it, each find their own factor instead of refactorising back and
  // forth. At most kSlots factors (least recently used replaced).
  static constexpr size_t kSlots = 2;
  void build_amg(const SparseMatrix& A, const Eigen::VectorXd& positions, FactorSlot& slot);
  void start_beside(const SparseMatrix& A, FactorSlot& slot, const std::vector<Mat3>& at, double left);
  static double beside_iterations(const SparseMatrix& A);
  /// `factor`, before its first factorisation of A, takes another slot's analysis of A's pattern.
  void adopt_analysis(CholeskyFactor& factor, const SparseMatrix& A) const;
  /// A factor made beside the steps that is no longer wanted keeps its thread until done.
  void retire(FactorSlot& slot);
  void adopt_beside(std::unique_ptr<FactorSlot>& sl, SolveStats& st);

  SolverSettings s_;
  WarpState warp_;
  const Eigen::VectorXd* positions_ = nullptr;  // node-block positions of the next solve (amg; the caller's)
  std::vector<std::unique_ptr<FactorSlot>> slots_;
  double key_ = 0;
  long clock_ = 0;
  std::vector<std::shared_ptr<BesideFactor>> retired_;  // finishing; dropped when done
};

}  // namespace fiberfem::core::detail
