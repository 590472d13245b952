// Element stiffness K^e = V B^T C_g B with the correct fiber-frame transform (PHYSICS.md
// sections 3 and 9): symmetry, null space, patch energies, invariances, and a check that
// the literal reading of the paper's eq. 11 is NOT rotation invariant.

#include "core/element.hpp"
#include "core/fiber_frame.hpp"
#include "core/material.hpp"
#include "test_support.hpp"

#include <Eigen/Eigenvalues>

#include <cmath>
#include <random>

namespace core = fiberfem::core;
using core::Mat12;
using core::Mat3;
using core::Vec12;
using core::Vec3;
using core::Vec6;

namespace {

core::Material ti_material() {
  core::EngineeringConstants c;
  c.E_L = 200e3;
  c.E_T = 20e3;
  c.nu_T = 0.45;
  c.nu_LT = 0.3;
  c.G_L = 9e3;
  return core::Material::from_engineering(c, 1000);
}

// A random, reasonably shaped tetrahedron of size ~1 cm with positive orientation.
Vec12 random_tet(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-0.003, 0.003);
  Vec12 X;
  X << 0, 0, 0, 0.01, 0, 0, 0, 0.01, 0, 0, 0, 0.01;
  for (int i = 0; i < 12; ++i) X(i) += u(rng);
  return X;
}

Vec3 random_unit(std::mt19937& rng) {
  std::normal_distribution<double> n(0, 1);
  return Vec3(n(rng), n(rng), n(rng)).normalized();
}

Vec12 apply_gradient(const Mat3& H, const Vec12& X) {
  Vec12 u;
  for (int a = 0; a < 4; ++a) u.segment<3>(3 * a) = H * X.segment<3>(3 * a);
  return u;
}

Mat12 blockdiag(const Mat3& Q) {
  Mat12 M = Mat12::Zero();
  for (int a = 0; a < 4; ++a) M.block<3, 3>(3 * a, 3 * a) = Q;
  return M;
}

double tet_volume(const Vec12& X) {
  return core::signed_volume(X.segment<3>(0), X.segment<3>(3), X.segment<3>(6), X.segment<3>(9));
}

// Independent strain energy density of a small strain eps (tensor) for the TI material with
// fiber f: rotate eps into the fiber frame by hand, then 1/2 eps_l : C eps_l in Voigt form.
double energy_density(const core::Material& m, const Vec3& f, const Mat3& eps) {
  const Mat3 Q = core::frame_from_fiber(f);
  const Mat3 el = Q * eps * Q.transpose();
  Vec6 v;
  v << el(0, 0), el(1, 1), el(2, 2), 2 * el(0, 1), 2 * el(1, 2), 2 * el(2, 0);
  return 0.5 * v.dot(m.stiffness() * v);
}

}  // namespace

TEST(ElementStiffness, SymmetricWithExactlySixZeroEigenvalues) {
  std::mt19937 rng(1);
  const core::Material m = ti_material();
  for (int trial = 0; trial < 20; ++trial) {
    const Vec12 X = random_tet(rng);
    const Mat12 K = core::element_stiffness(X, m, random_unit(rng));
    EXPECT_LT((K - K.transpose()).norm(), 1e-12 * K.norm());
    Eigen::SelfAdjointEigenSolver<Mat12> es(K);
    const auto ev = es.eigenvalues();  // ascending
    const double top = ev(11);
    for (int i = 0; i < 6; ++i) EXPECT_LT(std::abs(ev(i)), 1e-10 * top) << "eigenvalue " << i;
    EXPECT_GT(ev(6), 1e-6 * top) << "a seventh zero eigenvalue: the element would have a spurious mode";
  }
}

TEST(ElementStiffness, RigidMotionsAreInTheNullSpace) {
  std::mt19937 rng(2);
  const Vec12 X = random_tet(rng);
  const Mat12 K = core::element_stiffness(X, ti_material(), random_unit(rng));
  for (int d = 0; d < 3; ++d) {
    Vec12 t;
    for (int a = 0; a < 4; ++a) t.segment<3>(3 * a) = Vec3::Unit(d);
    EXPECT_LT((K * t).norm(), 1e-9 * K.norm()) << "translation " << d;
    Mat3 W = Mat3::Zero();  // infinitesimal rotation about axis d
    W((d + 1) % 3, (d + 2) % 3) = -1;
    W((d + 2) % 3, (d + 1) % 3) = 1;
    EXPECT_LT((K * apply_gradient(W, X)).norm(), 1e-9 * K.norm() * 0.01) << "rotation " << d;
  }
}

// Single-element patch test: for a uniform strain the element energy is V times the energy
// density computed independently in the fiber frame, for strains along, across and at
// angles to the fiber, and for shear.
TEST(ElementStiffness, UniformStrainEnergyMatchesFiberFrameDensity) {
  std::mt19937 rng(3);
  const core::Material m = ti_material();
  for (int trial = 0; trial < 10; ++trial) {
    const Vec12 X = random_tet(rng);
    const Vec3 f = random_unit(rng);
    const Mat12 K = core::element_stiffness(X, m, f);
    std::normal_distribution<double> n(0, 1e-3);
    Mat3 eps;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) eps(i, j) = n(rng);
    eps = 0.5 * (eps + eps.transpose()).eval();
    const Vec12 u = apply_gradient(eps, X);
    const double energy = 0.5 * u.dot(K * u);
    const double expected = tet_volume(X) * energy_density(m, f, eps);
    EXPECT_NEAR(energy, expected, 1e-11 * std::abs(expected));
  }
}

TEST(ElementStiffness, RotatingShapeAndFiberRotatesTheMatrix) {
  std::mt19937 rng(4);
  const core::Material m = ti_material();
  for (int trial = 0; trial < 10; ++trial) {
    const Vec12 X = random_tet(rng);
    const Vec3 f = random_unit(rng);
    const Mat3 Q = fiberfem::testing::random_rotation(rng);
    const Mat12 K = core::element_stiffness(X, m, f);
    const Mat12 Kr = core::element_stiffness(blockdiag(Q) * X, m, Q * f);
    EXPECT_LT((Kr - blockdiag(Q) * K * blockdiag(Q).transpose()).norm(), 1e-11 * K.norm());
  }
}

TEST(ElementStiffness, ChoiceOfM1M2AboutTheFiberChangesNothing) {
  std::mt19937 rng(5);
  const core::Material m = ti_material();
  const Vec12 X = random_tet(rng);
  const Vec3 f = random_unit(rng);
  const Mat12 K0 = core::element_stiffness(X, m, f, 0.0);
  for (double angle : {0.3, 1.0, 2.5, -1.7}) {
    const Mat12 K = core::element_stiffness(X, m, f, angle);
    EXPECT_LT((K - K0).norm(), 1e-11 * K0.norm()) << "angle " << angle;
  }
}

TEST(ElementStiffness, FiberSignDoesNotMatter) {
  std::mt19937 rng(6);
  const Vec12 X = random_tet(rng);
  const Vec3 f = random_unit(rng);
  const Mat12 K1 = core::element_stiffness(X, ti_material(), f);
  const Mat12 K2 = core::element_stiffness(X, ti_material(), -f);
  EXPECT_LT((K1 - K2).norm(), 1e-11 * K1.norm());
}

// PHYSICS.md section 3: K = M^T (LN)^T C (LN) M with LN from *global* gradients and
// M = blockdiag(Q) is the literal reading of the paper; it is not rotation invariant. The
// correct transform is. This test keeps the wrong formula from coming back.
TEST(ElementStiffness, LiteralPaperFormulaIsNotRotationInvariantButOursIs) {
  std::mt19937 rng(7);
  const core::Material m = ti_material();
  const Vec12 X = random_tet(rng);
  const Vec3 f = random_unit(rng);
  auto literal = [&](const Vec12& Xs, const Vec3& fs) {
    const core::Mat6x12 B = core::strain_operator(core::rest_shape_inverse(Xs));
    const Mat12 Ke = tet_volume(Xs) * B.transpose() * m.stiffness() * B;
    const Mat12 M = blockdiag(core::frame_from_fiber(fs));
    return Mat12(M.transpose() * Ke * M);
  };
  const Mat3 Q = fiberfem::testing::random_rotation(rng);
  const Mat12 Kl = literal(X, f), Klr = literal(blockdiag(Q) * X, Q * f);
  const double literal_error = (Klr - blockdiag(Q) * Kl * blockdiag(Q).transpose()).norm() / Kl.norm();
  EXPECT_GT(literal_error, 1e-2) << "the literal formula unexpectedly passed";
  const Mat12 K = core::element_stiffness(X, m, f), Kr = core::element_stiffness(blockdiag(Q) * X, m, Q * f);
  EXPECT_LT((Kr - blockdiag(Q) * K * blockdiag(Q).transpose()).norm() / K.norm(), 1e-11);
}

TEST(ElementStiffness, FiberFactorOneEqualsIsotropicModel) {
  std::mt19937 rng(8);
  const Vec12 X = random_tet(rng);
  core::LameFiberConstants l;
  l.lambda = 30e3;
  l.mu = 12e3;
  const core::Material lame = core::Material::from_lame(l, 1000);
  const double E = l.mu * (3 * l.lambda + 2 * l.mu) / (l.lambda + l.mu);
  const double nu = l.lambda / (2 * (l.lambda + l.mu));
  const core::Material iso = core::Material::isotropic(E, nu, 1000);
  const Mat12 Kl = core::element_stiffness(X, lame, random_unit(rng));
  const Mat12 Ki = core::element_stiffness(X, iso, random_unit(rng));
  EXPECT_LT((Kl - Ki).norm(), 1e-11 * Ki.norm());
  // The frame path, forced, gives the same matrix: skipping it is exact.
  const Mat3 Q = core::frame_from_fiber(random_unit(rng));
  EXPECT_LT((core::rotate_stiffness(iso.stiffness(), Q) - iso.stiffness()).norm(), 1e-11 * iso.stiffness().norm());
  // And a fiber factor barely above one is continuous with it.
  l.fiber_factor = 1 + 1e-9;
  const Mat12 Kn = core::element_stiffness(X, core::Material::from_lame(l, 1000), random_unit(rng));
  EXPECT_LT((Kn - Ki).norm(), 1e-8 * Ki.norm());
}

// g^e = V B^T voigt(f f^T): no net force or torque, and its work on a uniform strain is
// V f^T eps f (the virtual work of a unit stress along the fiber).
TEST(ActiveStressVector, WorkAndEquilibrium) {
  std::mt19937 rng(9);
  for (int trial = 0; trial < 5; ++trial) {
    const Vec12 X = random_tet(rng);
    const Vec3 f = random_unit(rng);
    const Vec12 g = core::active_stress_vector(X, 3.0 * f);
    Vec3 net = Vec3::Zero(), torque = Vec3::Zero();
    for (int a = 0; a < 4; ++a) {
      net += g.segment<3>(3 * a);
      torque += X.segment<3>(3 * a).cross(g.segment<3>(3 * a));
    }
    EXPECT_LT(net.norm(), 1e-12 * g.norm());
    EXPECT_LT(torque.norm(), 1e-12 * g.norm() * 0.01);
    Mat3 eps = Mat3::Random();
    eps = 0.5 * (eps + eps.transpose()).eval();
    EXPECT_NEAR(g.dot(apply_gradient(eps, X)), tet_volume(X) * f.dot(eps * f), 1e-12 * tet_volume(X));
  }
}
