#include "core/solvers/lagged_factors.hpp"

#include <omp.h>

#include <algorithm>
#include <vector>
#include <stdexcept>
#include <string>

namespace fiberfem::core::detail {
namespace {

SparseMatrix with_values(const SparseMatrix& pattern, const Eigen::VectorXd& values) {
  SparseMatrix A = pattern;
  Eigen::Map<Eigen::VectorXd>(A.valuePtr(), A.nonZeros()) = values;
  return A;
}

}  // namespace

FactorSlot& LaggedFactors::select_slot(SolveStats& st) {
  ++clock_;
  // Finished factors of retired slots are dropped (their threads joined, briefly).
  retired_.erase(std::remove_if(retired_.begin(), retired_.end(), [](const auto& b) { return !b->running(); }), retired_.end());
  std::unique_ptr<FactorSlot>* lru = nullptr;
  for (auto& sl : slots_) {
    if (sl->key == key_) {
      sl->last_used = clock_;
      if (sl->beside && sl->beside->left <= 0) adopt_beside(sl, st);
      return *sl;
    }
    if (!lru || sl->last_used < (*lru)->last_used) lru = &sl;
  }
  if (slots_.size() < kSlots) {
    slots_.push_back(std::make_unique<FactorSlot>());
    lru = &slots_.back();
  }
  FactorSlot& slot = **lru;
  retire(slot);
  slot.key = key_;
  slot.stale = true;
  slot.last_used = clock_;
  return slot;
}

// The factor made beside the steps replaces the slot that started it: the same family
// and use, its own factor and age.
void LaggedFactors::adopt_beside(std::unique_ptr<FactorSlot>& sl, SolveStats& st) {
  const std::shared_ptr<BesideFactor> b = std::move(sl->beside);
  b->job.wait();
  std::unique_ptr<FactorSlot> made = std::move(b->made);
  made->rows = b->matrix.rows();
  made->stale = !made->factor.ok();
  made->key = sl->key;
  made->last_used = sl->last_used;
  if (warp_.slot == sl.get()) warp_.slot = nullptr;
  sl = std::move(made);
  ++st.factorizations;
}

bool LaggedFactors::factor_beside(const SparseMatrix& A, const FactorSlot& slot) const {
  if (s_.preconditioner != PreconditionerKind::cholesky || ok(slot) || slot.beside) return false;
  return first_factors_beside(A);
}

bool LaggedFactors::first_factors_beside(const SparseMatrix& A) const {
  return s_.first_factorisation == FirstFactorisation::beside ||
         (s_.first_factorisation == FirstFactorisation::automatic && A.rows() >= kBesideMinRows);
}

bool LaggedFactors::beside_due() const {
  for (const auto& sl : slots_)
    if (sl->key == key_) return sl->beside && sl->beside->left <= 0;
  return false;
}

double LaggedFactors::beside_iterations(const SparseMatrix& A) {
  return std::min<double>(kBesideIterations, static_cast<double>(A.rows()) / 32.0);
}

void LaggedFactors::start_beside(const SparseMatrix& A, FactorSlot& slot, const std::vector<Mat3>& at, double left) {
  auto b = std::make_shared<BesideFactor>();
  b->matrix = A;
  b->left = left;
  b->made->at_factor = at;
  // Taken here, on the stepping thread, while no solve reads the other factors.
  adopt_analysis(b->made->factor, b->matrix);
  const bool single = s_.single_precision_preconditioner;
  BesideFactor* job = b.get();
  // One thread: the steps keep the others (OpenMP's count is per thread; BLAS runs on one).
  b->job = std::async(std::launch::async, [job, single] {
    omp_set_num_threads(1);
    job->made->factor.set_single_precision(single);
    job->made->factor.factorize(job->matrix);
  });
  slot.beside = std::move(b);
}

// Every family's matrix has the system's pattern: a factor not analysed yet takes the
// analysis of a slot's factor made for A's pattern (the same ordering, so the same factor).
void LaggedFactors::adopt_analysis(CholeskyFactor& factor, const SparseMatrix& A) const {
  for (const auto& sl : slots_)
    if (&sl->factor != &factor) factor.adopt_analysis(sl->factor, A);
}

void LaggedFactors::retire(FactorSlot& slot) {
  if (slot.beside) retired_.push_back(std::move(slot.beside));
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
    adopt_analysis(slot.factor, A);
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

int LaggedFactors::threads_beside() const {
  int n = 0;
  for (const auto& sl : slots_) n += sl->beside && sl->beside->running();
  for (const auto& b : retired_) n += b->running();
  return n;
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
    if (const BesideFactor* b = sl->beside.get()) {  // its matrix and rotations, to start again
      f.beside = true;
      f.beside_left = b->left;
      f.matrix_values = Eigen::Map<const Eigen::VectorXd>(b->matrix.valuePtr(), b->matrix.nonZeros());
      f.at_factor = b->made->at_factor;
    }
    st.factors.push_back(std::move(f));
  }
}

void LaggedFactors::check(const LinearSolverState& st, const SparseMatrix& pattern) const {
  if (st.factors.size() > kSlots)
    throw std::invalid_argument("linear solver state: " + std::to_string(st.factors.size()) + " factors, at most " +
                                std::to_string(kSlots));
  for (const auto& f : st.factors) {
    if ((f.factored || f.beside) && f.matrix_values.size() != pattern.nonZeros())
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
      const SparseMatrix A = with_values(pattern, f.matrix_values);
      if (s_.preconditioner == PreconditionerKind::amg) {
        build_amg(A, f.setup_positions, *sl);  // (sizes checked by check(), before anything changed)
      } else {
        sl->factor.set_single_precision(s_.single_precision_preconditioner);
        adopt_analysis(sl->factor, A);
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
    if (f.beside) start_beside(with_values(pattern, f.matrix_values), *sl, f.at_factor, f.beside_left);
    slots_.push_back(std::move(sl));
  }
}

}  // namespace fiberfem::core::detail
