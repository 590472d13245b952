// Corotated element force and tangents (PHYSICS.md sections 4 and 9): zero force under
// rigid motion, force against energy differences, both tangents against finite
// differences of the force, including inverted elements.

#include "core/corotation.hpp"
#include "core/element.hpp"
#include "core/rotation.hpp"
#include "test_support.hpp"

#include <cmath>
#include <random>

namespace core = fiberfem::core;
using core::Mat12;
using core::Mat3;
using core::Vec12;
using core::Vec3;

namespace {

struct Element {
  Vec12 X;
  Mat3 Dm_inv;
  Mat12 K;
};

Element make_element(const core::Material& m, const Vec3& fiber) {
  Element el;
  el.X << 0, 0, 0, 0.01, 0.001, 0, 0.002, 0.012, 0, 0.001, 0.002, 0.011;
  el.Dm_inv = core::rest_shape_inverse(el.X);
  el.K = core::element_stiffness(el.X, m, fiber);
  return el;
}

core::Material ti() {
  core::EngineeringConstants c;
  c.E_L = 300e3;
  c.E_T = 30e3;
  c.nu_T = 0.4;
  c.nu_LT = 0.3;
  c.G_L = 12e3;
  return core::Material::from_engineering(c, 1000);
}

Mat3 R_of(const Vec12& x, const Element& el) { return core::rotation_svd(core::deformation_gradient(x, el.Dm_inv)); }

Vec12 force(const Vec12& x, const Element& el) { return core::corotated_force(R_of(x, el), el.K, x, el.X); }
double energy(const Vec12& x, const Element& el) { return core::corotated_energy(R_of(x, el), el.K, x, el.X); }

Vec12 deform(const Element& el, const Mat3& F, const Vec3& t) {
  Vec12 x;
  for (int a = 0; a < 4; ++a) x.segment<3>(3 * a) = F * el.X.segment<3>(3 * a) + t;
  return x;
}

// Central finite-difference Jacobian of the force, as a stiffness -df/dx.
Mat12 fd_stiffness(const Vec12& x, const Element& el, double h) {
  Mat12 J;
  for (int k = 0; k < 12; ++k) {
    Vec12 xp = x, xm = x;
    xp(k) += h;
    xm(k) -= h;
    J.col(k) = -(force(xp, el) - force(xm, el)) / (2 * h);
  }
  return J;
}

}  // namespace

TEST(Corotation, RigidMotionGivesZeroForceAndEnergy) {
  std::mt19937 rng(11);
  const Element el = make_element(ti(), Vec3(1, 2, 0.5));
  for (int trial = 0; trial < 20; ++trial) {
    const Mat3 Q = fiberfem::testing::random_rotation(rng);
    const Vec12 x = deform(el, Q, Vec3(0.3, -1.0, 2.0));
    const double scale = (el.K * el.X).norm() + el.K.norm() * 0.01;
    EXPECT_LT(force(x, el).norm(), 1e-10 * scale);
    // Round-off displacements ~1e-16 |X| give energies ~1e-32 K |X|^2; a 1 % strain gives 1e-4.
    EXPECT_LT(std::abs(energy(x, el)), 1e-20 * el.K.norm() * el.X.squaredNorm());
  }
  // Half turn, the worst case for naive polar decompositions.
  const Mat3 half = Eigen::AngleAxisd(M_PI, Vec3(0, 0, 1)).toRotationMatrix();
  EXPECT_LT(force(deform(el, half, Vec3::Zero()), el).norm(), 1e-10 * el.K.norm() * 0.01);
}

// For an isotropic material the corotated force is exactly -dE/dx (the dR terms vanish
// because the stress commutes with the stretch); check at a large deformation.
TEST(Corotation, IsotropicForceIsMinusEnergyGradient) {
  const Element el = make_element(core::Material::isotropic(50e3, 0.3, 1000), Vec3::UnitX());
  Mat3 F;
  F << 1.2, 0.3, -0.1, 0.05, 0.8, 0.2, -0.2, 0.1, 1.1;
  const Mat3 Q = Eigen::AngleAxisd(0.9, Vec3(1, 1, 0).normalized()).toRotationMatrix();
  const Vec12 x = deform(el, Q * F, Vec3(0.1, 0.2, 0.3));
  const Vec12 f = force(x, el);
  const double h = 1e-8;
  for (int k = 0; k < 12; ++k) {
    Vec12 xp = x, xm = x;
    xp(k) += h;
    xm(k) -= h;
    EXPECT_NEAR(-(energy(xp, el) - energy(xm, el)) / (2 * h), f(k), 1e-6 * f.norm()) << "dof " << k;
  }
}

// For a transversely isotropic material the warped force is -dE/dx only to first order in
// strain (PHYSICS.md section 4: the consistent tangent is then non-symmetric). The mismatch
// must shrink in proportion to the strain.
TEST(Corotation, AnisotropicForceMatchesEnergyGradientToFirstOrder) {
  const Element el = make_element(ti(), Vec3(1, 1, 0));
  const Mat3 Q = Eigen::AngleAxisd(1.2, Vec3(0, 1, 1).normalized()).toRotationMatrix();
  Mat3 D;
  D << 1.0, 0.3, -0.1, 0.3, -0.5, 0.2, -0.1, 0.2, 0.7;
  double previous = 0;
  for (double s : {1e-2, 1e-3}) {
    const Vec12 x = deform(el, Q * (Mat3::Identity() + s * D), Vec3::Zero());
    const Vec12 f = force(x, el);
    Vec12 g;
    const double h = 1e-9;
    for (int k = 0; k < 12; ++k) {
      Vec12 xp = x, xm = x;
      xp(k) += h;
      xm(k) -= h;
      g(k) = -(energy(xp, el) - energy(xm, el)) / (2 * h);
    }
    const double rel = (g - f).norm() / f.norm();
    EXPECT_LT(rel, 5 * s) << "strain " << s;
    if (previous > 0) {
      EXPECT_LT(rel, 0.3 * previous) << "mismatch does not shrink with strain";
    }
    previous = rel;
  }
}

TEST(Corotation, ConsistentTangentMatchesFiniteDifferences) {
  const Element el = make_element(ti(), Vec3(0.3, 1, 0.2));
  Mat3 F;
  F << 1.3, 0.2, -0.1, 0.1, 0.7, 0.25, -0.15, 0.1, 1.05;
  const Mat3 Q = Eigen::AngleAxisd(2.0, Vec3(1, -1, 2).normalized()).toRotationMatrix();
  const Vec12 x = deform(el, Q * F, Vec3(0.01, 0.02, 0.0));
  const Mat12 Kc = core::consistent_stiffness(R_of(x, el), el.K, x, el.X, el.Dm_inv);
  const Mat12 Kfd = fd_stiffness(x, el, 1e-8);
  EXPECT_LT((Kc - Kfd).norm(), 1e-6 * Kfd.norm());
  // The warped stiffness alone misses the dR/dx term: visibly different at this deformation.
  const Mat12 Kw = core::warped_stiffness(R_of(x, el), el.K);
  EXPECT_GT((Kw - Kfd).norm(), 1e-2 * Kfd.norm());
  // Non-symmetric for an anisotropic material.
  EXPECT_GT((Kc - Kc.transpose()).norm(), 1e-4 * Kc.norm());
}

TEST(Corotation, ConsistentTangentMatchesFiniteDifferencesForInvertedElement) {
  const Element el = make_element(ti(), Vec3(0, 0, 1));
  Mat3 F;
  F << 1.1, 0.1, 0.0, 0.0, 0.9, 0.1, 0.05, 0.0, -0.4;  // det < 0
  ASSERT_LT(F.determinant(), 0);
  const Vec12 x = deform(el, F, Vec3::Zero());
  const Mat12 Kc = core::consistent_stiffness(R_of(x, el), el.K, x, el.X, el.Dm_inv);
  const Mat12 Kfd = fd_stiffness(x, el, 1e-8);
  EXPECT_LT((Kc - Kfd).norm(), 1e-6 * Kfd.norm());
  // The inverted element is pushed back: the force does work against further flattening.
  const Vec12 f = force(x, el);
  EXPECT_TRUE(f.allFinite());
  EXPECT_GT(f.norm(), 0);
}

TEST(Corotation, TangentsEqualPrecomputedStiffnessAtRest) {
  const Element el = make_element(ti(), Vec3(1, 0.5, 0.2));
  const Mat12 Kc = core::consistent_stiffness(Mat3::Identity(), el.K, el.X, el.X, el.Dm_inv);
  EXPECT_LT((Kc - el.K).norm(), 1e-10 * el.K.norm());
  EXPECT_LT((core::warped_stiffness(Mat3::Identity(), el.K) - el.K).norm(), 1e-14 * el.K.norm());
}

TEST(Corotation, LocalNodeOrderChangesNothing) {
  const core::Material m = ti();
  const Vec3 fiber(0.2, 0.9, 0.4);
  const Element el = make_element(m, fiber);
  Mat3 F;
  F << 1.1, 0.2, 0.0, -0.1, 0.95, 0.1, 0.0, 0.3, 1.2;
  const Vec12 x = deform(el, F, Vec3::Zero());
  const Vec12 f = force(x, el);
  // Even permutation of the local nodes keeps positive orientation: (0,1,2,3) -> (1,2,0,3).
  const int p[4] = {1, 2, 0, 3};
  Element pe;
  Vec12 px;
  for (int a = 0; a < 4; ++a) {
    pe.X.segment<3>(3 * a) = el.X.segment<3>(3 * p[a]);
    px.segment<3>(3 * a) = x.segment<3>(3 * p[a]);
  }
  pe.Dm_inv = core::rest_shape_inverse(pe.X);
  pe.K = core::element_stiffness(pe.X, m, fiber);
  const Vec12 pf = force(px, pe);
  for (int a = 0; a < 4; ++a)
    EXPECT_LT((pf.segment<3>(3 * a) - f.segment<3>(3 * p[a])).norm(), 1e-10 * f.norm());
}
