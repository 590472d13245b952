#include "core/solvers/lagged_factors.hpp"

#include <omp.h>

#include <algorithm>
#include <stdexcept>
#include <string>

namespace fiberfem::core::detail {

FactorSlot& LaggedFactors::select_slot() {
  ++clock_;
  FactorSlot* lru = nullptr;
  for (auto& sl : slots_) {
    if (sl->key == key_) {
      sl->last_used = clock_;
      return *sl;
    }
    if (!lru || sl->last_used < lru->last_used) lru = sl.get();
  }
  if (slots_.size() < kSlots) {
    slots_.push_back(std::make_unique<FactorSlot>());
    lru = slots_.back().get();
  }
  lru->key = key_;
  lru->stale = true;
  lru->last_used = clock_;
  return *lru;
}

void LaggedFactors::build_amg(const SparseMatrix& A, const Eigen::VectorXd& positions, FactorSlot& slot) {
  slot.amg_matrix = A;  // kept for checkpoints (a Cholesky factor keeps its own copy)
  slot.amg_positions = positions;
  if (!slot.amg.build(A, positions)) slot.amg_matrix = SparseMatrix();
}

void LaggedFactors::refactor(const SparseMatrix& A, FactorSlot& slot, SolveStats& st, SparseSystem* sync) {
  if (sync) sync->sync_matrix();  // the factorisation reads the CSR values (of A)
  if (s_.preconditioner == PreconditionerKind::amg) {
    // Rigid-body modes about the current configuration (about the rest one, 40 instead
    // of 9 iterations were measured once the beam had swung).
    if (!positions_ || positions_->size() != A.rows())
      throw std::logic_error("pcg/amg: set_block_positions was not called with the " + std::to_string(A.rows()) +
                             " node-block positions before solve");
    build_amg(A, *positions_, slot);
  } else {
    slot.factor.set_single_precision(s_.single_precision_preconditioner);
    slot.factor.factorize(A);
  }
  slot.at_factor = warp_.current;
  slot.rows = A.rows();
  slot.stale = false;
  slot.baseline = -1;
  slot.excess = 0;
  ++st.factorizations;
}

// The refresh rule that minimises the time of a run when a factor's iterations grow as
// it ages: refactorise once the iterations it has cost beyond its first solve add up to
// what a factorisation costs, counted in iterations (its flops over those of one
// application of the factor, 4 nnz(L)), times refresh_budget. Deterministic: counts,
// not timings, so a run and its restore from a checkpoint refresh at the same steps.
void LaggedFactors::note_iterations(FactorSlot& slot, int iterations) const {
  if (slot.baseline < 0) {
    slot.baseline = iterations;
    return;
  }
  slot.excess += std::max(0, iterations - slot.baseline);
  const double setup_cost =
      s_.preconditioner == PreconditionerKind::amg ? kAmgSetupIterations : slot.factor.iterations_per_factorisation();
  if (s_.refresh_budget > 0 && slot.excess > s_.refresh_budget * setup_cost)
    slot.stale = true;
}

FactorInfo LaggedFactors::info() const {
  if (!warp_.slot) return {};
  if (!warp_.slot->amg.ok()) return warp_.slot->factor.info();
  FactorInfo i;  // an amg hierarchy: no factor entries or flops to report
  i.factored = true;
  i.ordering = "amg";
  i.solve_threads = omp_get_max_threads();
  return i;
}

void LaggedFactors::save(LinearSolverState& st) const {
  st.key = key_;
  st.clock = clock_;
  for (const auto& sl : slots_) {
    LinearSolverState::Factor f;
    f.factored = ok(*sl);
    if (f.factored) {
      if (sl->amg.ok()) {
        f.matrix_values = Eigen::Map<const Eigen::VectorXd>(sl->amg_matrix.valuePtr(), sl->amg_matrix.nonZeros());
        f.setup_positions = sl->amg_positions;
      } else {
        const auto& A = sl->factor.matrix();
        f.matrix_values = Eigen::Map<const Eigen::VectorXd>(A.valuePtr(), A.nonZeros());
      }
    }
    f.at_factor = sl->at_factor;
    f.rows = sl->rows;
    f.stale = sl->stale;
    f.baseline = sl->baseline;
    f.excess = sl->excess;
    f.key = sl->key;
    f.last_used = sl->last_used;
    st.factors.push_back(std::move(f));
  }
}

void LaggedFactors::check(const LinearSolverState& st, const SparseMatrix& pattern) const {
  if (st.factors.size() > kSlots)
    throw std::invalid_argument("linear solver state: " + std::to_string(st.factors.size()) + " factors, at most " +
                                std::to_string(kSlots));
  for (const auto& f : st.factors) {
    if (f.factored && f.matrix_values.size() != pattern.nonZeros())
      throw std::invalid_argument("linear solver state: a factor's matrix has " + std::to_string(f.matrix_values.size()) +
                                  " values, the system " + std::to_string(pattern.nonZeros()));
    if (f.factored && s_.preconditioner == PreconditionerKind::amg && f.setup_positions.size() != pattern.rows())
      throw std::invalid_argument("linear solver state: an amg hierarchy with " + std::to_string(f.setup_positions.size()) +
                                  " setup positions, the system " + std::to_string(pattern.rows()));
  }
}

void LaggedFactors::load(const LinearSolverState& st, const SparseMatrix& pattern) {
  key_ = st.key;
  clock_ = st.clock;
  slots_.clear();
  warp_.slot = nullptr;
  for (const auto& f : st.factors) {
    auto sl = std::make_unique<FactorSlot>();
    if (f.factored) {
      SparseMatrix A = pattern;
      Eigen::Map<Eigen::VectorXd>(A.valuePtr(), A.nonZeros()) = f.matrix_values;
      if (s_.preconditioner == PreconditionerKind::amg) {
        build_amg(A, f.setup_positions, *sl);  // (sizes checked by check(), before anything changed)
      } else {
        sl->factor.set_single_precision(s_.single_precision_preconditioner);
        sl->factor.factorize(A);
      }
    }
    sl->at_factor = f.at_factor;
    sl->rows = f.rows;
    sl->stale = f.stale;
    sl->baseline = f.baseline;
    sl->excess = f.excess;
    sl->key = f.key;
    sl->last_used = f.last_used;
    slots_.push_back(std::move(sl));
  }
}

}  // namespace fiberfem::core::detail
