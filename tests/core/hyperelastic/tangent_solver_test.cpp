// TangentSolver: a lagged factor as GMRES's preconditioner (in single precision where
// UMFPACK's factors are copied) still solves a later, different tangent to the forcing
// asked for: checked against a dense LU of that tangent, on a saddle-point matrix whose
// zero pressure block makes UMFPACK pivot off the diagonal (row and column permutations)
// and whose rows differ in scale by orders of magnitude (its row scaling).
#include "core/hyperelastic/tangent_solver.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/SparseLU>

#include <cstdio>
#include <random>
#include <vector>

namespace fiberfem::core::hyperelastic {
namespace {

// [[A, B^T], [B, 0]]: A a banded nonsymmetric "displacement" block with rows scaled from
// 1e-3 to 1e3, B a sparse coupling to `np` pressures; `shift` perturbs A's values.
SparseMatrix saddle(int nu, int np, double shift, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Eigen::Triplet<double>> t;
  for (int i = 0; i < nu; ++i) {
    const double row_scale = std::pow(10.0, 3.0 * (2.0 * i / (nu - 1) - 1.0));
    t.emplace_back(i, i, row_scale * (8.0 + shift * u(rng)));
    for (int d : {-7, -3, -1, 1, 2, 5}) {
      const int j = i + d;
      if (j >= 0 && j < nu) t.emplace_back(i, j, row_scale * (u(rng) + shift * u(rng)));
    }
  }
  for (int k = 0; k < np; ++k)
    for (int c = 0; c < 4; ++c) {
      const int j = (k * 7 + c * 13) % nu;
      const double v = 1.0 + 0.5 * u(rng);
      t.emplace_back(nu + k, j, v);
      t.emplace_back(j, nu + k, v);
    }
  SparseMatrix K(nu + np, nu + np);
  K.setFromTriplets(t.begin(), t.end());
  return K;
}

TEST(TangentSolver, ALaggedFactorSolvesALaterTangentToTheForcing) {
  const int nu = 240, np = 30, n = nu + np;
  const SparseMatrix K0 = saddle(nu, np, 0.0, 1);
  SparseMatrix K1 = K0;
  const SparseMatrix dK = saddle(nu, np, 0.05, 2) - saddle(nu, np, 0.0, 2);
  K1 += dK;  // the same pattern, values moved by a few per cent (a later Newton tangent)
  const Eigen::VectorXd R = Eigen::VectorXd::LinSpaced(n, -1.0, 2.0);

  TangentSolver solver;
  Eigen::VectorXd d0;
  ASSERT_TRUE(solver.solve(K0, R, 1e-2, true, d0));  // fresh: factorised, solved directly
  EXPECT_EQ(solver.factorisations(), 1);
  const Eigen::VectorXd exact0 = Eigen::MatrixXd(K0).partialPivLu().solve(R);
  EXPECT_LT((d0 - exact0).norm(), 1e-9 * exact0.norm());

  for (double forcing : {1e-4, 1e-10}) {
    Eigen::VectorXd d1;
    const int krylov_before = solver.krylov_iterations();
    ASSERT_TRUE(solver.solve(K1, R, forcing, false, d1));
    EXPECT_EQ(solver.factorisations(), 1) << "the lagged factor served, no new factorisation";
    EXPECT_GT(solver.krylov_iterations(), krylov_before);
    EXPECT_LE((K1 * d1 - R).norm(), 1.01 * forcing * R.norm()) << "forcing " << forcing;
    if (forcing == 1e-10) {
      const Eigen::VectorXd exact1 = Eigen::MatrixXd(K1).partialPivLu().solve(R);
      EXPECT_LT((d1 - exact1).norm(), 1e-6 * exact1.norm());
    }
  }
}

// A warm solve starts from the guess it is given and reaches the same residual, |K d - R|
// <= forcing |R|: from the answer itself it needs no iteration, from the answer of a
// nearby right-hand side (the bordered Newton's responses from one iteration to the next)
// fewer than from zero; a guess worse than zero (or of the wrong size) is not used.
TEST(TangentSolver, AWarmSolveStartsFromItsGuessAndReachesTheSameResidual) {
  const int nu = 240, np = 30, n = nu + np;
  const SparseMatrix K0 = saddle(nu, np, 0.0, 1);
  SparseMatrix K1 = K0;
  K1 += saddle(nu, np, 0.05, 2) - saddle(nu, np, 0.0, 2);
  const Eigen::VectorXd R = Eigen::VectorXd::LinSpaced(n, -1.0, 2.0);
  const Eigen::VectorXd R_near = R + 1e-3 * Eigen::VectorXd::LinSpaced(n, 1.0, 0.0);
  const Eigen::VectorXd exact = Eigen::MatrixXd(K1).partialPivLu().solve(R);
  const double forcing = 1e-8;
  auto iterations = [&](Eigen::VectorXd guess, bool warm, const Eigen::VectorXd& rhs) {
    TangentSolver solver;
    Eigen::VectorXd d0;
    EXPECT_TRUE(solver.solve(K0, rhs, 1e-2, true, d0));
    EXPECT_TRUE(solver.solve(K1, rhs, forcing, false, guess, warm));
    EXPECT_EQ(solver.factorisations(), 1);
    EXPECT_LE((K1 * guess - rhs).norm(), 1.01 * forcing * rhs.norm());
    return solver.krylov_iterations();
  };
  EXPECT_EQ(iterations(exact, true, R), 0);
  const Eigen::VectorXd near = Eigen::MatrixXd(K1).partialPivLu().solve(R_near);
  const int cold = iterations(Eigen::VectorXd(), false, R);
  const int warm = iterations(near, true, R);
  EXPECT_LT(warm, cold);
  EXPECT_EQ(iterations(-1e3 * exact, true, R), cold) << "a guess worse than zero is not used";
  EXPECT_EQ(iterations(Eigen::VectorXd::Ones(3), true, R), cold) << "a guess of the wrong size is not used";
  std::printf("GMRES iterations to 1e-8: %d from zero, %d from a nearby answer\n", cold, warm);
}

// A factor of an unrelated matrix (same pattern, other values) does not precondition it:
// GMRES gives up within its budget and the tangent is factorised afresh, so the answer is
// still the exact one, not a half-converged iterate.
TEST(TangentSolver, AFactorThatNoLongerPreconditionsIsReplaced) {
  const int nu = 240, np = 30, n = nu + np;
  const SparseMatrix K0 = saddle(nu, np, 0.0, 1);
  const SparseMatrix K1 = saddle(nu, np, 0.0, 7);
  ASSERT_EQ(K0.nonZeros(), K1.nonZeros());
  const Eigen::VectorXd R = Eigen::VectorXd::LinSpaced(n, 1.0, -2.0);
  TangentSolver solver;
  Eigen::VectorXd d;
  ASSERT_TRUE(solver.solve(K0, R, 1e-8, true, d));
  ASSERT_TRUE(solver.solve(K1, R, 1e-8, false, d));
  EXPECT_EQ(solver.factorisations(), 2) << "the lagged factor failed, the tangent was factorised again";
  EXPECT_GE(solver.krylov_iterations(), TangentSolver::kMaxKrylovIterations / 2) << "GMRES was tried first";
  const Eigen::VectorXd exact = Eigen::MatrixXd(K1).partialPivLu().solve(R);
  EXPECT_LT((d - exact).norm(), 1e-9 * exact.norm());
}

// [[A, B^T], [B, 0]] on a g x g x g grid: A a 7-point stencil, nonsymmetric by `skew`, B
// a pressure per 2 x 2 x 2 cell coupled to its corners. Nested dissection splits its
// elimination into two halves below a separator.
SparseMatrix grid_saddle(int g, double skew, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const int nu = g * g * g, c = g / 2, np = c * c * c;
  auto id = [g](int i, int j, int k) { return (k * g + j) * g + i; };
  std::vector<Eigen::Triplet<double>> t;
  for (int k = 0; k < g; ++k)
    for (int j = 0; j < g; ++j)
      for (int i = 0; i < g; ++i) {
        const int r = id(i, j, k);
        t.emplace_back(r, r, 6.5 + 0.1 * u(rng));
        const int nb[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
        for (const auto& d : nb) {
          const int a = i + d[0], b = j + d[1], e = k + d[2];
          if (a >= 0 && a < g && b >= 0 && b < g && e >= 0 && e < g) t.emplace_back(r, id(a, b, e), -1.0 + skew * u(rng));
        }
      }
  for (int k = 0; k < c; ++k)
    for (int j = 0; j < c; ++j)
      for (int i = 0; i < c; ++i) {
        const int row = nu + (k * c + j) * c + i;
        for (int corner = 0; corner < 8; ++corner) {
          const int col = id(2 * i + (corner & 1), 2 * j + ((corner >> 1) & 1), 2 * k + (corner >> 2));
          const double v = 0.5 + 0.25 * u(rng);
          t.emplace_back(row, col, v);
          t.emplace_back(col, row, v);
        }
      }
  SparseMatrix K(nu + np, nu + np);
  K.setFromTriplets(t.begin(), t.end());
  return K;
}

// On a factor whose elimination splits in two, the lagged substitutions run on two
// threads: as exact an inverse as the unsplit copy, the same answer to the last bit as on
// one thread (the same operations on every row), to the forcing asked for, and the exact
// solution's (a sparse LU of that tangent).
TEST(TangentSolver, TwoThreadsSubstituteAsOneDoes) {
  const int g = 14;
  const SparseMatrix K0 = grid_saddle(g, 0.05, 1);
  const SparseMatrix K1 = K0 + 0.03 * (grid_saddle(g, 0.05, 2) - grid_saddle(g, 0.05, 3));  // a later tangent
  ASSERT_EQ(K1.nonZeros(), K0.nonZeros());
  const Eigen::Index n = K0.rows();
  const Eigen::VectorXd R = Eigen::VectorXd::LinSpaced(n, -1.0, 2.0);
  Eigen::SparseLU<SparseMatrix> exact_lu(K1);
  ASSERT_EQ(exact_lu.info(), Eigen::Success);
  const Eigen::VectorXd exact = exact_lu.solve(R);

  std::vector<Eigen::VectorXd> answers;
  for (int threads : {1, 2}) {
    TangentSolver solver;
    solver.set_threads(threads);
    Eigen::VectorXd d;
    ASSERT_TRUE(solver.solve(K0, R, 1e-2, true, d));
    if (solver.lagged_parts() == 0) GTEST_SKIP() << "no single-precision copy (built without UMFPACK)";
    ASSERT_EQ(solver.lagged_parts(), 2) << "the grid's factor should split into two halves";
    // On the matrix it is the factor of, the single-precision copy is an inverse to about
    // 1e-7: one GMRES iteration reaches 1e-5 (a wrong substitution would need many).
    ASSERT_TRUE(solver.solve(K0, -R, 1e-5, false, d));
    EXPECT_EQ(solver.krylov_iterations(), 1) << threads << " threads";
    EXPECT_LE((K0 * d + R).norm(), 1e-5 * R.norm());
    ASSERT_TRUE(solver.solve(K1, R, 1e-10, false, d));
    EXPECT_EQ(solver.factorisations(), 1) << "the lagged factor served";
    EXPECT_LE((K1 * d - R).norm(), 1.01e-10 * R.norm()) << threads << " threads";
    EXPECT_LT((d - exact).norm(), 1e-8 * exact.norm()) << threads << " threads";
    answers.push_back(d);
  }
  EXPECT_EQ((answers[0] - answers[1]).cwiseAbs().maxCoeff(), 0.0) << "one thread and two differ";
}

}  // namespace
}  // namespace fiberfem::core::hyperelastic
