// Fiber frames and the Voigt (Bond) strain transform (PHYSICS.md section 3): frames are
// proper rotations with the fiber as third row; T(Q) against the hand-expanded Bond matrix
// and against rotating strain tensors with a Voigt conversion written here; energy
// invariance of C_g; transverse and full isotropy.

#include "core/fiber_frame.hpp"
#include "core/material.hpp"
#include "test_support.hpp"

#include <Eigen/Dense>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace core = fiberfem::core;
using core::Mat3;
using core::Mat6;
using core::Vec3;
using core::Vec6;
using fiberfem::testing::expect_invalid;
using fiberfem::testing::random_rotation;

namespace {

// Independent Voigt conversions (order xx, yy, zz, xy, yz, zx; engineering shear).
Mat3 tensor_of(const Vec6& v) {
  Mat3 e;
  e(0, 0) = v(0);
  e(1, 1) = v(1);
  e(2, 2) = v(2);
  e(0, 1) = e(1, 0) = v(3) / 2;
  e(1, 2) = e(2, 1) = v(4) / 2;
  e(2, 0) = e(0, 2) = v(5) / 2;
  return e;
}
Vec6 voigt_of(const Mat3& e) {
  Vec6 v;
  v << e(0, 0), e(1, 1), e(2, 2), 2 * e(0, 1), 2 * e(1, 2), 2 * e(2, 0);
  return v;
}

Vec6 random_voigt(std::mt19937& rng) {
  std::normal_distribution<double> n(0, 1);
  Vec6 v;
  for (int i = 0; i < 6; ++i) v(i) = n(rng);
  return v;
}

// Fibers to try: random directions of very different lengths, the axes with both signs,
// and directions within 1e-9..1e-3 of an axis (where a naive cross product degenerates).
std::vector<Vec3> test_fibers() {
  std::vector<Vec3> f;
  std::mt19937 rng(31);
  std::normal_distribution<double> n(0, 1);
  std::uniform_real_distribution<double> logscale(-6, 6);
  for (int i = 0; i < 200; ++i) f.push_back(Vec3(n(rng), n(rng), n(rng)) * std::pow(10.0, logscale(rng)));
  for (int d = 0; d < 3; ++d) {
    f.push_back(Vec3::Unit(d));
    f.push_back(-Vec3::Unit(d));
    f.push_back(1e-8 * Vec3::Unit(d));
    for (double eps : {1e-12, 1e-9, 1e-6, 1e-3}) {
      f.push_back(Vec3::Unit(d) + eps * Vec3::Unit((d + 1) % 3));
      f.push_back(-Vec3::Unit(d) + eps * Vec3(1, -1, 1));
    }
  }
  f.push_back(Vec3(1, 1, 1));
  f.push_back(Vec3(1, 1, 0));
  f.push_back(Vec3(0, -1, 1));
  return f;
}

// Rotation about z by theta in the "global to local" sense of frame_from_fiber: rows are
// the local axes (cos, sin, 0), (-sin, cos, 0), (0, 0, 1).
Mat3 frame_about_z(double t) {
  Mat3 Q;
  Q << std::cos(t), std::sin(t), 0, -std::sin(t), std::cos(t), 0, 0, 0, 1;
  return Q;
}

core::Material ti_material() {
  core::EngineeringConstants c;
  c.E_L = 120e3;
  c.E_T = 15e3;
  c.nu_T = 0.45;
  c.nu_LT = 0.35;
  c.G_L = 6e3;
  return core::Material::from_engineering(c, 1000);
}

}  // namespace

TEST(FiberFrame, ProperRotationWithUnitFiberAsThirdRow) {
  for (const Vec3& f : test_fibers()) {
    const Mat3 Q = core::frame_from_fiber(f);
    EXPECT_LT((Q * Q.transpose() - Mat3::Identity()).norm(), 1e-13) << f.transpose();
    EXPECT_NEAR(Q.determinant(), 1.0, 1e-13) << f.transpose();
    EXPECT_LT((Q.row(2).transpose() - f / f.norm()).norm(), 1e-14) << f.transpose();
    // The frame maps the fiber to the local z axis.
    EXPECT_LT((Q * f / f.norm() - Vec3::UnitZ()).norm(), 1e-13) << f.transpose();
  }
}

TEST(FiberFrame, AngleTurnsM1AboutTheFiber) {
  std::mt19937 rng(32);
  const std::vector<Vec3> fibers = test_fibers();
  for (size_t i = 0; i < fibers.size(); i += 7) {
    const Vec3& f = fibers[i];
    const Mat3 Q0 = core::frame_from_fiber(f);
    EXPECT_LT((core::frame_from_fiber(f, 0.0) - Q0).norm(), 1e-15);
    const Vec3 m1 = Q0.row(0), m2 = Q0.row(1);
    for (double a : {0.1, 1.0, -2.0, M_PI, 5.5}) {
      const Mat3 Q = core::frame_from_fiber(f, a);
      // Right-handed turn about m3: m1 -> cos m1 + sin m2, m2 -> -sin m1 + cos m2.
      EXPECT_LT((Q.row(0).transpose() - (std::cos(a) * m1 + std::sin(a) * m2)).norm(), 1e-14) << a;
      EXPECT_LT((Q.row(1).transpose() - (-std::sin(a) * m1 + std::cos(a) * m2)).norm(), 1e-14) << a;
      EXPECT_LT((Q.row(2) - Q0.row(2)).norm(), 1e-15);
      EXPECT_NEAR(Q.determinant(), 1.0, 1e-14);
      // Equivalently Q(a) = Rz(a) Q0 in the rows-are-axes convention.
      EXPECT_LT((Q - frame_about_z(a) * Q0).norm(), 1e-14);
    }
  }
}

TEST(FiberFrame, RejectsZeroAndNonFiniteFibers) {
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  for (const Vec3& f : {Vec3(0, 0, 0), Vec3(nan, 0, 1), Vec3(0, inf, 0), Vec3(-inf, 1, 1)}) {
    expect_invalid([&] { core::frame_from_fiber(f); }, {"fiber direction", "non-zero"});
    expect_invalid([&] { core::frame_from_fiber(f, 0.5); }, {"fiber direction", "finite"});
  }
}

TEST(FiberFrame, VoigtConversionsRoundTripAndMatchHandValues) {
  Vec6 v;
  v << 1, 2, 3, 4, 5, 6;
  Mat3 e;
  e << 1, 2, 3, 2, 2, 2.5, 3, 2.5, 3;
  EXPECT_EQ(core::strain_tensor(v), e);
  EXPECT_EQ(core::strain_voigt(e), v);
  Vec6 s;
  s << 1, 2, 3, 2, 2.5, 3;  // stress: no factor two
  EXPECT_EQ(core::stress_voigt(e), s);
  std::mt19937 rng(33);
  for (int trial = 0; trial < 20; ++trial) {
    const Vec6 r = random_voigt(rng);
    EXPECT_LT((core::strain_voigt(core::strain_tensor(r)) - r).norm(), 1e-14);
    const Mat3 t = tensor_of(r);
    EXPECT_LT((core::strain_tensor(core::strain_voigt(t)) - t).norm(), 1e-14);
    // Strain energy pairing: sigma : eps = stress_voigt(sigma) . strain_voigt(eps).
    const Mat3 sig = tensor_of(random_voigt(rng));
    EXPECT_NEAR(core::stress_voigt(sig).dot(core::strain_voigt(t)), (sig.array() * t.array()).sum(), 1e-12);
  }
}

// The Bond matrix for a rotation about z, expanded by hand from eps'_ij = Q_ik Q_jl eps_kl.
TEST(BondTransform, MatchesHandExpandedRotationAboutZ) {
  for (double t : {0.0, 0.3, M_PI / 4, 1.2, 2.9, -0.7}) {
    const double c = std::cos(t), s = std::sin(t);
    Mat6 expected = Mat6::Zero();
    expected.row(0) << c * c, s * s, 0, c * s, 0, 0;
    expected.row(1) << s * s, c * c, 0, -c * s, 0, 0;
    expected.row(2) << 0, 0, 1, 0, 0, 0;
    expected.row(3) << -2 * c * s, 2 * c * s, 0, c * c - s * s, 0, 0;
    expected.row(4) << 0, 0, 0, 0, c, -s;
    expected.row(5) << 0, 0, 0, 0, s, c;
    EXPECT_LT((core::bond_strain_transform(frame_about_z(t)) - expected).norm(), 1e-14) << t;
  }
}

TEST(BondTransform, AgreesWithRotatingTheStrainTensor) {
  std::mt19937 rng(34);
  for (int trial = 0; trial < 50; ++trial) {
    const Mat3 Q = random_rotation(rng);
    const Mat6 T = core::bond_strain_transform(Q);
    for (int k = 0; k < 3; ++k) {
      const Vec6 eg = random_voigt(rng);
      const Vec6 el = voigt_of(Q * tensor_of(eg) * Q.transpose());
      EXPECT_LT((T * eg - el).norm(), 1e-13 * eg.norm());
    }
  }
}

TEST(BondTransform, IsAGroupRepresentation) {
  std::mt19937 rng(35);
  EXPECT_LT((core::bond_strain_transform(Mat3::Identity()) - Mat6::Identity()).norm(), 1e-15);
  for (int trial = 0; trial < 20; ++trial) {
    const Mat3 A = random_rotation(rng), B = random_rotation(rng);
    const Mat6 TA = core::bond_strain_transform(A), TB = core::bond_strain_transform(B);
    EXPECT_LT((core::bond_strain_transform(A * B) - TA * TB).norm(), 1e-13);
    EXPECT_LT((core::bond_strain_transform(A.transpose()) * TA - Mat6::Identity()).norm(), 1e-13);
  }
}

// eps_g^T C_g eps_g = eps_l^T C eps_l with eps_l = voigt(Q eps_g Q^T).
TEST(RotateStiffness, PreservesStrainEnergy) {
  std::mt19937 rng(36);
  const Mat6 C = ti_material().stiffness();
  for (int trial = 0; trial < 50; ++trial) {
    const Mat3 Q = random_rotation(rng);
    const Mat6 Cg = core::rotate_stiffness(C, Q);
    EXPECT_LT((Cg - Cg.transpose()).norm(), 1e-12 * C.norm());
    const Vec6 eg = random_voigt(rng);
    const Vec6 el = voigt_of(Q * tensor_of(eg) * Q.transpose());
    const double e_local = el.dot(C * el);
    EXPECT_NEAR(eg.dot(Cg * eg), e_local, 1e-12 * std::abs(e_local));
  }
}

TEST(RotateStiffness, IsotropicStiffnessIsUnchanged) {
  std::mt19937 rng(37);
  const Mat6 C = core::Material::isotropic(40e3, 0.42, 1000).stiffness();
  for (int trial = 0; trial < 20; ++trial)
    EXPECT_LT((core::rotate_stiffness(C, random_rotation(rng)) - C).norm(), 1e-12 * C.norm());
}

// Transverse isotropy: turning the frame about the fiber (local z) leaves C unchanged;
// tilting the fiber does not.
TEST(RotateStiffness, TransverselyIsotropicStiffnessIsInvariantAboutTheFiber) {
  const Mat6 C = ti_material().stiffness();
  for (double t : {0.2, 0.9, M_PI / 3, 2.5})
    EXPECT_LT((core::rotate_stiffness(C, frame_about_z(t)) - C).norm(), 1e-12 * C.norm()) << t;
  Mat3 tilt;
  tilt = Eigen::AngleAxisd(0.3, Vec3::UnitX()).toRotationMatrix();
  EXPECT_GT((core::rotate_stiffness(C, tilt) - C).norm(), 1e-3 * C.norm());
}

// Fiber along global x: the global stiffness has the fiber modulus C33 on xx, the
// transverse C11 on yy and zz, the transverse shear C44 on yz and the fiber-plane shear
// C55 on xy and zx.
TEST(RotateStiffness, FiberAlongXPutsTheConstantsWhereExpected) {
  const core::Material m = ti_material();
  const core::StiffnessConstants k = m.constants();
  for (double angle : {0.0, 0.7}) {
    const Mat6 Cg = core::rotate_stiffness(m.stiffness(), core::frame_from_fiber(Vec3(2, 0, 0), angle));
    const double tol = 1e-12 * k.C33;
    EXPECT_NEAR(Cg(0, 0), k.C33, tol);
    EXPECT_NEAR(Cg(1, 1), k.C11, tol);
    EXPECT_NEAR(Cg(2, 2), k.C11, tol);
    EXPECT_NEAR(Cg(1, 2), k.C12, tol);
    EXPECT_NEAR(Cg(0, 1), k.C13, tol);
    EXPECT_NEAR(Cg(0, 2), k.C13, tol);
    EXPECT_NEAR(Cg(4, 4), 0.5 * (k.C11 - k.C12), tol);
    EXPECT_NEAR(Cg(3, 3), k.C55, tol);
    EXPECT_NEAR(Cg(5, 5), k.C55, tol);
    EXPECT_LT((Cg.topRightCorner<3, 3>().norm()), tol);
  }
}
