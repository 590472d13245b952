#pragma once
/// @file Linear solvers for the step's symmetric positive definite system (PHYSICS.md section 5).

#include "core/sparse_system.hpp"

#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace fiberfem::core {

enum class LinearSolverKind {
  pcg,     ///< Preconditioned conjugate gradient (block-Jacobi 3x3 preconditioner).
  direct,  ///< Sparse Cholesky every step (CHOLMOD supernodal when built with it, else Eigen LLT).
};

/// Preconditioner of the PCG solver.
enum class PreconditionerKind {
  /// Inverse of each node's 3x3 diagonal block. Cheap to build, weak: iterations grow with
  /// the stiffness-to-mass ratio h^2 K / M and with the mesh resolution.
  block_jacobi,
  /// A sparse Cholesky factor of an earlier step's matrix, warped by the change of each
  /// node's rotation since then (W A_0^-1 W^T; SOFA's warp preconditioner, Courtecuisse et
  /// al. 2010). Refactorised when the extra iterations of the aging factor have cost about
  /// a factorisation (`refresh_budget`) or a solve needs more than `refresh_iterations`;
  /// between refreshes a step costs a few triangular solves. Memory: the factor.
  cholesky,
  /// Smoothed-aggregation algebraic multigrid (AMGCL; core/amg_preconditioner.hpp) of an
  /// earlier step's matrix, one single-precision V-cycle per iteration (always float:
  /// single_precision_preconditioner does not apply), with the rigid-body modes of the
  /// configuration it was built in; lagged and warped by the nodes' rotations exactly as
  /// the cholesky factor (same refresh rules, a setup priced at kAmgSetupIterations
  /// iterations). At 250,000 tets: more iterations than the factor, each about a third of
  /// its cost, a setup of 0.2-0.5 s where a factorisation takes 3-8 s, a third of the
  /// memory; it pays where the body moves fast (docs/performance.md). Needs a build with
  /// AMGCL (has_amg()) and every node wholly free or wholly fixed.
  amg,
};
const char* to_string(PreconditionerKind k);
/// What an amg setup costs, counted in PCG iterations for the refresh budget: measured
/// on the 245,760-tet beam's step matrix, a setup takes about 200 ms and an iteration
/// 6.2 ms (a whole first step, with its extra iterations, up to 0.5 s).
constexpr double kAmgSetupIterations = 32.0;
/// "pcg" or "direct".
const char* to_string(LinearSolverKind k);

/// When the cholesky preconditioner's first factor of a matrix family is made.
enum class FirstFactorisation {
  /// `beside` for systems of at least kBesideMinRows free DOFs, else `wait` (on any thread
  /// count, so that runs on any count stay the same bits; `beside` takes a thread more
  /// while it runs, `wait` keeps a run on its count of cores).
  automatic,
  /// The step waits for it (a large mesh's first step takes the factorisation's time:
  /// 3.7 s at 250,000 tets).
  wait,
  /// It is made on a thread beside the steps, which meanwhile solve with block Jacobi;
  /// it takes over at the first solve after they have run kBesideIterations iterations
  /// (fewer below 32,000 rows: rows / 32), waiting for it there if it is not done. A count,
  /// not a clock, so a run and its restore from a checkpoint switch at the same step.
  beside,
};
const char* to_string(FirstFactorisation f);
/// Fewest free DOFs for FirstFactorisation::automatic to factorise beside the steps.
inline constexpr int kBesideMinRows = 20000;
/// Block-Jacobi iterations run before a factor made beside the steps takes over (what a
/// factorisation cost in such iterations on the beams of docs/vega-comparison.md: about
/// 900 at 50,000 tets, 1,100 at 250,000, one core each).
inline constexpr int kBesideIterations = 1000;

/// SolverSettings::jacobi_first chosen from the system.
inline constexpr int kJacobiFirstAuto = -1;
/// The automatic break-even of SolverSettings::jacobi_first for a system of `rows` unknowns:
/// the cube root of the rows, within [12, 100]. A block-Jacobi iteration costs about one
/// product with the matrix; an application of the factor one such product plus the two
/// substitutions, whose entries grow against the matrix's as the cube root of the rows
/// for a 3-D mesh (nested dissection), and the factorisation besides. Measured on the Vega
/// comparison's beams (one thread, docs/performance.md): the break-even is about 17
/// iterations at 4,700 unknowns and about 55 at 34,000; the cube roots, 17 and 32, err on
/// the side of the factor.
int jacobi_first_iterations(Eigen::Index rows);
/// How far the iterations of SolverSettings::jacobi_first may run beyond the break-even
/// `even`, summed over the solves, before the run switches to the factor: even^2 / 4 (at
/// least 2 even), about what a factorisation costs in block-Jacobi iterations (measured
/// about 70 at 4,700 unknowns, 900 at 34,000; the rule gives 72 and 256). It carries the
/// first solves, which start from fewer recycled solutions and take two or three times
/// the iterations of later ones.
double jacobi_first_allowance(double even);

/// Settings of the linear solve. Defaults are the engine's `balanced` choice.
struct SolverSettings {
  LinearSolverKind method = LinearSolverKind::pcg;  ///< pcg | direct. Default pcg.
  PreconditionerKind preconditioner = PreconditionerKind::cholesky;  ///< Default cholesky.
  /// With the cholesky preconditioner: a solve that needs more iterations than this makes
  /// the next solve refactorise, >= 1. Default 8 (the `interactive` preset: 32).
  int refresh_iterations = 8;
  /// With the cholesky preconditioner: the next solve also refactorises once the
  /// iterations the factor has cost beyond its first solve add up to refresh_budget times
  /// a factorisation's cost counted in iterations (its flops over 4 nnz(L), what one
  /// application of the factor costs). 0 turns the rule off (refresh_iterations alone),
  /// finite, >= 0. Default 0 (the `interactive` preset: 1, the refresh that minimises a
  /// run's time when the iterations grow steadily with the factor's age; off by default
  /// because it changes which steps refresh, and the marginal 1,000:1 fiber ratio case of
  /// the stability map then gains 12.6 % energy after its release instead of 4.4 %).
  double refresh_budget = 0.0;
  /// With the cholesky preconditioner: apply the factor in single precision (a float copy
  /// of the CHOLMOD factor; the factorisation and PCG stay double). The preconditioner is
  /// an approximation of a lagged matrix anyway; its round-off (1e-7) is far below the
  /// lag's. Default true. Without CHOLMOD it has no effect.
  bool single_precision_preconditioner = true;
  double tolerance = 1e-6;    ///< PCG relative residual |r|/|b|, in (0, 1). Default 1e-6.
  int max_iterations = 500;   ///< PCG iteration cap, >= 1. Default 500.
  bool warm_start = true;     ///< PCG starts from the last velocity. Default true.
  /// With warm_start: the initial guess is the best combination (Galerkin projection, the
  /// least A-norm error) of the last `recycled_solutions` solutions (the given guess is
  /// used only before there are any: LinearSolver::takes_guess()),
  /// which costs one pass over A for all of them; 0 keeps the given guess. In [0, 64].
  /// Default 8 (halves PCG iterations on the cantilever benchmark, docs/performance.md).
  int recycled_solutions = 8;
  /// A step whose relative residual ends above this counts as failed (rolled back and
  /// retried with substeps), in (0, inf). Default 1e-2.
  double failure_residual = 1e-2;
  /// With the cholesky preconditioner: when the first factor of each matrix family is
  /// made (FirstFactorisation). Default automatic.
  FirstFactorisation first_factorisation = FirstFactorisation::automatic;
  /// With the cholesky preconditioner: solve with block Jacobi (no factorisation) for as
  /// long as it stays cheaper than the factor would be, then switch to the factor for the
  /// rest of the run. The value is the break-even: block-Jacobi iterations a solve may take
  /// on average; the run switches at the first solve that would bring the iterations beyond
  /// it, summed from the first solve (and never below 0), above jacobi_first_allowance(): a
  /// solve is cut off there and taken again from the same guess with the factor.
  /// kJacobiFirstAuto: chosen from the system, jacobi_first_iterations(); 0: off (the
  /// factor from the first solve). Where first factors are made beside the steps
  /// (first_factorisation beside, or automatic from kBesideMinRows unknowns) the factor is
  /// made there as ever, the solves meanwhile run block Jacobi uncut, and when its turn
  /// comes block Jacobi goes on (cut off as above) if those solves stayed within the
  /// allowance, the finished factor held for the switch. Default auto.
  int jacobi_first = kJacobiFirstAuto;
  /// @throws std::invalid_argument naming the field.
  void validate() const;
};

/// `s` with the factor refreshed by cost (the `interactive` fidelity preset's rule):
/// refresh_budget 1, refresh_iterations 32 only as a bound.
SolverSettings with_cost_refresh(SolverSettings s);

/// Whether the engine was built with CHOLMOD (the supernodal factor, its single-precision
/// copy, UMFPACK for the static solver); without it Eigen's simplicial solvers stand in.
bool has_cholmod();

/// Result of one solve.
struct SolveStats {
  int iterations = 0;          ///< PCG iterations (1 for the direct solver).
  int factorizations = 0;      ///< Cholesky factorisations done by this solve (0 or more).
  double relative_residual = 0;  ///< |A x - b| / |b|.
  bool ok = false;             ///< Finite result and (for PCG) converged to tolerance.
};

/// Everything a solver carries from one solve to the next (recycled solutions, lagged
/// factors and their age), so that a restored solver continues bit-for-bit
/// (Simulator::checkpoint). A factor is kept as the values of the matrix it factorised
/// (same pattern as the system matrix): factorising the same matrix again gives the same
/// factor, so a restore refactorises instead of storing the factor.
struct LinearSolverState {
  std::string solver_name;           ///< LinearSolver::name() of the solver that saved it.
  Eigen::Index history_rows = 0;     ///< Rows of the recycled-solution basis (free DOFs), or 0.
  int history_cols = 0;              ///< Columns (SolverSettings::recycled_solutions), or 0.
  Eigen::VectorXd history;           ///< The basis, row-major, history_rows x history_cols.
  int history_count = 0;             ///< Valid columns, in [0, history_cols].
  int history_next = 0;              ///< Column the next solution overwrites.
  double key = 0;                    ///< Matrix family of the next solve (step size h, s).
  long clock = 0;                    ///< Solve counter (least-recently-used factor choice).
  /// One lagged factor (warp preconditioner).
  struct Factor {
    bool factored = false;           ///< The factorisation succeeded (else refactorised at next use).
    Eigen::VectorXd matrix_values;   ///< Values of the factorised matrix (system pattern).
    std::vector<Mat3> at_factor;     ///< Node-block rotations at factorisation time.
    /// amg: node-block positions its rigid-body modes were built at (3 per block); empty
    /// for a Cholesky factor.
    Eigen::VectorXd setup_positions;
    Eigen::Index rows = -1;          ///< Rows of the factorised matrix.
    bool stale = true;               ///< Refactorise before the next use.
    int baseline = -1;               ///< Iterations of the first solve with it (-1: none yet).
    double excess = 0;               ///< Iterations beyond `baseline` summed over later solves.
    double key = 0;                  ///< Matrix family (step size h, s).
    long last_used = 0;              ///< Clock of the last use.
    /// A factorisation of `matrix_values` (at `at_factor`) was under way beside the steps
    /// (FirstFactorisation::beside): restarted on restore, it takes over after
    /// `beside_left` more fallback iterations.
    bool beside = false;
    double beside_left = 0;
  };
  std::vector<Factor> factors;       ///< In slot order.
  /// SolverSettings::jacobi_first: still solving with block Jacobi (false once switched to
  /// the factor, or when off), and the iterations summed beyond the break-even so far.
  bool jacobi_first = false;
  double jacobi_first_excess = 0;
};

/// The Cholesky factor a solver last used, for reports and tests.
struct FactorInfo {
  bool factored = false;   ///< A factorisation exists.
  double nonzeros = 0;     ///< Entries of L.
  double flops = 0;        ///< Floating-point operations of one factorisation (CHOLMOD's count; 0 if unknown).
  std::string ordering;    ///< Fill-reducing ordering of the analysis: "amd", "metis", ...
  int solve_threads = 1;   ///< Threads one application of the preconditioner's factor uses.
};

/// Solves A x = b for the engine's SPD matrices. The pattern is analysed once.
class LinearSolver {
 public:
  virtual ~LinearSolver() = default;
  /// Solves with `x` as the initial guess (PCG) or ignoring it (direct).
  virtual SolveStats solve(const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x) = 0;
  /// Another right-hand side with the matrix of the last solve (unchanged since): solvers
  /// that factorise per solve reuse that factorisation.
  virtual SolveStats solve_same_matrix(const SparseMatrix& A, const Eigen::VectorXd& b, Eigen::VectorXd& x) {
    return solve(A, b, x);
  }
  virtual std::string name() const = 0;
  /// The factor of the last solve (solvers without one: factored false).
  virtual FactorInfo factor_info() const { return {}; }
  /// Threads busy with factorisations beside the steps now (FirstFactorisation::beside):
  /// the step leaves them their cores.
  virtual int threads_beside() const { return 0; }
  /// Node blocks of the free DOFs for block preconditioners: rows starts[k] .. starts[k+1]-1
  /// belong to one node. Ignored by solvers that need none.
  virtual void set_blocks(std::vector<int> /*starts*/) {}
  /// Whether `solve` wants the current rotation of each node block (warp preconditioner).
  virtual bool uses_block_rotations() const { return false; }
  /// Whether `solve` wants the current position of each node block (the amg
  /// preconditioner's rigid-body modes).
  virtual bool uses_block_positions() const { return false; }
  /// Current positions of the node blocks, 3 per block in block order, m; called before
  /// `solve` when uses_block_positions(). The solver reads them (only when it rebuilds its
  /// preconditioner) during the next solve, so `positions` must outlive it.
  virtual void set_block_positions(const Eigen::VectorXd& /*positions*/) {}
  /// Current rotation of each node block (same order as the blocks); called before `solve`
  /// when uses_block_rotations().
  virtual void set_block_rotations(const std::vector<Mat3>& /*rotations*/) {}
  /// Where a solve gets the node rotations when it turns to the warp preconditioner without
  /// having been given them (uses_block_rotations() was false before it: a PCG solve that
  /// leaves block Jacobi for the factor, SolverSettings::jacobi_first). The callback brings
  /// them up to date and returns them; it must stay valid while the solver is used.
  virtual void set_block_rotation_source(std::function<const std::vector<Mat3>&()> /*source*/) {}
  /// The matrix changed by more than a step's motion (time step, material, damping):
  /// solvers that reuse a factorisation refresh it at the next solve.
  virtual void invalidate() {}
  /// The state jumped (reset, set_state): forget remembered solutions, so a run from a
  /// state does not depend on what was solved before it.
  virtual void forget_solutions() {}
  /// Whether the next solve starts from the caller's guess as given: true for a PCG solver
  /// with recycled solutions that remembers none yet (its first solve, or the first after
  /// forget_solutions()); then a caller with a better guess than its last solution
  /// (Simulator: the free-flight velocity) pays off. False when the guess is ignored
  /// (direct) or replaced by the projection on remembered solutions.
  virtual bool takes_guess() const { return false; }
  /// The system the matrices come from: a solver that can work from its upper block store
  /// (SparseSystem::has_blocks) reads the blocks while they are current and calls
  /// sync_matrix() before anything that needs the CSR values (a factorisation).
  virtual void set_system(SparseSystem* /*system*/) {}
  /// Whether solve() handles a matrix whose blocks are current (else the caller syncs first).
  virtual bool reads_blocks() const { return false; }
  /// Names the family of the next matrices (the simulator passes the step size h):
  /// solvers that reuse factorisations keep one per family.
  virtual void set_matrix_key(double /*key*/) {}
  /// What the next solves depend on besides their inputs (see LinearSolverState).
  virtual LinearSolverState save_state() const {
    LinearSolverState s;
    s.solver_name = name();
    return s;
  }
  /// Restores save_state()'s result; `pattern` is a matrix with the system's sparsity
  /// pattern (its values are replaced). Refactorises the saved factors from their
  /// matrices. @throws std::invalid_argument if the state belongs to another solver kind
  /// or another system size.
  virtual void load_state(const LinearSolverState& state, const SparseMatrix& pattern);
};

/// Makes the solver for `settings` (validated).
std::unique_ptr<LinearSolver> make_linear_solver(const SolverSettings& settings);

/// Whether the direct solver uses CHOLMOD in this build.
bool direct_solver_uses_cholmod();

}  // namespace fiberfem::core
