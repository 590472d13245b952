// Linear solvers (core/linear_solver.hpp, PHYSICS.md section 5) on the engine's kind of
// system, a box stiffness plus M / h^2 assembled by SparseSystem: residuals measured here as
// |A x - b| / |b| and solutions against a dense Cholesky; warm starts, the iteration cap,
// the exactness of the block-Jacobi and warped-Cholesky preconditioners on matrices built
// so that they are exact, factor reuse and refresh, and settings validation.

#include "core/amg_preconditioner.hpp"
#include "core/box_generator.hpp"
#include "core/element.hpp"
#include "core/linear_solver.hpp"
#include "core/sparse_system.hpp"
#include "test_support.hpp"

#include <Eigen/Dense>

#include <omp.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <random>

namespace core = fiberfem::core;
using core::Mat12;
using core::Mat3;
using core::Vec12;
using core::Vec3;
using fiberfem::testing::expect_invalid;
using fiberfem::testing::random_rotation;

namespace {

struct System {
  core::TetMesh mesh;
  core::SparseSystem sys;
  Eigen::VectorXd b;
};

// A (K + M / h^2) over the free DOFs of a box clamped at x = 0, with a TI material and
// random fibers; `mass_scale` multiplies the mass term to make a second matrix with the
// same pattern.
core::SparseMatrix assemble(core::SparseSystem& sys, const core::TetMesh& mesh, double mass_scale) {
  core::EngineeringConstants c;
  c.E_L = 80e3;
  c.E_T = 16e3;
  c.nu_T = 0.45;
  c.nu_LT = 0.3;
  c.G_L = 6e3;
  const core::Material mat = core::Material::from_engineering(c, 1000);
  const double h = 2e-3;
  sys.zero_matrix();
  Eigen::VectorXd unused = Eigen::VectorXd::Zero(sys.num_dofs());
  sys.assemble([&](int e, Mat12& Ke, Vec12& fe) {
    std::mt19937 rng(static_cast<unsigned>(e));
    std::normal_distribution<double> n(0, 1);
    const Vec3 fiber(n(rng), n(rng), n(rng));
    const Vec12 X = core::gather(mesh.rest_positions(), mesh.tets()[static_cast<size_t>(e)]);
    Ke = core::element_stiffness(X, mat, fiber);
    const double m_node = 0.25 * mat.density_kg_m3() * mesh.rest_volume(e);
    Ke.diagonal().array() += mass_scale * m_node / (h * h);
    fe.setZero();
  }, unused);
  return sys.matrix();
}

System make_system() {
  core::BoxSpec s;
  s.size_m = Vec3(0.06, 0.02, 0.02);
  s.cells = {6, 3, 3};
  core::TetMesh mesh = core::make_box(s);
  std::vector<std::uint8_t> fixed(static_cast<size_t>(3 * mesh.num_nodes()), 0);
  for (int n : mesh.node_set("xmin"))
    for (int c = 0; c < 3; ++c) fixed[static_cast<size_t>(3 * n + c)] = 1;
  core::SparseSystem sys(mesh, fixed);
  assemble(sys, mesh, 1.0);
  std::mt19937 rng(71);
  std::normal_distribution<double> n(0, 1);
  Eigen::VectorXd b(sys.num_free());
  for (Eigen::Index i = 0; i < b.size(); ++i) b(i) = n(rng);
  return System{std::move(mesh), std::move(sys), b};
}

double residual(const core::SparseMatrix& A, const Eigen::VectorXd& b, const Eigen::VectorXd& x) {
  return (b - A * x).norm() / b.norm();
}

Eigen::VectorXd dense_solve(const core::SparseMatrix& A, const Eigen::VectorXd& b) {
  return Eigen::MatrixXd(A).llt().solve(b);
}

core::SolverSettings pcg(core::PreconditionerKind p, double tol = 1e-8, int max_iterations = 2000) {
  core::SolverSettings s;
  s.method = core::LinearSolverKind::pcg;
  s.preconditioner = p;
  s.tolerance = tol;
  s.max_iterations = max_iterations;
  s.jacobi_first = 0;  // the factor from the first solve: the tests below are of the factor
  return s;
}

std::unique_ptr<core::LinearSolver> make(const core::SolverSettings& s, const core::SparseSystem& sys) {
  auto solver = core::make_linear_solver(s);
  solver->set_blocks(sys.node_block_starts());
  return solver;
}

// Q_k, a random rotation per node block, and the block-diagonal W of them (free DOFs).
struct BlockRotations {
  std::vector<Mat3> Q;
  core::SparseMatrix W;
};
BlockRotations random_block_rotations(const std::vector<int>& starts, int num_free, unsigned seed) {
  std::mt19937 rng(seed);
  BlockRotations r;
  std::vector<Eigen::Triplet<double>> w;
  for (size_t k = 0; k + 1 < starts.size(); ++k) {
    r.Q.push_back(random_rotation(rng));
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) w.emplace_back(starts[k] + i, starts[k] + j, r.Q.back()(i, j));
  }
  r.W.resize(num_free, num_free);
  r.W.setFromTriplets(w.begin(), w.end());
  return r;
}

}  // namespace

TEST(LinearSolver, BlockJacobiPcgReachesTheRequestedTolerance) {
  System S = make_system();
  const core::SparseMatrix& A = S.sys.matrix();
  const Eigen::VectorXd x_ref = dense_solve(A, S.b);
  ASSERT_LT(residual(A, S.b, x_ref), 1e-12);
  int previous_iterations = 0;
  for (double tol : {1e-3, 1e-6, 1e-10}) {
    auto solver = make(pcg(core::PreconditionerKind::block_jacobi, tol), S.sys);
    EXPECT_EQ(solver->name(), "pcg/block_jacobi");
    EXPECT_FALSE(solver->uses_block_rotations());
    Eigen::VectorXd x;
    const core::SolveStats st = solver->solve(A, S.b, x);
    const double r = residual(A, S.b, x);
    EXPECT_TRUE(st.ok) << "tol " << tol;
    EXPECT_LE(r, 2 * tol) << "tol " << tol;
    EXPECT_NEAR(st.relative_residual, r, tol) << "reported residual off";
    EXPECT_EQ(st.factorizations, 0);
    EXPECT_GT(st.iterations, previous_iterations) << "a tighter tolerance must take more iterations";
    previous_iterations = st.iterations;
    // The error is bounded by the residual times the condition number (< 1e4 here).
    EXPECT_LT((x - x_ref).norm(), 1e4 * tol * x_ref.norm());
  }
}

TEST(LinearSolver, CholeskyPcgFactorisesOnceAndReusesTheFactor) {
  System S = make_system();
  auto solver = make(pcg(core::PreconditionerKind::cholesky, 1e-9), S.sys);
  EXPECT_EQ(solver->name(), "pcg/cholesky");
  EXPECT_TRUE(solver->uses_block_rotations());
  Eigen::VectorXd x;
  core::SolveStats st = solver->solve(S.sys.matrix(), S.b, x);
  EXPECT_TRUE(st.ok);
  EXPECT_EQ(st.factorizations, 1);
  EXPECT_LE(st.iterations, 2) << "an exact preconditioner converges at once";
  EXPECT_LE(residual(S.sys.matrix(), S.b, x), 2e-9);
  // A nearby matrix with the same pattern: the old factor is a good preconditioner.
  const core::SparseMatrix A2 = assemble(S.sys, S.mesh, 1.05);
  x.setZero();
  st = solver->solve(A2, S.b, x);
  EXPECT_TRUE(st.ok);
  EXPECT_EQ(st.factorizations, 0);
  EXPECT_GT(st.iterations, 1);
  EXPECT_LE(st.iterations, 8);
  EXPECT_LE(residual(A2, S.b, x), 2e-9);
  EXPECT_LT((x - dense_solve(A2, S.b)).norm(), 1e-6 * x.norm());
  // invalidate() forces a refactorisation at the next solve.
  solver->invalidate();
  x.setZero();
  st = solver->solve(A2, S.b, x);
  EXPECT_EQ(st.factorizations, 1);
  EXPECT_LE(st.iterations, 2);
  EXPECT_LE(residual(A2, S.b, x), 2e-9);
}

// One factor per matrix family (the simulator's step size): alternating between two very
// different matrices, each with its own key, factorises each once; without keys every
// switch refactorises. Each answer is checked against a dense solve.
TEST(LinearSolver, CholeskyPcgKeepsOneFactorPerMatrixKey) {
  System S = make_system();
  const core::SparseMatrix A1 = S.sys.matrix();
  const core::SparseMatrix A2 = assemble(S.sys, S.mesh, 0.25);  // like h doubled
  int iterations[2] = {0, 0};
  for (bool keyed : {true, false}) {
    auto solver = make(pcg(core::PreconditionerKind::cholesky, 1e-9), S.sys);
    int factorizations = 0;
    for (int round = 0; round < 3; ++round)
      for (int which = 0; which < 2; ++which) {
        const core::SparseMatrix& A = which == 0 ? A1 : A2;
        if (keyed) solver->set_matrix_key(which == 0 ? 1.0 / 60 : 1.0 / 120);
        Eigen::VectorXd x = Eigen::VectorXd::Zero(S.b.size());
        const core::SolveStats st = solver->solve(A, S.b, x);
        ASSERT_TRUE(st.ok);
        factorizations += st.factorizations;
        iterations[keyed ? 0 : 1] += st.iterations;
        if (keyed) {
          EXPECT_LE(st.iterations, 2) << "each matrix has its own exact factor";
        }
        EXPECT_LT((x - dense_solve(A, S.b)).norm(), 1e-6 * x.norm());
      }
    if (keyed) {
      EXPECT_EQ(factorizations, 2);
    }
  }
  EXPECT_GT(iterations[1], 2 * iterations[0]) << "keyed " << iterations[0] << ", unkeyed " << iterations[1];
}

// The factors of a solver's matrix families (keys) share one symbolic analysis where their
// matrices have one pattern, and each is still its own matrix's exact factor: the solve of
// the second family is the same, bit for bit, as a solver's that factorised that matrix
// alone (the ordering depends on the pattern only). A family whose matrix has another
// pattern of the same size (one more pair of entries) is analysed afresh and solved exactly.
TEST(LinearSolver, CholeskyPcgFamiliesShareTheAnalysisOfOnePattern) {
  System S = make_system();
  const core::SparseMatrix A1 = S.sys.matrix();
  const core::SparseMatrix A2 = assemble(S.sys, S.mesh, 0.25);  // like h doubled
  std::vector<Eigen::Triplet<double>> t;
  for (int r = 0; r < A2.outerSize(); ++r)
    for (core::SparseMatrix::InnerIterator it(A2, r); it; ++it) t.emplace_back(r, static_cast<int>(it.col()), it.value());
  const int n = static_cast<int>(A2.rows());
  ASSERT_EQ(A2.coeff(0, n - 1), 0.0) << "the corner must lie outside the pattern";
  const double corner = 1e-3 * A2.coeff(0, 0);
  t.emplace_back(0, n - 1, corner);
  t.emplace_back(n - 1, 0, corner);
  core::SparseMatrix B(n, n);
  B.setFromTriplets(t.begin(), t.end());

  core::SolverSettings s = pcg(core::PreconditionerKind::cholesky, 1e-9);
  s.warm_start = false;  // every solve from zero: the same factor, the same iterates
  auto solver = make(s, S.sys);
  const auto solve = [&](core::LinearSolver& sv, double key, const core::SparseMatrix& A, Eigen::VectorXd& x) {
    sv.set_matrix_key(key);
    const core::SolveStats st = sv.solve(A, S.b, x);
    EXPECT_TRUE(st.ok);
    EXPECT_EQ(st.factorizations, 1);
    EXPECT_LE(st.iterations, 2) << "an exact factor (key " << key << ")";
    const Eigen::VectorXd ref = dense_solve(A, S.b);
    EXPECT_LT((x - ref).norm(), 1e-8 * ref.norm());
  };
  Eigen::VectorXd x1, x2, x2_alone, xb;
  solve(*solver, 1.0 / 60, A1, x1);
  const core::FactorInfo first = solver->factor_info();
  solve(*solver, 1.0 / 120, A2, x2);
  const core::FactorInfo second = solver->factor_info();
  auto alone = make(s, S.sys);
  solve(*alone, 1.0 / 120, A2, x2_alone);
  EXPECT_EQ(x2, x2_alone);
  EXPECT_EQ(second.nonzeros, alone->factor_info().nonzeros);
  EXPECT_EQ(second.nonzeros, first.nonzeros);
  EXPECT_EQ(second.ordering, first.ordering);
  // A third family (replacing a slot) of another pattern: the same as a solver's of B alone.
  solve(*solver, 1.0 / 240, B, xb);
  Eigen::VectorXd xb_alone;
  auto alone_b = make(s, S.sys);
  solve(*alone_b, 1.0 / 240, B, xb_alone);
  EXPECT_EQ(xb, xb_alone);
}

// A solve that needs more than refresh_iterations marks the factor stale: the next solve
// refactorises; and a solve that does not converge with the old factor refactorises and
// solves again at once, reporting the iterations of both attempts.
TEST(LinearSolver, CholeskyPcgRefreshesAStaleFactor) {
  System S = make_system();
  const core::SparseMatrix A1 = S.sys.matrix();
  const core::SparseMatrix A3 = assemble(S.sys, S.mesh, 3.0);
  {
    core::SolverSettings s = pcg(core::PreconditionerKind::cholesky, 1e-9);
    s.refresh_iterations = 2;
    auto solver = make(s, S.sys);
    Eigen::VectorXd x;
    ASSERT_EQ(solver->solve(A1, S.b, x).factorizations, 1);
    x.setZero();
    core::SolveStats st = solver->solve(A3, S.b, x);
    EXPECT_TRUE(st.ok);
    EXPECT_EQ(st.factorizations, 0);
    ASSERT_GT(st.iterations, 2) << "the test needs A3 far enough from A1";
    EXPECT_LE(residual(A3, S.b, x), 2e-9);
    x.setZero();
    st = solver->solve(A3, S.b, x);
    EXPECT_EQ(st.factorizations, 1) << "stale factor not refreshed";
    EXPECT_LE(st.iterations, 2);
  }
  {
    core::SolverSettings s = pcg(core::PreconditionerKind::cholesky, 1e-12, 3);
    s.single_precision_preconditioner = false;  // exact with a fresh factor (see below for float)
    auto solver = make(s, S.sys);
    Eigen::VectorXd x;
    ASSERT_EQ(solver->solve(A1, S.b, x).factorizations, 1);
    x.setZero();
    const core::SolveStats st = solver->solve(A3, S.b, x);
    EXPECT_TRUE(st.ok);
    EXPECT_EQ(st.factorizations, 1);
    // Eigen counts a solve that converges on its k-th update as k - 1 iterations, so the
    // exact second attempt adds 0 or 1 to the 3 of the capped first attempt.
    EXPECT_GE(st.iterations, 3) << "the first, capped attempt counts too";
    EXPECT_LE(st.iterations, 3 + 1);
    EXPECT_LE(residual(A3, S.b, x), 2e-12);
  }
}

// refresh_budget: the factor is refreshed once the iterations it has cost beyond its first
// solve add up to budget x (flops of a factorisation / 4 nnz(L)), both read off
// factor_info(); with budget 0 only refresh_iterations refreshes (here never: it is
// set out of reach). The extra iterations come from solving with A3 on A1's factor.
TEST(LinearSolver, CholeskyPcgRefreshesWhenExtraIterationsCostAFactorisation) {
  System S = make_system();
  const core::SparseMatrix A1 = S.sys.matrix();
  const core::SparseMatrix A3 = assemble(S.sys, S.mesh, 3.0);
  for (double budget : {3.0, 0.0}) {
    core::SolverSettings s = pcg(core::PreconditionerKind::cholesky, 1e-9);
    s.refresh_iterations = 1000;
    s.refresh_budget = budget;
    s.recycled_solutions = 0;
    auto solver = make(s, S.sys);
    Eigen::VectorXd x = Eigen::VectorXd::Zero(S.sys.num_free());
    core::SolveStats st = solver->solve(A1, S.b, x);
    ASSERT_EQ(st.factorizations, 1);
    const int baseline = st.iterations;
    const core::FactorInfo info = solver->factor_info();
    ASSERT_TRUE(info.factored);
    ASSERT_GT(info.flops, 0);
    const double allowed = budget * info.flops / (4 * info.nonzeros);
    double excess = 0;
    int refreshed_at = -1;
    for (int k = 0; k < 200 && refreshed_at < 0; ++k) {
      x.setZero();
      st = solver->solve(A3, S.b, x);
      ASSERT_TRUE(st.ok);
      EXPECT_LE(residual(A3, S.b, x), 2e-9);
      if (st.factorizations > 0) {
        ADD_FAILURE() << "refreshed at solve " << k << " with an excess of " << excess << ", budget " << allowed;
        refreshed_at = k;
        break;
      }
      ASSERT_GT(st.iterations, baseline) << "the test needs A3 far enough from A1";
      excess += st.iterations - baseline;
      // Stale exactly when the excess passed the budget: the next solve refactorises.
      if (budget > 0 && excess > allowed) {
        x.setZero();
        EXPECT_EQ(solver->solve(A3, S.b, x).factorizations, 1) << "after " << k + 1 << " solves, excess " << excess;
        refreshed_at = k + 1;
      }
    }
    if (budget > 0) {
      EXPECT_GE(refreshed_at, 2) << "the budget should take a few solves to use up: " << allowed;
    } else {
      EXPECT_EQ(refreshed_at, -1) << "budget 0 refreshed";
    }
  }
}

// The single-precision copy of the factor: with a fresh factor each PCG iteration cuts the
// residual by about float round-off (1e-7 relative), so 1e-12 takes two iterations where
// the double factor takes one; the solution is the same to the tolerance.
TEST(LinearSolver, SinglePrecisionPreconditionerIsAccurateToFloatRoundOff) {
  if (!core::has_cholmod()) GTEST_SKIP() << "the single-precision copy needs CHOLMOD's supernodal factor";
  System S = make_system();
  const core::SparseMatrix& A = S.sys.matrix();
  const Eigen::VectorXd x_ref = dense_solve(A, S.b);
  for (bool single : {true, false}) {
    core::SolverSettings s = pcg(core::PreconditionerKind::cholesky, 1e-12);
    s.single_precision_preconditioner = single;
    s.recycled_solutions = 0;
    auto solver = make(s, S.sys);
    Eigen::VectorXd x;
    const core::SolveStats st = solver->solve(A, S.b, x);
    EXPECT_TRUE(st.ok);
    EXPECT_EQ(st.factorizations, 1);
    EXPECT_EQ(st.iterations, single ? 2 : 1) << (single ? "float" : "double");
    EXPECT_LE(residual(A, S.b, x), 1e-12);
    EXPECT_LE((x - x_ref).norm(), 1e-9 * x_ref.norm());
  }
}

// A block (a 9x9x9-cell cube clamped on one face) orders by nested dissection, and its
// elimination tree splits in two: one application of the single-precision factor then
// runs on two threads, each through its own subtrees, with the separators above them on
// one. Same contract as the serial substitution: with a fresh factor PCG reaches 1e-12 in
// two iterations, and the solution is CHOLMOD's double-precision direct solve; on one
// thread (the serial substitution) the iterations and the solution are the same.
TEST(LinearSolver, SplitTreeSubstitutionOnTwoThreadsMatchesTheDirectSolve) {
  if (!core::has_cholmod()) GTEST_SKIP() << "the single-precision copy needs CHOLMOD's supernodal factor";
  core::BoxSpec spec;
  spec.size_m = Vec3(0.03, 0.03, 0.03);
  spec.cells = {9, 9, 9};
  const core::TetMesh mesh = core::make_box(spec);
  std::vector<std::uint8_t> fixed(static_cast<size_t>(3 * mesh.num_nodes()), 0);
  for (int n : mesh.node_set("xmin"))
    for (int c = 0; c < 3; ++c) fixed[static_cast<size_t>(3 * n + c)] = 1;
  core::SparseSystem sys(mesh, fixed);
  const core::SparseMatrix A = assemble(sys, mesh, 1.0);
  std::mt19937 rng(5);
  std::normal_distribution<double> normal(0, 1);
  Eigen::VectorXd b(sys.num_free());
  for (Eigen::Index i = 0; i < b.size(); ++i) b(i) = normal(rng);

  core::SolverSettings direct;
  direct.method = core::LinearSolverKind::direct;
  auto reference = make(direct, sys);
  Eigen::VectorXd x_ref;
  ASSERT_TRUE(reference->solve(A, b, x_ref).ok);
  EXPECT_EQ(reference->factor_info().ordering, "metis");

  const int threads_before = omp_get_max_threads();
  for (int threads : {2, 1}) {
    omp_set_num_threads(threads);
    core::SolverSettings s = pcg(core::PreconditionerKind::cholesky, 1e-12);
    s.recycled_solutions = 0;
    auto solver = make(s, sys);
    Eigen::VectorXd x;
    const core::SolveStats st = solver->solve(A, b, x);
    const core::FactorInfo info = solver->factor_info();
    EXPECT_TRUE(info.factored);
    EXPECT_EQ(info.solve_threads, threads);
    EXPECT_TRUE(st.ok);
    EXPECT_EQ(st.iterations, 2) << threads << " thread(s)";
    EXPECT_LE(residual(A, b, x), 1e-12);
    EXPECT_LE((x - x_ref).norm(), 1e-10 * x_ref.norm()) << threads << " thread(s)";
  }
  omp_set_num_threads(threads_before);
}

// W A0 W^T with W = blockdiag(Q_k), one rotation per node: the warped preconditioner
// W A0^-1 W^T is its exact inverse, so PCG converges at once without refactorising.
TEST(LinearSolver, WarpedCholeskyIsExactForRotatedMatrices) {
  System S = make_system();
  const core::SparseMatrix& A0 = S.sys.matrix();
  const std::vector<int> starts = S.sys.node_block_starts();
  const size_t nb = starts.size() - 1;
  for (size_t k = 0; k < nb; ++k) ASSERT_EQ(starts[k + 1] - starts[k], 3) << "test assumes whole free nodes";
  auto solver = make(pcg(core::PreconditionerKind::cholesky, 1e-10), S.sys);
  solver->set_block_rotations(std::vector<Mat3>(nb, Mat3::Identity()));
  Eigen::VectorXd x;
  ASSERT_EQ(solver->solve(A0, S.b, x).factorizations, 1);

  const auto [Q, W] = random_block_rotations(starts, S.sys.num_free(), 72);
  const core::SparseMatrix A1 = W * A0 * core::SparseMatrix(W.transpose());
  solver->set_block_rotations(Q);
  x.setZero();
  const core::SolveStats st = solver->solve(A1, S.b, x);
  EXPECT_TRUE(st.ok);
  EXPECT_EQ(st.factorizations, 0);
  EXPECT_LE(st.iterations, 2);
  EXPECT_LE(residual(A1, S.b, x), 2e-10);
  // Without telling it about the rotations the old factor is a poor preconditioner.
  auto unwarped = make(pcg(core::PreconditionerKind::cholesky, 1e-10), S.sys);
  unwarped->set_block_rotations(std::vector<Mat3>(nb, Mat3::Identity()));
  ASSERT_EQ(unwarped->solve(A0, S.b, x).factorizations, 1);
  x.setZero();
  const core::SolveStats st2 = unwarped->solve(A1, S.b, x);
  EXPECT_GT(st2.iterations, 5);
}

// On a block-diagonal SPD matrix whose blocks are the node blocks (sizes 3, 2 and 1), the
// block-Jacobi preconditioner is the exact inverse: one iteration.
TEST(LinearSolver, BlockJacobiIsExactOnBlockDiagonalMatrices) {
  const std::vector<int> starts{0, 3, 5, 6, 9, 11};
  const int n = starts.back();
  std::mt19937 rng(73);
  std::normal_distribution<double> g(0, 1);
  Eigen::MatrixXd D = Eigen::MatrixXd::Zero(n, n);
  for (size_t k = 0; k + 1 < starts.size(); ++k) {
    const int r0 = starts[k], sz = starts[k + 1] - starts[k];
    Eigen::MatrixXd B(sz, sz);
    for (int i = 0; i < sz * sz; ++i) B(i) = g(rng);
    D.block(r0, r0, sz, sz) = B * B.transpose() + 0.5 * Eigen::MatrixXd::Identity(sz, sz);
  }
  const core::SparseMatrix A = D.sparseView();
  Eigen::VectorXd b(n);
  for (int i = 0; i < n; ++i) b(i) = g(rng);
  auto solver = core::make_linear_solver(pcg(core::PreconditionerKind::block_jacobi, 1e-12));
  solver->set_blocks(starts);
  Eigen::VectorXd x;
  core::SolveStats st = solver->solve(A, b, x);
  EXPECT_TRUE(st.ok);
  EXPECT_LE(st.iterations, 1);  // one update (Eigen reports a first-update convergence as 0)
  EXPECT_LT((x - D.llt().solve(b)).norm(), 1e-12 * x.norm());
  // Scalar Jacobi (no blocks given) is not exact here.
  auto scalar = core::make_linear_solver(pcg(core::PreconditionerKind::block_jacobi, 1e-12));
  x.resize(0);
  st = scalar->solve(A, b, x);
  EXPECT_TRUE(st.ok);
  EXPECT_GT(st.iterations, 2);
}

TEST(LinearSolver, WarmStartFromTheSolutionTakesNoIterations) {
  System S = make_system();
  const core::SparseMatrix& A = S.sys.matrix();
  const Eigen::VectorXd x_ref = dense_solve(A, S.b);
  for (auto p : {core::PreconditionerKind::block_jacobi, core::PreconditionerKind::cholesky}) {
    auto solver = make(pcg(p, 1e-8), S.sys);
    Eigen::VectorXd x = x_ref;
    const core::SolveStats st = solver->solve(A, S.b, x);
    EXPECT_TRUE(st.ok) << core::to_string(p);
    EXPECT_LE(st.iterations, 1) << core::to_string(p);
    EXPECT_LE(residual(A, S.b, x), 1e-8);
    // With warm_start off the guess is ignored: same work as from zero.
    core::SolverSettings cold = pcg(p, 1e-8);
    cold.warm_start = false;
    auto from_zero = make(cold, S.sys);
    Eigen::VectorXd z;
    const int zero_iterations = make(pcg(p, 1e-8), S.sys)->solve(A, S.b, z).iterations;
    x = x_ref;
    EXPECT_EQ(from_zero->solve(A, S.b, x).iterations, zero_iterations) << core::to_string(p);
  }
}

// The recycled warm start is the Galerkin projection onto the last solutions: a right-hand
// side that is a combination of earlier ones has its solution in their span, so the guess
// is already the solution (up to round-off); without recycling, or after
// forget_solutions(), PCG starts from the extrapolated guess and iterates.
TEST(LinearSolver, RecycledSolutionsMakeTheGuessExactInTheirSpan) {
  System S = make_system();
  const core::SparseMatrix& A = S.sys.matrix();
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0, 1);
  Eigen::VectorXd b2(S.b.size());
  for (Eigen::Index i = 0; i < b2.size(); ++i) b2(i) = n(rng);
  const Eigen::VectorXd b3 = 0.3 * S.b - 2.0 * b2;
  auto run = [&](int recycled, bool forget) {
    core::SolverSettings st = pcg(core::PreconditionerKind::block_jacobi, 1e-10);
    st.recycled_solutions = recycled;
    auto solver = make(st, S.sys);
    Eigen::VectorXd x;
    EXPECT_TRUE(solver->solve(A, S.b, x).ok);
    EXPECT_TRUE(solver->solve(A, b2, x).ok);
    if (forget) solver->forget_solutions();
    x.setZero();
    const core::SolveStats third = solver->solve(A, b3, x);
    EXPECT_TRUE(third.ok);
    EXPECT_LE(residual(A, b3, x), 1e-10);
    EXPECT_LE((x - dense_solve(A, b3)).norm(), 1e-7 * x.norm());
    return third.iterations;
  };
  const int recycled = run(8, false), plain = run(0, false), forgotten = run(8, true);
  EXPECT_LE(recycled, 1);
  EXPECT_GT(plain, 20);
  EXPECT_EQ(forgotten, plain);
}

TEST(LinearSolver, IterationCapIsRespectedAndReportedNotOk) {
  System S = make_system();
  const core::SparseMatrix& A = S.sys.matrix();
  for (int cap : {1, 3, 10}) {
    auto solver = make(pcg(core::PreconditionerKind::block_jacobi, 1e-12, cap), S.sys);
    Eigen::VectorXd x;
    const core::SolveStats st = solver->solve(A, S.b, x);
    EXPECT_EQ(st.iterations, cap);
    EXPECT_FALSE(st.ok);
    EXPECT_TRUE(x.allFinite());
    EXPECT_GT(st.relative_residual, 1e-12);
    EXPECT_GT(residual(A, S.b, x), 1e-12);
    EXPECT_LT(residual(A, S.b, x), 1.0) << "partial progress expected";
  }
}

TEST(LinearSolver, DirectSolverIsExactAndReusesTheAnalysis) {
  System S = make_system();
  core::SolverSettings s;
  s.method = core::LinearSolverKind::direct;
  auto solver = make(s, S.sys);
  EXPECT_EQ(solver->name(), core::direct_solver_uses_cholmod() ? "cholmod" : "llt");
  Eigen::VectorXd x = Eigen::VectorXd::Constant(S.sys.num_free(), 1e30);  // ignored
  core::SolveStats st = solver->solve(S.sys.matrix(), S.b, x);
  EXPECT_TRUE(st.ok);
  EXPECT_EQ(st.iterations, 1);
  EXPECT_EQ(st.factorizations, 1);
  EXPECT_LT(residual(S.sys.matrix(), S.b, x), 1e-12);
  EXPECT_NEAR(st.relative_residual, residual(S.sys.matrix(), S.b, x), 1e-14);
  EXPECT_LT((x - dense_solve(S.sys.matrix(), S.b)).norm(), 1e-10 * x.norm());
  // Same pattern, new values: refactorised, still exact.
  const core::SparseMatrix A2 = assemble(S.sys, S.mesh, 7.0);
  st = solver->solve(A2, S.b, x);
  EXPECT_TRUE(st.ok);
  EXPECT_LT(residual(A2, S.b, x), 1e-12);
  EXPECT_LT((x - dense_solve(A2, S.b)).norm(), 1e-10 * x.norm());
}

// Debian's CHOLMOD asks for OpenMP teams of 4 threads (CHOLMOD_OMP_NUM_THREADS) in its
// factorisation; the factor caps them at the engine's thread count. Counted as the threads
// of this process (Linux: /proc/self/task) before and after a factorisation, with the
// engine's two-thread pool already started.
TEST(LinearSolver, FactorisationStartsNoThreadsBeyondTheEngines) {
  if (!core::direct_solver_uses_cholmod()) GTEST_SKIP() << "built without CHOLMOD";
  const auto threads = [] {
    int n = 0;
    for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator("/proc/self/task")) ++n;
    return n;
  };
  omp_set_num_threads(2);
  int team = 0;
#pragma omp parallel
  {
#pragma omp atomic
    ++team;
  }
  ASSERT_EQ(team, 2);
  const int before = threads();
  System S = make_system();
  ASSERT_GT(S.sys.num_free(), 128);  // CHOLMOD's loops go parallel above 128 columns
  core::SolverSettings s;
  s.method = core::LinearSolverKind::direct;
  auto solver = make(s, S.sys);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(S.sys.num_free());
  ASSERT_TRUE(solver->solve(S.sys.matrix(), S.b, x).ok);
  EXPECT_LT(residual(S.sys.matrix(), S.b, x), 1e-12);
  EXPECT_EQ(threads(), before);
}

TEST(LinearSolver, IndefiniteMatrixIsAReportedFailureNotAnException) {
  System S = make_system();
  const core::SparseMatrix negative = -S.sys.matrix();
  core::SolverSettings s;
  s.method = core::LinearSolverKind::direct;
  Eigen::VectorXd x;
  core::SolveStats st;
  EXPECT_NO_THROW(st = make(s, S.sys)->solve(negative, S.b, x));
  EXPECT_FALSE(st.ok);
  EXPECT_FALSE(std::isfinite(st.relative_residual));
  EXPECT_NO_THROW(st = make(pcg(core::PreconditionerKind::cholesky), S.sys)->solve(negative, S.b, x));
  EXPECT_FALSE(st.ok);
}

TEST(LinearSolver, ZeroRightHandSideGivesZero) {
  System S = make_system();
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(S.sys.num_free());
  core::SolverSettings direct;
  direct.method = core::LinearSolverKind::direct;
  for (const core::SolverSettings& s :
       {pcg(core::PreconditionerKind::block_jacobi), pcg(core::PreconditionerKind::cholesky), direct}) {
    Eigen::VectorXd x;
    const core::SolveStats st = make(s, S.sys)->solve(S.sys.matrix(), zero, x);
    EXPECT_TRUE(st.ok);
    EXPECT_EQ(x.size(), zero.size());
    EXPECT_EQ(x.norm(), 0.0);
  }
}

TEST(SolverSettings, DefaultsAreValid) {
  const core::SolverSettings s;
  EXPECT_NO_THROW(s.validate());
  EXPECT_EQ(s.method, core::LinearSolverKind::pcg);
  EXPECT_EQ(s.preconditioner, core::PreconditionerKind::cholesky);
  EXPECT_STREQ(core::to_string(core::PreconditionerKind::cholesky), "cholesky");
  EXPECT_STREQ(core::to_string(core::PreconditionerKind::block_jacobi), "block_jacobi");
}

TEST(SolverSettings, ValidateNamesTheField) {
  auto with = [](auto change) {
    core::SolverSettings s;
    change(s);
    return s;
  };
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  const std::vector<std::pair<core::SolverSettings, const char*>> bad{
      {with([](auto& s) { s.tolerance = 0; }), "tolerance"},
      {with([](auto& s) { s.tolerance = 1; }), "tolerance"},
      {with([](auto& s) { s.tolerance = -1e-6; }), "tolerance"},
      {with([&](auto& s) { s.tolerance = nan; }), "tolerance"},
      {with([](auto& s) { s.max_iterations = 0; }), "max_iterations"},
      {with([](auto& s) { s.refresh_iterations = 0; }), "refresh_iterations"},
      {with([](auto& s) { s.refresh_budget = -1; }), "refresh_budget"},
      {with([](auto& s) { s.refresh_budget = std::numeric_limits<double>::infinity(); }), "refresh_budget"},
      {with([](auto& s) { s.failure_residual = 0; }), "failure_residual"},
      {with([&](auto& s) { s.failure_residual = inf; }), "failure_residual"},
      {with([&](auto& s) { s.failure_residual = nan; }), "failure_residual"},
      {with([](auto& s) { s.recycled_solutions = -1; }), "recycled_solutions"},
      {with([](auto& s) { s.recycled_solutions = 65; }), "recycled_solutions"},
      {with([](auto& s) { s.jacobi_first = -2; }), "jacobi_first"},
  };
  for (const auto& [s, field] : bad) {
    expect_invalid([&] { s.validate(); }, {"solver", field});
    expect_invalid([&] { core::make_linear_solver(s); }, {field});
  }
}

// ------------------------------------------------------------------------------ amg

namespace {

// A stiff box (the mass term a thousandth of the test system's: K dominates, as in the
// engine's steps at large h c / dx), clamped at x = 0, with its free nodes' positions.
struct StiffBox {
  core::TetMesh mesh;
  core::SparseSystem sys;
  Eigen::VectorXd positions;  // 3 per free node, block order
  Eigen::VectorXd b;
};

StiffBox make_stiff_box(std::array<int, 3> cells) {
  core::BoxSpec s;
  s.size_m = Vec3(0.1, 0.02, 0.02);
  s.cells = cells;
  core::TetMesh mesh = core::make_box(s);
  std::vector<std::uint8_t> fixed(static_cast<size_t>(3 * mesh.num_nodes()), 0);
  for (int n : mesh.node_set("xmin"))
    for (int c = 0; c < 3; ++c) fixed[static_cast<size_t>(3 * n + c)] = 1;
  core::SparseSystem sys(mesh, fixed);
  assemble(sys, mesh, 1e-3);
  Eigen::VectorXd positions(sys.num_free());
  for (int n = 0; n < mesh.num_nodes(); ++n) {
    const int f = sys.free_index()[static_cast<size_t>(3 * n)];
    if (f >= 0) positions.segment<3>(f) = mesh.rest_positions().col(n);
  }
  std::mt19937 rng(91);
  std::normal_distribution<double> nd(0, 1);
  Eigen::VectorXd b(sys.num_free());
  for (Eigen::Index i = 0; i < b.size(); ++i) b(i) = nd(rng);
  return StiffBox{std::move(mesh), std::move(sys), positions, b};
}

std::unique_ptr<core::LinearSolver> make_amg(const StiffBox& S, double tol, const std::vector<Mat3>& rotations) {
  auto solver = make(pcg(core::PreconditionerKind::amg, tol), S.sys);
  EXPECT_TRUE(solver->uses_block_rotations());
  EXPECT_TRUE(solver->uses_block_positions());
  solver->set_block_rotations(rotations);
  solver->set_block_positions(S.positions);
  return solver;
}

}  // namespace

// The amg preconditioner against independent references: the solution of the direct
// (CHOLMOD) solver, and block Jacobi's iteration count on the same stiff system. A
// multigrid with the rigid-body modes needs a few tens of iterations where block Jacobi
// needs hundreds; its hierarchy has more than one level.
TEST(LinearSolver, AmgPcgMatchesTheDirectSolveInFewIterations) {
  if (!core::has_amg()) GTEST_SKIP() << "built without AMGCL";
  const StiffBox S = make_stiff_box({30, 6, 6});
  const core::SparseMatrix& A = S.sys.matrix();
  const size_t nb = S.sys.node_block_starts().size() - 1;
  core::SolverSettings direct;
  direct.method = core::LinearSolverKind::direct;
  Eigen::VectorXd x_ref;
  ASSERT_TRUE(core::make_linear_solver(direct)->solve(A, S.b, x_ref).ok);

  auto amg = make_amg(S, 1e-10, std::vector<Mat3>(nb, Mat3::Identity()));
  EXPECT_EQ(amg->name(), "pcg/amg");
  Eigen::VectorXd x;
  const core::SolveStats st = amg->solve(A, S.b, x);
  ASSERT_TRUE(st.ok);
  EXPECT_EQ(st.factorizations, 1) << "one hierarchy setup";
  EXPECT_EQ(amg->factor_info().ordering, "amg");
  EXPECT_LE(residual(A, S.b, x), 2e-10);
  EXPECT_LT((x - x_ref).norm(), 1e-6 * x_ref.norm());

  Eigen::VectorXd xj;
  const core::SolveStats jacobi = make(pcg(core::PreconditionerKind::block_jacobi, 1e-10, 20000), S.sys)->solve(A, S.b, xj);
  ASSERT_TRUE(jacobi.ok);
  EXPECT_LT(4 * st.iterations, jacobi.iterations) << "amg " << st.iterations << ", block Jacobi " << jacobi.iterations;
  EXPECT_LE(st.iterations, 60);

  core::AmgHierarchy h;
  ASSERT_TRUE(h.build(A, S.positions));
  EXPECT_GE(h.levels(), 2);
  EXPECT_GT(h.operator_complexity(), 1.0);
  EXPECT_LT(h.operator_complexity(), 3.0);
  // Sizes that do not make node blocks are refused, not crashed on.
  EXPECT_FALSE(h.build(A, Eigen::VectorXd::Zero(3)));
  EXPECT_FALSE(h.ok());
}

// Warped as the Cholesky factor: for A1 = W A0 W^T (each node block turned by Q_k) the
// hierarchy of A0 warped by Q is exactly the hierarchy of A1, so PCG on A1 takes the
// iterations of PCG on A0 with the rotated right-hand side W^T b; without the warp the old
// hierarchy needs more.
TEST(LinearSolver, WarpedAmgIsExactForRotatedMatrices) {
  if (!core::has_amg()) GTEST_SKIP() << "built without AMGCL";
  const StiffBox S = make_stiff_box({20, 4, 4});
  const core::SparseMatrix& A0 = S.sys.matrix();
  const std::vector<int> starts = S.sys.node_block_starts();
  const size_t nb = starts.size() - 1;
  const auto [Q, W] = random_block_rotations(starts, S.sys.num_free(), 92);
  const core::SparseMatrix A1 = W * A0 * core::SparseMatrix(W.transpose());
  const Eigen::VectorXd b0 = W.transpose() * S.b;

  core::SolverSettings settings = pcg(core::PreconditionerKind::amg, 1e-8);
  settings.warm_start = false;
  auto on_a0 = core::make_linear_solver(settings);
  on_a0->set_blocks(starts);
  on_a0->set_block_rotations(std::vector<Mat3>(nb, Mat3::Identity()));
  on_a0->set_block_positions(S.positions);
  Eigen::VectorXd x0;
  const core::SolveStats reference = on_a0->solve(A0, b0, x0);
  ASSERT_TRUE(reference.ok);

  auto warped = core::make_linear_solver(settings);
  warped->set_blocks(starts);
  warped->set_block_rotations(std::vector<Mat3>(nb, Mat3::Identity()));
  warped->set_block_positions(S.positions);
  Eigen::VectorXd x;
  ASSERT_EQ(warped->solve(A0, S.b, x).factorizations, 1);
  warped->set_block_rotations(Q);
  x.setZero();
  const core::SolveStats st = warped->solve(A1, S.b, x);
  ASSERT_TRUE(st.ok);
  EXPECT_EQ(st.factorizations, 0) << "the hierarchy of A0 is reused";
  EXPECT_NEAR(st.iterations, reference.iterations, 1);
  EXPECT_LE(residual(A1, S.b, x), 2e-8);
  EXPECT_LT((x - W * x0).norm(), 1e-5 * x.norm()) << "the solution is the rotated one";

  auto unwarped = core::make_linear_solver(settings);
  unwarped->set_blocks(starts);
  unwarped->set_block_rotations(std::vector<Mat3>(nb, Mat3::Identity()));
  unwarped->set_block_positions(S.positions);
  ASSERT_EQ(unwarped->solve(A0, S.b, x).factorizations, 1);
  x.setZero();
  const core::SolveStats st2 = unwarped->solve(A1, S.b, x);
  EXPECT_GT(st2.iterations, st.iterations + 5);
}

TEST(SolverSettings, AmgIsRefusedOnlyWithoutAmgcl) {
  core::SolverSettings s;
  s.preconditioner = core::PreconditionerKind::amg;
  EXPECT_STREQ(core::to_string(s.preconditioner), "amg");
  if (core::has_amg())
    EXPECT_NO_THROW(s.validate());
  else
    expect_invalid([&] { s.validate(); }, {"amg", "AMGCL"});
}

// SolverSettings::jacobi_first on a system whose mass dominates (a small time step: the
// velocity system of a soft body, where block Jacobi converges in a few iterations): the
// solves stay on block Jacobi, no factor is made, and each answer is the dense solve's to
// the tolerance. With it off the first solve factorises.
TEST(LinearSolver, JacobiFirstKeepsBlockJacobiWhileItIsCheaperThanAFactor) {
  System S = make_system();
  const core::SparseMatrix A = assemble(S.sys, S.mesh, 1e4);  // M / h^2 with h 100 times smaller
  const Eigen::VectorXd x_ref = dense_solve(A, S.b);
  core::SolverSettings s = pcg(core::PreconditionerKind::cholesky, 1e-10);
  s.jacobi_first = core::kJacobiFirstAuto;
  s.recycled_solutions = 0;
  auto solver = make(s, S.sys);
  const int even = core::jacobi_first_iterations(A.rows());
  for (int k = 0; k < 5; ++k) {
    Eigen::VectorXd x;
    const core::SolveStats st = solver->solve(A, S.b, x);
    EXPECT_TRUE(st.ok);
    EXPECT_EQ(st.factorizations, 0) << "solve " << k;
    EXPECT_LE(st.iterations, even) << "solve " << k;
    EXPECT_LE((x - x_ref).norm(), 1e-8 * x_ref.norm());
  }
  EXPECT_FALSE(solver->factor_info().factored);
  s.jacobi_first = 0;
  auto off = make(s, S.sys);
  Eigen::VectorXd x;
  EXPECT_EQ(off->solve(A, S.b, x).factorizations, 1);
}

// Where block Jacobi is slow (the stiffness dominates: a large time step) the first solve
// is cut off after the break-even plus its allowance, taken again from the same guess
// with the factor, and every later solve uses the factor: the answers are the bits of a
// solver with jacobi_first off, and the first solve's iterations are the cut-off ones more.
TEST(LinearSolver, JacobiFirstSwitchesToTheFactorWhereBlockJacobiIsSlow) {
  System S = make_system();
  const core::SparseMatrix A = assemble(S.sys, S.mesh, 1e-6);
  core::SolverSettings s = pcg(core::PreconditionerKind::cholesky, 1e-10);
  auto off = make(s, S.sys);
  s.jacobi_first = core::kJacobiFirstAuto;
  auto on = make(s, S.sys);
  const double even = core::jacobi_first_iterations(A.rows());
  const int cut = static_cast<int>(even + core::jacobi_first_allowance(even));
  for (int k = 0; k < 3; ++k) {
    Eigen::VectorXd x_off, x_on;
    const core::SolveStats a = off->solve(A, S.b, x_off);
    const core::SolveStats b = on->solve(A, S.b, x_on);
    EXPECT_TRUE(a.ok && b.ok);
    EXPECT_EQ(b.factorizations, a.factorizations) << "solve " << k;
    EXPECT_EQ(b.iterations, a.iterations + (k == 0 ? cut : 0)) << "solve " << k;
    EXPECT_EQ(x_on, x_off) << "solve " << k;
  }
  EXPECT_TRUE(on->factor_info().factored);
}

// While block Jacobi runs first the solver asks for no node rotations (the step skips
// them); the solve that switches to the factor takes them from the rotation source, once,
// and the factor is made at those rotations: a later solve warped from there gives the
// bits of a solver that was handed the same rotations from the start. After the switch the
// rotations are asked for again, and a solve given them, or one with the same matrix
// (solve_same_matrix), does not call the source.
TEST(LinearSolver, JacobiFirstTakesTheNodeRotationsFromTheSourceWhenItSwitches) {
  System S = make_system();
  const core::SparseMatrix soft = assemble(S.sys, S.mesh, 1e4);
  const core::SparseMatrix stiff = assemble(S.sys, S.mesh, 1e-6);
  const std::vector<int> starts = S.sys.node_block_starts();
  const BlockRotations first = random_block_rotations(starts, S.sys.num_free(), 5);
  const BlockRotations later = random_block_rotations(starts, S.sys.num_free(), 6);
  core::SolverSettings s = pcg(core::PreconditionerKind::cholesky, 1e-10);
  s.recycled_solutions = 0;
  auto off = make(s, S.sys);
  s.jacobi_first = core::kJacobiFirstAuto;
  auto on = make(s, S.sys);
  int calls = 0;
  on->set_block_rotation_source([&]() -> const std::vector<Mat3>& {
    ++calls;
    return first.Q;
  });
  Eigen::VectorXd x_on, x_off;
  for (int k = 0; k < 2; ++k) {
    EXPECT_FALSE(on->uses_block_rotations()) << "solve " << k;
    EXPECT_EQ(on->solve(soft, S.b, x_on).factorizations, 0);
  }
  EXPECT_EQ(calls, 0) << "no rotations while block Jacobi runs";
  EXPECT_FALSE(on->uses_block_rotations());
  EXPECT_GE(on->solve(stiff, S.b, x_on).factorizations, 1);
  EXPECT_EQ(calls, 1) << "the switch takes the rotations once";
  EXPECT_TRUE(on->uses_block_rotations()) << "asked for again after the switch";
  off->set_block_rotations(first.Q);
  ASSERT_EQ(off->solve(stiff, S.b, x_off).factorizations, 1);
  // Both factors made at `first`; the next solve warps them to `later`.
  on->set_block_rotations(later.Q);
  off->set_block_rotations(later.Q);
  Eigen::VectorXd y_on, y_off;
  const core::SolveStats a = on->solve(stiff, S.b, y_on);
  const core::SolveStats b = off->solve(stiff, S.b, y_off);
  EXPECT_EQ(calls, 1) << "given rotations, the source is not called";
  EXPECT_EQ(a.factorizations, 0);
  EXPECT_EQ(a.iterations, b.iterations);
  EXPECT_EQ(y_on, y_off) << "the factor was made at the source's rotations";
  Eigen::VectorXd z = y_on;
  EXPECT_TRUE(on->solve_same_matrix(stiff, S.b, z).ok);
  EXPECT_EQ(calls, 1) << "the same matrix keeps its rotations";
}

// A solver restored from the state of one still on block Jacobi goes on with block Jacobi
// and the same count towards the switch: it then switches at the same solve as the
// original. One restored from a state saved after the switch (or before the setting
// existed, when the field reads false) solves with the factor.
TEST(LinearSolver, JacobiFirstStateIsRestoredWithTheSolver) {
  System S = make_system();
  const core::SparseMatrix soft = assemble(S.sys, S.mesh, 1e2);
  const core::SparseMatrix stiff = assemble(S.sys, S.mesh, 1e-6);
  core::SolverSettings s = pcg(core::PreconditionerKind::cholesky, 1e-10);
  s.jacobi_first = core::kJacobiFirstAuto;
  auto original = make(s, S.sys);
  Eigen::VectorXd x;
  for (int k = 0; k < 3; ++k) ASSERT_EQ(original->solve(soft, S.b, x).factorizations, 0);
  const core::LinearSolverState saved = original->save_state();
  EXPECT_TRUE(saved.jacobi_first);
  auto restored = make(s, S.sys);
  restored->load_state(saved, soft);
  for (const core::SparseMatrix* A : {&soft, &stiff, &stiff}) {
    Eigen::VectorXd xa, xb;
    const core::SolveStats a = original->solve(*A, S.b, xa);
    const core::SolveStats b = restored->solve(*A, S.b, xb);
    EXPECT_EQ(a.iterations, b.iterations);
    EXPECT_EQ(a.factorizations, b.factorizations);
    EXPECT_EQ(xa, xb);
  }
  const core::LinearSolverState after = original->save_state();
  EXPECT_FALSE(after.jacobi_first) << "switched to the factor on the stiff matrix";
  auto later = make(s, S.sys);
  later->load_state(after, soft);
  Eigen::VectorXd xa, xb;
  const core::SolveStats a = original->solve(soft, S.b, xa);
  const core::SolveStats b = later->solve(soft, S.b, xb);
  EXPECT_TRUE(later->factor_info().factored);
  EXPECT_EQ(a.iterations, b.iterations) << "the factor, not block Jacobi";
  EXPECT_EQ(xa, xb);
}
