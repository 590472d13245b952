// The closed-form element of the dynamic step (core/spencer_element.hpp) against the
// stored-matrix route of PHYSICS.md section 3 (element_stiffness: V B^T T(Q)^T C T(Q) B,
// corotated_force: -R K (R^T x - X)): two independent derivations of the same operator.
// Random elements, fibers, rotations and deformations (inverted ones included), for the
// paper's Lame-plus-fiber material, engineering constants and an isotropic material.
// spencer_force_lanes (the lane-parallel force kernel) is checked against spencer_force,
// one element and four elements (one per SIMD lane) at a time.

#include "core/corotation.hpp"
#include "core/element.hpp"
#include "core/rotation.hpp"
#include "core/sparse_system.hpp"
#include "core/spencer_element.hpp"
#include "test_support.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <type_traits>
#include <vector>

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

namespace {

using Lanes4 = double __attribute__((vector_size(4 * sizeof(double))));

// One lane's input of spencer_force_lanes and the scalar route's view of the same element.
struct LaneCase {
  core::SpencerConstants c;
  core::SpencerElement el;
  Mat3 R, D, F;  // F = I + D Dm^-1, as the step forms it.
};

// Random element: Dm near 1 cm edges with positive volume, deformed as Q S X + t with
// S = I + stretch * random and Q a random rotation (the identity when variant % 3 == 2);
// R the polar rotation of F, or Q itself (close to it, as the step's approximate
// rotations are) on odd `variant`. Constants are the test materials' (variant % 5 < 3),
// random transversely isotropic ones or random isotropic ones.
LaneCase random_lane_case(std::mt19937& rng, double stretch, int variant) {
  std::uniform_real_distribution<double> u(-1, 1), p(0, 1);
  LaneCase lc;
  Mat3 Dm;
  do {
    Dm = 0.01 * (Mat3::Identity() + 0.4 * Mat3::NullaryExpr([&] { return u(rng); }));
  } while (Dm.determinant() < 0.2e-6);
  const Vec3 X0(u(rng), u(rng), u(rng));
  lc.el.Dm = Dm;
  lc.el.Dm_inv = Dm.inverse();
  lc.el.fiber = Vec3(u(rng), u(rng), u(rng)).normalized();
  lc.el.volume = Dm.determinant() / 6.0;
  const Mat3 Q = variant % 3 == 2 ? Mat3::Identity() : random_rotation(rng);
  const Mat3 S = Mat3::Identity() + stretch * Mat3::NullaryExpr([&] { return u(rng); });
  const Vec3 t(u(rng), u(rng), u(rng));
  const Vec3 x0 = Q * S * X0 + t;
  for (int j = 0; j < 3; ++j) {
    const Vec3 Xj = X0 + Dm.col(j);
    lc.D.col(j) = (Vec3(Q * S * Xj + t) - x0) - Dm.col(j);
  }
  lc.F = lc.D * lc.el.Dm_inv;
  lc.F.diagonal().array() += 1.0;
  lc.R = variant % 2 ? Q : core::rotation_svd(lc.F);
  switch (variant % 5) {
    case 0: case 1: case 2: lc.c = core::SpencerConstants::of(materials()[static_cast<size_t>(variant % 5)]); break;
    case 3: lc.c = {1e5 * p(rng), 1e3 + 1e5 * p(rng), 3e4 * u(rng), 2e4 * u(rng), 1e5 * u(rng)}; break;
    default: lc.c = {1e5 * p(rng), 1e3 + 1e5 * p(rng), 0, 0, 0}; break;
  }
  return lc;
}

template <class T>
void set_lane(T& v, int l, double x) {
  if constexpr (std::is_same_v<T, double>) v = x;
  else v[l] = x;
}

template <class T>
double get_lane(const T& v, int l) {
  if constexpr (std::is_same_v<T, double>) return v;
  else return v[l];
}

// spencer_force_lanes on `cases` (one per lane), returning each lane's forces and energy.
template <class T>
void force_lanes(const std::vector<LaneCase>& cases, std::vector<Vec12>& fe, std::vector<double>& energy) {
  T k[5], R[9], Dm_inv[9], D[9], f[3], out[12], en;
  const int n = static_cast<int>(cases.size());
  for (int l = 0; l < n; ++l) {
    const LaneCase& lc = cases[static_cast<size_t>(l)];
    const core::SpencerConstants ks = lc.c.scaled(lc.el.volume);
    const double kk[5] = {ks.lambda, ks.mu_t, ks.alpha, ks.gamma, ks.beta};
    for (int q = 0; q < 5; ++q) set_lane(k[q], l, kk[q]);
    for (int r = 0; r < 3; ++r)
      for (int q = 0; q < 3; ++q) {
        set_lane(R[3 * r + q], l, lc.R(r, q));
        set_lane(Dm_inv[3 * r + q], l, lc.el.Dm_inv(r, q));
        set_lane(D[3 * r + q], l, lc.D(r, q));
      }
    for (int q = 0; q < 3; ++q) set_lane(f[q], l, lc.el.fiber(q));
  }
  core::spencer_force_lanes(k, R, Dm_inv, D, f, out, en);
  fe.assign(static_cast<size_t>(n), Vec12::Zero());
  energy.assign(static_cast<size_t>(n), 0.0);
  for (int l = 0; l < n; ++l) {
    for (int q = 0; q < 12; ++q) fe[static_cast<size_t>(l)](q) = get_lane(out[q], l);
    energy[static_cast<size_t>(l)] = get_lane(en, l);
  }
}

template <class T>
void check_force_lanes_against_scalar(int lanes) {
  std::mt19937 rng(23);
  for (int trial = 0; trial < 200; ++trial) {
    // Strains of ~1e-3 (near rest) and of up to 0.6 (some elements inverted).
    const double stretch = trial % 2 ? 1e-3 : 0.6;
    std::vector<LaneCase> cases;
    for (int l = 0; l < lanes; ++l) cases.push_back(random_lane_case(rng, stretch, trial + l));
    std::vector<Vec12> got;
    std::vector<double> energy;
    force_lanes<T>(cases, got, energy);
    for (int l = 0; l < lanes; ++l) {
      const LaneCase& lc = cases[static_cast<size_t>(l)];
      Vec12 expected;
      double e_expected = 0;
      core::spencer_force(lc.c, lc.el, lc.R, lc.F, expected, e_expected);
      // The strain is a difference of O(1 + |D| |Dm^-1|) terms (R^T F and I; D Dm^-1
      // carries the rotation), so both routes' round-off is relative to that, not to the
      // strain: under a small strain the tolerance scales with the ratio. (spencer_force's
      // I + D Dm^-1 is the larger error near rest; ForceLanesAreAccurateNearRest.)
      const double ratio =
          std::max(1.0, (1 + lc.D.norm() * lc.el.Dm_inv.norm()) / core::corotated_strain(lc.R, lc.F).norm());
      EXPECT_LT((got[static_cast<size_t>(l)] - expected).norm(), 1e-12 * ratio * expected.norm())
          << "trial " << trial << " lane " << l;
      EXPECT_NEAR(energy[static_cast<size_t>(l)], e_expected, 1e-12 * ratio * std::abs(e_expected))
          << "trial " << trial << " lane " << l;
    }
  }
}

template <class T>
void check_force_lanes_at_rest(int lanes) {
  std::mt19937 rng(29);
  std::vector<LaneCase> cases;
  for (int l = 0; l < lanes; ++l) {
    LaneCase lc = random_lane_case(rng, 0.1, 3 + l);
    lc.D.setZero();
    lc.R.setIdentity();
    cases.push_back(lc);
  }
  std::vector<Vec12> got;
  std::vector<double> energy;
  force_lanes<T>(cases, got, energy);
  for (int l = 0; l < lanes; ++l) {
    for (int q = 0; q < 12; ++q) EXPECT_EQ(got[static_cast<size_t>(l)](q), 0.0) << "lane " << l << " component " << q;
    EXPECT_EQ(energy[static_cast<size_t>(l)], 0.0) << "lane " << l;
  }
  // Near rest the strain is as accurate as the displacement: with R = I, scaling D by
  // 2^-30 scales every force by exactly 2^-30 and the energy by 2^-60 (through
  // I + D Dm^-1 the strain would keep only a few digits of such a displacement).
  std::mt19937 rng2(31);
  for (int l = 0; l < lanes; ++l) {
    cases[static_cast<size_t>(l)].D = 0.1 * random_lane_case(rng2, 0.1, l).D;
  }
  force_lanes<T>(cases, got, energy);
  std::vector<Vec12> tiny_fe;
  std::vector<double> tiny_energy;
  for (LaneCase& lc : cases) lc.D *= std::ldexp(1.0, -30);
  force_lanes<T>(cases, tiny_fe, tiny_energy);
  for (int l = 0; l < lanes; ++l) {
    const size_t i = static_cast<size_t>(l);
    EXPECT_GT(got[i].norm(), 0.0);
    for (int q = 0; q < 12; ++q) EXPECT_EQ(tiny_fe[i](q), std::ldexp(got[i](q), -30)) << "lane " << l << " component " << q;
    EXPECT_EQ(tiny_energy[i], std::ldexp(energy[i], -60)) << "lane " << l;
  }
}

// Forces and energy of `lc` in long double from the same (double) inputs, the strain as
// sym(R^T (I + D Dm^-1)) - I: the reference the round-off of either route is measured by.
void force_long_double(const LaneCase& lc, Eigen::Matrix<long double, 12, 1>& fe, long double& energy) {
  using M3 = Eigen::Matrix<long double, 3, 3>;
  using V3 = Eigen::Matrix<long double, 3, 1>;
  const M3 R = lc.R.cast<long double>(), Dm_inv = lc.el.Dm_inv.cast<long double>();
  M3 F = lc.D.cast<long double>() * Dm_inv;
  F.diagonal().array() += 1;
  const M3 S = R.transpose() * F;
  M3 eps = (S + S.transpose()) / 2;
  eps.diagonal().array() -= 1;
  const V3 f = lc.el.fiber.cast<long double>(), ef = eps * f;
  const long double tr = eps.trace(), fef = f.dot(ef);
  M3 sigma = 2 * static_cast<long double>(lc.c.mu_t) * eps;
  sigma.diagonal().array() += lc.c.lambda * tr + lc.c.alpha * fef;
  sigma += (lc.c.alpha * tr + lc.c.beta * fef) * f * f.transpose();
  sigma += 2 * static_cast<long double>(lc.c.gamma) * (f * ef.transpose() + ef * f.transpose());
  const long double V = lc.el.volume;
  energy = V * sigma.cwiseProduct(eps).sum() / 2;
  const M3 f123 = -V * (R * sigma) * Dm_inv.transpose();
  for (int a = 1; a < 4; ++a) fe.segment<3>(3 * a) = f123.col(a - 1);
  fe.segment<3>(0) = -(f123.col(0) + f123.col(1) + f123.col(2));
}

}  // namespace

TEST(SpencerElement, ForceLanesAreAccurateNearRest) {
  // Unrotated elements (R the polar rotation of F = I + D Dm^-1, so close to I) under
  // strains of 1e-3 .. 1e-5: the forces and energy are accurate relative to the strain,
  // where going through I + D Dm^-1 keeps only ~16 + log10(strain) digits (spencer_force
  // misses 1e-12 here by up to 200 times). The long double reference, which takes that
  // route with 3 more digits, bounds how small the strain can be.
  std::mt19937 rng(37);
  for (double stretch : {1e-3, 1e-4, 1e-5})
    for (int trial = 0; trial < 100; ++trial) {
      std::vector<LaneCase> cases;
      for (int l = 0; l < 4; ++l) cases.push_back(random_lane_case(rng, stretch, 3 * (trial + l) + 2));
      std::vector<Vec12> got;
      std::vector<double> energy;
      force_lanes<Lanes4>(cases, got, energy);
      for (int l = 0; l < 4; ++l) {
        const size_t i = static_cast<size_t>(l);
        Eigen::Matrix<long double, 12, 1> ref;
        long double e_ref;
        force_long_double(cases[i], ref, e_ref);
        EXPECT_LT(static_cast<double>((got[i].cast<long double>() - ref).norm() / ref.norm()), 1e-12)
            << "stretch " << stretch << " trial " << trial << " lane " << l;
        EXPECT_LT(static_cast<double>(std::abs(energy[i] - e_ref) / e_ref), 1e-12)
            << "stretch " << stretch << " trial " << trial << " lane " << l;
      }
    }
}

TEST(SpencerElement, ForceLanesEqualScalarForceOneLane) { check_force_lanes_against_scalar<double>(1); }

TEST(SpencerElement, ForceLanesEqualScalarForceFourLanes) { check_force_lanes_against_scalar<Lanes4>(4); }

TEST(SpencerElement, ForceLanesVanishExactlyAtRestOneLane) { check_force_lanes_at_rest<double>(1); }

TEST(SpencerElement, ForceLanesVanishExactlyAtRestFourLanes) { check_force_lanes_at_rest<Lanes4>(4); }
