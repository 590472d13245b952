// Rotation extraction (PHYSICS.md section 4): both methods return proper rotations that
// maximise trace(R^T F) over SO(3), checked against the maximum computed here from the
// eigenvalues of F^T F, against the known R of F = R S, and against F (F^T F)^(-1/2);
// inverted, flattened and rank-one F; warm starts and the iteration cap of the polar method.

#include "core/rotation.hpp"
#include "test_support.hpp"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>

#include <cmath>
#include <limits>
#include <random>

namespace core = fiberfem::core;
using core::Mat3;
using core::Vec3;
using fiberfem::testing::random_rotation;

namespace {

double orthonormality_error(const Mat3& R) { return (R.transpose() * R - Mat3::Identity()).norm(); }

// max over SO(3) of trace(R^T F) = s1 + s2 + sign(det F) s3 (s3 the smallest singular value),
// singular values from the eigenvalues of F^T F.
double max_trace(const Mat3& F) {
  const Vec3 ev = Eigen::SelfAdjointEigenSolver<Mat3>(F.transpose() * F).eigenvalues();  // ascending
  const double s3 = std::sqrt(std::max(0.0, ev(0))), s2 = std::sqrt(std::max(0.0, ev(1))),
               s1 = std::sqrt(std::max(0.0, ev(2)));
  return s1 + s2 + (F.determinant() < 0 ? -s3 : s3);
}

// Polar rotation of an F with det F > 0: F (F^T F)^(-1/2).
Mat3 reference_polar(const Mat3& F) {
  Eigen::SelfAdjointEigenSolver<Mat3> es(F.transpose() * F);
  const Mat3 inv_sqrt = es.eigenvectors() * es.eigenvalues().cwiseSqrt().cwiseInverse().asDiagonal() *
                        es.eigenvectors().transpose();
  return F * inv_sqrt;
}

Mat3 polar_from(const Mat3& F, Eigen::Quaterniond q, int max_iterations = 200, int* iterations = nullptr) {
  const int it = core::rotation_polar(F, q, max_iterations);
  if (iterations) *iterations = it;
  return q.toRotationMatrix();
}

Mat3 random_matrix(std::mt19937& rng) {
  std::normal_distribution<double> n(0, 1);
  Mat3 F;
  for (int i = 0; i < 9; ++i) F(i) = n(rng);
  return F;
}

// R0 Q diag(s) Q^T: a stretch with principal axes Q (possibly with negative or zero
// entries) followed by the rotation R0.
Mat3 rotated_stretch(const Mat3& R0, const Mat3& Q, const Vec3& s) { return R0 * Q * s.asDiagonal() * Q.transpose(); }

}  // namespace

TEST(Rotation, RandomMatricesGiveMaximisingProperRotations) {
  std::mt19937 rng(51);
  int inverted = 0;
  for (int trial = 0; trial < 500; ++trial) {
    const Mat3 F = random_matrix(rng);
    inverted += F.determinant() < 0;
    const double best = max_trace(F);
    const Mat3 Rs = core::rotation_svd(F);
    EXPECT_LT(orthonormality_error(Rs), 1e-13);
    EXPECT_NEAR(Rs.determinant(), 1.0, 1e-13);
    EXPECT_NEAR((Rs.transpose() * F).trace(), best, 1e-11 * F.norm()) << "det F " << F.determinant();
    int it = 0;
    const Mat3 Rp = polar_from(F, Eigen::Quaterniond::Identity(), 200, &it);
    EXPECT_LT(it, 200) << "polar did not converge";
    EXPECT_LT(orthonormality_error(Rp), 1e-13);
    EXPECT_NEAR(Rp.determinant(), 1.0, 1e-13);
    EXPECT_NEAR((Rp.transpose() * F).trace(), best, 1e-10 * F.norm()) << "det F " << F.determinant();
  }
  EXPECT_GT(inverted, 150);  // about half of them
}

TEST(Rotation, RotationTimesSymmetricPositiveDefiniteGivesTheRotation) {
  std::mt19937 rng(52);
  std::uniform_real_distribution<double> stretch(0.5, 2.0);
  for (int trial = 0; trial < 200; ++trial) {
    const Mat3 R0 = random_rotation(rng);
    const Mat3 F = rotated_stretch(R0, random_rotation(rng), Vec3(stretch(rng), stretch(rng), stretch(rng)));
    EXPECT_LT((core::rotation_svd(F) - R0).norm(), 1e-13);
    int it = 0;
    EXPECT_LT((polar_from(F, Eigen::Quaterniond::Identity(), 200, &it) - R0).norm(), 1e-11);
    EXPECT_LT(it, 200);
    // From an arbitrary start as well.
    const Eigen::Quaterniond start(random_rotation(rng));
    EXPECT_LT((polar_from(F, start) - R0).norm(), 1e-11);
  }
}

TEST(Rotation, MethodsAgreeWithTheClassicalPolarDecomposition) {
  std::mt19937 rng(53);
  int tested = 0;
  while (tested < 200) {
    const Mat3 F = Mat3::Identity() + 0.4 * random_matrix(rng);
    if (F.determinant() < 0.1) continue;
    ++tested;
    const Mat3 R = reference_polar(F);
    EXPECT_LT((core::rotation_svd(F) - R).norm(), 1e-12);
    EXPECT_LT((polar_from(F, Eigen::Quaterniond::Identity()) - R).norm(), 1e-11);
  }
}

// F = R0 Q diag(s1, s2, -s3) Q^T with s3 < s2 < s1: trace(R^T F) is maximised only by R0
// (flip the smallest principal stretch; Irving, Teran, Fedkiw 2004).
TEST(Rotation, InvertedElementsGiveTheRotationThatFlipsTheSmallestStretch) {
  std::mt19937 rng(54);
  std::uniform_real_distribution<double> big(1.0, 2.0), small(0.05, 0.8);
  for (int trial = 0; trial < 200; ++trial) {
    const Mat3 R0 = random_rotation(rng);
    const Mat3 F = rotated_stretch(R0, random_rotation(rng), Vec3(big(rng), big(rng), -small(rng)));
    ASSERT_LT(F.determinant(), 0);
    const Mat3 Rs = core::rotation_svd(F);
    EXPECT_NEAR(Rs.determinant(), 1.0, 1e-13);
    EXPECT_LT((Rs - R0).norm(), 1e-12);
    const Mat3 Rp = polar_from(F, Eigen::Quaterniond::Identity());
    EXPECT_NEAR(Rp.determinant(), 1.0, 1e-13);
    EXPECT_LT((Rp - R0).norm(), 1e-10);
  }
}

// Flattened elements (rank 2): the maximiser is still unique, R0.
TEST(Rotation, FlattenedElementsGiveTheRotation) {
  std::mt19937 rng(55);
  std::uniform_real_distribution<double> stretch(0.5, 2.0);
  for (int trial = 0; trial < 100; ++trial) {
    const Mat3 R0 = random_rotation(rng);
    const Mat3 F = rotated_stretch(R0, random_rotation(rng), Vec3(stretch(rng), stretch(rng), 0.0));
    EXPECT_LT((core::rotation_svd(F) - R0).norm(), 1e-12);
    const Mat3 Rp = polar_from(F, Eigen::Quaterniond::Identity());
    EXPECT_LT((Rp - R0).norm(), 1e-10);
    EXPECT_NEAR(Rp.determinant(), 1.0, 1e-13);
  }
}

// Rank one (collapsed to a line): the maximiser is any rotation taking the stretched axis
// a to R0 a; both methods must return one of them.
TEST(Rotation, RankOneElementsGiveAProperRotationAlongTheLine) {
  std::mt19937 rng(56);
  for (int trial = 0; trial < 100; ++trial) {
    const Mat3 R0 = random_rotation(rng), Q = random_rotation(rng);
    const Mat3 F = rotated_stretch(R0, Q, Vec3(1.5, 0.0, 0.0));
    const Vec3 a = Q.col(0);
    for (const Mat3& R : {core::rotation_svd(F), polar_from(F, Eigen::Quaterniond::Identity())}) {
      EXPECT_LT(orthonormality_error(R), 1e-13);
      EXPECT_NEAR(R.determinant(), 1.0, 1e-13);
      EXPECT_LT((R * a - R0 * a).norm(), 1e-10);
      EXPECT_NEAR((R.transpose() * F).trace(), 1.5, 1e-12);
    }
  }
}

TEST(Rotation, ZeroMatrixGivesAProperRotation) {
  const Mat3 Rs = core::rotation_svd(Mat3::Zero());
  EXPECT_TRUE(Rs.allFinite());
  EXPECT_LT(orthonormality_error(Rs), 1e-14);
  EXPECT_NEAR(Rs.determinant(), 1.0, 1e-14);
  Eigen::Quaterniond q(Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()));
  const Eigen::Quaterniond q0 = q;
  EXPECT_EQ(core::rotation_polar(Mat3::Zero(), q), 0);
  EXPECT_TRUE(q.isApprox(q0, 1e-15));
}

TEST(RotationPolar, WarmStartAtTheAnswerNeedsNoIterations) {
  std::mt19937 rng(57);
  std::uniform_real_distribution<double> stretch(0.7, 1.4);
  for (int trial = 0; trial < 100; ++trial) {
    const Mat3 R0 = random_rotation(rng);
    const Mat3 F = rotated_stretch(R0, random_rotation(rng), Vec3(stretch(rng), stretch(rng), stretch(rng)));
    Eigen::Quaterniond q(R0);
    EXPECT_LE(core::rotation_polar(F, q), 1);
    EXPECT_LT((q.toRotationMatrix() - R0).norm(), 1e-12);
  }
}

// The header promises two or three iterations from a warm start: a previous rotation
// 0.01 rad away (a typical per-step change) must converge to 1e-12 rad in at most three.
TEST(RotationPolar, WarmStartNearTheAnswerConvergesInAFewIterations) {
  std::mt19937 rng(58);
  std::uniform_real_distribution<double> stretch(0.7, 1.4);
  std::normal_distribution<double> n(0, 1);
  for (int trial = 0; trial < 100; ++trial) {
    const Mat3 R0 = random_rotation(rng);
    const Mat3 F = rotated_stretch(R0, random_rotation(rng), Vec3(stretch(rng), stretch(rng), stretch(rng)));
    const Vec3 axis = Vec3(n(rng), n(rng), n(rng)).normalized();
    Eigen::Quaterniond q = Eigen::Quaterniond(Eigen::AngleAxisd(0.01, axis)) * Eigen::Quaterniond(R0);
    const int it = core::rotation_polar(F, q);
    EXPECT_LE(it, 3);
    EXPECT_LT((q.toRotationMatrix() - R0).norm(), 1e-11);
    EXPECT_NEAR(q.norm(), 1.0, 1e-14);
  }
}

TEST(RotationPolar, IterationCapIsRespected) {
  const Mat3 R0 = Eigen::AngleAxisd(2.0, Vec3(1, -1, 2).normalized()).toRotationMatrix();
  const Mat3 F = R0 * Vec3(1.2, 0.8, 1.0).asDiagonal();
  double previous = F.trace();  // objective at the identity start
  for (int cap : {0, 1, 2, 3}) {
    Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
    EXPECT_EQ(core::rotation_polar(F, q, cap), cap);
    EXPECT_NEAR(q.norm(), 1.0, 1e-14);
    if (cap == 0) {
      EXPECT_TRUE(q.isApprox(Eigen::Quaterniond::Identity()));
    }
    // Every step is an ascent step on trace(R^T F).
    const double reached = (q.toRotationMatrix().transpose() * F).trace();
    EXPECT_GE(reached, previous - 1e-14) << "cap " << cap;
    previous = reached;
    // Resuming from the capped state finishes the job.
    EXPECT_LT(core::rotation_polar(F, q, 100), 100);
    EXPECT_LT((q.toRotationMatrix() - R0).norm(), 1e-11);
  }
  EXPECT_LT(F.trace(), max_trace(F) - 0.5) << "the start should be far from the answer";
}

TEST(RotationPolar, NonFiniteInputStopsWithoutCorruptingTheStart) {
  Mat3 F = Mat3::Identity();
  F(1, 2) = std::numeric_limits<double>::quiet_NaN();
  Eigen::Quaterniond q(Eigen::AngleAxisd(0.3, Vec3::UnitX()));
  const Eigen::Quaterniond q0 = q;
  EXPECT_EQ(core::rotation_polar(F, q), 0);
  EXPECT_TRUE(q.coeffs().allFinite());
  EXPECT_TRUE(q.isApprox(q0, 1e-15));
}

// When the start is a critical point of trace(R^T F) that is not the maximum, the gradient
// sum_i r_i x f_i is exactly zero and the ascent never moves. Two such F from the identity
// start (the simulator's start after reset() / set_state()): a half turn about z, and an
// element inverted along x whose smallest stretch is along y, diag(-1, 0.5, 0.8), both
// exactly diagonal as in axis-aligned box scenes.
TEST(RotationPolar, EscapesNonMaximalCriticalStarts) {
  for (const Mat3& F : {Mat3(Eigen::AngleAxisd(M_PI, Vec3::UnitZ()).toRotationMatrix()),
                        Mat3(Vec3(-1.0, 0.5, 0.8).asDiagonal()), Mat3(Vec3(-2.0, -1.0, 0.5).asDiagonal())}) {
    const Mat3 Rs = core::rotation_svd(F);
    EXPECT_NEAR((Rs.transpose() * F).trace(), max_trace(F), 1e-12);
    const Mat3 Rp = polar_from(F, Eigen::Quaterniond::Identity());
    EXPECT_NEAR((Rp.transpose() * F).trace(), max_trace(F), 1e-10) << "F =\n" << F;
    EXPECT_LT((Rp - Rs).norm(), 1e-9) << "F =\n" << F;
  }
}

// A non-finite F (positions gone NaN) should give a non-finite R, so that the failure shows
// up, rather than arbitrary finite numbers.
TEST(RotationSvd, NonFiniteInputPropagates) {
  for (int k = 0; k < 9; ++k) {
    Mat3 F = Mat3::Identity();
    F(k) = k % 2 ? std::numeric_limits<double>::infinity() : std::numeric_limits<double>::quiet_NaN();
    const Mat3 R = core::rotation_svd(F);
    EXPECT_FALSE(R.allFinite()) << "entry " << k << ": got\n" << R;
  }
}

// rotation_polar_batch (four elements in SIMD lanes) against the reference polar rotation:
// warm starts near the answer (the steady step), far from it and reversed (handed to the
// scalar iteration), inverted and random F, batches of one to four; every lane updates
// its own warm start and rotation only.
TEST(RotationPolar, BatchOfFourAgreesWithTheReference) {
  std::mt19937 rng(23);
  std::normal_distribution<double> n(0, 1);
  const double tol = 1e-9;
  int cases = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const int count = 1 + trial % 4;
    Mat3 F[4];
    Eigen::Quaterniond q[4], q_scalar[4];
    Mat3 R[4];
    Eigen::Quaterniond* qp[4];
    Mat3* Rp[4];
    for (int l = 0; l < 4; ++l) {
      const Mat3 R0 = random_rotation(rng);
      const int kind = (trial / 4 + l) % 4;
      const Vec3 s = kind == 2 ? Vec3(1.2, 0.9, -0.3) : Vec3(1 + 0.2 * n(rng), 1 + 0.2 * n(rng), 1 + 0.2 * n(rng));
      F[l] = kind == 3 ? random_matrix(rng) : rotated_stretch(R0, random_rotation(rng), s);
      // Warm start: near the answer (a small turn away), or a random rotation.
      const Mat3 answer = core::rotation_svd(F[l]);
      const Vec3 turn = (kind == 0 ? 8e-3 : kind == 1 ? 3.0 : kind == 2 ? 0.05 : 1e-3) * Vec3(n(rng), n(rng), n(rng)).normalized();
      q[l] = Eigen::Quaterniond(Eigen::AngleAxisd(turn.norm(), turn.normalized()).toRotationMatrix() * answer);
      q_scalar[l] = q[l];
      R[l] = Mat3::Constant(-7);
      qp[l] = &q[l];
      Rp[l] = &R[l];
    }
    core::rotation_polar_batch(F, qp, Rp, count, tol);
    for (int l = 0; l < 4; ++l) {
      if (l >= count) {  // lanes past the count are not touched
        EXPECT_EQ(R[l](0, 0), -7.0);
        EXPECT_EQ(q[l].coeffs(), q_scalar[l].coeffs());
        continue;
      }
      const Mat3 expected = core::rotation_svd(F[l]);
      EXPECT_LT(orthonormality_error(R[l]), 1e-12);
      EXPECT_NEAR(R[l].determinant(), 1.0, 1e-12);
      EXPECT_LT((R[l] - q[l].toRotationMatrix()).norm(), 1e-12) << "R and the warm start disagree";
      // The maximiser of trace(R^T F) is unique unless two singular values sum to zero.
      EXPECT_NEAR((R[l].transpose() * F[l]).trace(), max_trace(F[l]), 1e-9 * F[l].norm());
      if (F[l].determinant() > 1e-3) {
        EXPECT_LT((R[l] - reference_polar(F[l])).norm(), 1e-8) << "trial " << trial << " lane " << l;
        EXPECT_LT((R[l] - expected).norm(), 1e-8);
        ++cases;
      }
    }
  }
  EXPECT_GT(cases, 300);
}
