#pragma once
/// @file The linear solves of Newton's method on the accurate tier: a sparse LU of the
/// tangent (UMFPACK when built with it), reused while it still preconditions later tangents
/// well. A solve first tries GMRES on the new tangent, preconditioned on the right by the
/// last factor, to the forcing tolerance Newton asks for (on the true residual); only when
/// that does not converge within kMaxKrylovIterations is the tangent factorised again.
/// Near a converged state the tangent barely changes, so most iterations cost a few
/// triangular solves instead of a factorisation.

#include "core/hyperelastic/assembly.hpp"

#include <memory>

namespace fiberfem::core::hyperelastic {

class TangentSolver {
 public:
  /// Iterations of GMRES on a lagged factor before the tangent is factorised afresh (one
  /// application of the factor each; 16 and 36 were slower on the Land problems).
  static constexpr int kMaxKrylovIterations = 24;

  /// `keeps_state`: keep copies of the matrices analysed and factorised, for state()
  /// (a time stepper's checkpoints); off, state() is empty.
  explicit TangentSolver(bool keeps_state = false);
  ~TangentSolver();
  TangentSolver(const TangentSolver&) = delete;
  TangentSolver& operator=(const TangentSolver&) = delete;

  /// Solves K delta = R to relative residual `forcing` (in (0, 1); a fresh factor solves
  /// exactly). `fresh` forces a new factorisation. `warm`: delta holds a guess (of R's
  /// size, finite) that the lagged solve corrects, to the same residual |K delta - R| <=
  /// forcing |R| (a guess already that close costs one product). @return false when the
  /// tangent is singular (no factor) or the answer is not finite.
  bool solve(const SparseMatrix& K, const Eigen::VectorXd& R, double forcing, bool fresh, Eigen::VectorXd& delta,
             bool warm = false);

  /// The solver's memory: the matrix its symbolic analysis was made from and the one its
  /// factor is of (0 x 0 when there is none). Restoring it gives the same factor, so the
  /// solves after a restore equal those of the run it was taken from, bit for bit.
  struct State {
    SparseMatrix analysed;
    SparseMatrix factored;
  };
  State state() const { return {analysed_, factored_}; }
  /// Analyses and factorises the state's matrices again.
  /// @throws std::invalid_argument when its factored matrix is singular.
  void restore(const State& state);

  /// Takes `other`'s memory (its analysis, factor and their matrices) without factorising
  /// again: what restore(other.state()) gives, at no cost. `other` is left without a factor.
  void take_memory(TangentSolver& other);

  /// Threads for the substitutions with a lagged factor (two at most are used; 1 by default).
  void set_threads(int threads) { threads_ = threads; }

  /// Parts of the lagged factor's substitutions that can go on threads of their own: 2
  /// when its elimination splits into two independent halves worth it, else 1 (0: no
  /// single-precision copy).
  int lagged_parts() const;

  int factorisations() const { return factorisations_; }
  int krylov_iterations() const { return krylov_iterations_; }
  double seconds() const { return seconds_; }

 private:
  struct Factor;
  bool factorise(const SparseMatrix& K);
  std::unique_ptr<Factor> factor_;
  bool keeps_state_ = false;
  SparseMatrix analysed_, factored_;  // copies (when keeps_state_): what state() hands out
  bool have_factor_ = false;
  int threads_ = 1;
  int factorisations_ = 0;
  int krylov_iterations_ = 0;
  double seconds_ = 0;
};

}  // namespace fiberfem::core::hyperelastic
