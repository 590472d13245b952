// The closed-form element of the dynamic step (core/spencer_element.hpp) against the
// stored-matrix route of PHYSICS.md section 3 (element_stiffness: V B^T T(Q)^T C T(Q) B,
// corotated_force: -R K (R^T x - X)): two independent derivations of the same operator.
// Random elements, fibers, rotations and deformations (inverted ones included), for the
// paper's Lame-plus-fiber material, engineering constants and an isotropic material.

#include "core/corotation.hpp"
#include "core/element.hpp"
#include "core/rotation.hpp"
#include "core/sparse_system.hpp"
#include "core/spencer_element.hpp"
#include "test_support.hpp"

#include <random>

namespace core = fiberfem::core;
using core::Mat12;
using core::Mat3;
using core::Vec12;
using core::Vec3;

namespace {

std::vector<core::Material> materials() {
  core::LameFiberConstants lf;  // lambda 40 kPa, mu 10 kPa
  lf.fiber_factor = 30.0;
  lf.shear_factor = 2.0;
  core::EngineeringConstants ec;
  ec.E_L = 18e3;
  ec.E_T = 7.2e3;
  ec.nu_T = 0.45;
  ec.nu_LT = 0.3;
  ec.G_L = 4e3;
  return {core::Material::from_lame(lf, 1000), core::Material::from_engineering(ec, 1050),
          core::Material::isotropic(5e4, 0.45, 1000)};
}

Mat3 random_rotation(std::mt19937& rng) {
  std::normal_distribution<double> n;
  Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  return q.normalized().toRotationMatrix();
}

struct Case {
  Vec12 X, x;
  Vec3 fiber;
  core::SpencerElement el;
};

Case random_case(std::mt19937& rng, double stretch) {
  std::uniform_real_distribution<double> u(-1, 1);
  Case c;
  for (int a = 0; a < 4; ++a) c.X.segment<3>(3 * a) = 0.01 * (Vec3::Unit(a == 0 ? 0 : a - 1) * (a == 0 ? 0 : 1) +
                                                                0.3 * Vec3(u(rng), u(rng), u(rng)));
  c.fiber = Vec3(u(rng), u(rng), u(rng)).normalized();
  const Mat3 R = random_rotation(rng);
  Mat3 S = Mat3::Identity();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) S(i, j) += stretch * u(rng);
  const Vec3 t(u(rng), u(rng), u(rng));
  for (int a = 0; a < 4; ++a) c.x.segment<3>(3 * a) = R * S * c.X.segment<3>(3 * a) + t;
  c.el.Dm_inv = core::rest_shape_inverse(c.X);
  for (int j = 0; j < 3; ++j) c.el.Dm.col(j) = c.X.segment<3>(3 * (j + 1)) - c.X.segment<3>(0);
  c.el.fiber = c.fiber;
  Mat3 Dm;
  for (int j = 0; j < 3; ++j) Dm.col(j) = c.X.segment<3>(3 * (j + 1)) - c.X.segment<3>(0);
  c.el.volume = std::abs(Dm.determinant()) / 6.0;
  return c;
}

}  // namespace

TEST(SpencerElement, ConstantsReproduceTheLocalStiffness) {
  // C_ijkl of Spencer's form with f = e3, in Voigt order with engineering shear, must be
  // the material's local 6 x 6 C entry by entry.
  for (const core::Material& m : materials()) {
    const core::SpencerConstants c = core::SpencerConstants::of(m);
    core::Mat6 C;
    const int pairs[6][2] = {{0, 0}, {1, 1}, {2, 2}, {0, 1}, {1, 2}, {2, 0}};
    for (int I = 0; I < 6; ++I) {
      // Column I: stress of the unit engineering strain I.
      Mat3 eps = Mat3::Zero();
      const int k = pairs[I][0], l = pairs[I][1];
      if (k == l) eps(k, l) = 1;
      else eps(k, l) = eps(l, k) = 0.5;
      const Mat3 s = core::spencer_stress(c, Vec3::UnitZ(), eps);
      for (int J = 0; J < 6; ++J) C(J, I) = s(pairs[J][0], pairs[J][1]);
    }
    EXPECT_LT((C - m.stiffness()).norm(), 1e-12 * m.stiffness().norm()) << C << "\n\n" << m.stiffness();
  }
}

TEST(SpencerElement, WarpedBlocksEqualRotatedStoredStiffness) {
  std::mt19937 rng(7);
  for (const core::Material& m : materials()) {
    const core::SpencerConstants c = core::SpencerConstants::of(m);
    for (int trial = 0; trial < 50; ++trial) {
      const Case k = random_case(rng, 0.3);
      const Mat12 K = core::element_stiffness(k.X, m, k.fiber);
      const Mat3 R = random_rotation(rng);
      const double scale = 0.37;
      const Mat12 expected = scale * core::warped_stiffness(R, K);
      // spencer_upper_blocks, as the step calls it (here with T = double, one element).
      const core::SpencerConstants ks = c.scaled(scale * k.el.volume);
      const double kk[5] = {ks.lambda, ks.mu_t, ks.alpha, ks.gamma, ks.beta};
      double Rr[9], Dr[9], out[90];
      for (int r = 0; r < 3; ++r)
        for (int q = 0; q < 3; ++q) {
          Rr[3 * r + q] = R(r, q);
          Dr[3 * r + q] = k.el.Dm_inv(r, q);
        }
      const double fv[3] = {k.fiber(0), k.fiber(1), k.fiber(2)};
      core::spencer_upper_blocks(kk, Rr, Dr, fv, out);
      Mat12 got = Mat12::Zero();
      for (int a = 0; a < 4; ++a)
        for (int b = a; b < 4; ++b)
          for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) got(3 * a + i, 3 * b + j) = out[9 * core::ElementBatch::block_index(a, b) + 3 * i + j];
      for (int a = 0; a < 4; ++a)
        for (int b = a; b < 4; ++b)
          EXPECT_LT((got.block<3, 3>(3 * a, 3 * b) - expected.block<3, 3>(3 * a, 3 * b)).norm(),
                    1e-11 * expected.norm())
              << "block " << a << b << " trial " << trial;
    }
  }
}

TEST(SpencerElement, ForceAndEnergyEqualStoredStiffnessRoute) {
  std::mt19937 rng(11);
  for (const core::Material& m : materials()) {
    const core::SpencerConstants c = core::SpencerConstants::of(m);
    for (int trial = 0; trial < 60; ++trial) {
      // Stretches up to 0.8 of the rest size: some elements come out inverted.
      const Case k = random_case(rng, trial < 30 ? 0.05 : 0.8);
      const Mat12 K = core::element_stiffness(k.X, m, k.fiber);
      const Mat3 F = core::deformation_gradient(k.x, k.el.Dm_inv);
      const Mat3 R = core::rotation_svd(F);
      const Vec12 expected = core::corotated_force(R, K, k.x, k.X);
      Vec12 got;
      double energy = 0;
      core::spencer_force(c, k.el, R, F, got, energy);
      EXPECT_LT((got - expected).norm(), 1e-10 * (expected.norm() + 1e-12)) << "trial " << trial;
      const double e_expected = core::corotated_energy(R, K, k.x, k.X);
      EXPECT_NEAR(energy, e_expected, 1e-10 * std::abs(e_expected) + 1e-300);
      EXPECT_NEAR(core::spencer_energy(c, k.el, R, F), e_expected, 1e-10 * std::abs(e_expected) + 1e-300);
    }
  }
}

TEST(SpencerElement, IsotropicConstantsHaveNoFiberTerms) {
  const core::SpencerConstants c = core::SpencerConstants::of(core::Material::isotropic(5e4, 0.3, 1000));
  EXPECT_EQ(c.alpha, 0.0);
  EXPECT_EQ(c.gamma, 0.0);
  EXPECT_EQ(c.beta, 0.0);
  // Lame: lambda = E nu / ((1 + nu)(1 - 2 nu)), mu = E / (2 (1 + nu)).
  EXPECT_NEAR(c.lambda, 5e4 * 0.3 / (1.3 * 0.4), 1e-8);
  EXPECT_NEAR(c.mu_t, 5e4 / 2.6, 1e-8);
}
