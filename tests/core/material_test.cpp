// Transversely isotropic material (PHYSICS.md section 2): the three parameterisations
// against closed-form inverses of the compliance, uniaxial and shear load cases built by
// hand, the off-axis Young's modulus, the isotropic special case, and every refusal.

#include "core/material.hpp"
#include "test_support.hpp"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>

#include <cmath>
#include <limits>
#include <random>

namespace core = fiberfem::core;
using core::Mat6;
using core::Vec6;
using fiberfem::testing::expect_invalid;

namespace {

constexpr double kRho = 1060.0;

core::EngineeringConstants ti_constants() {
  core::EngineeringConstants c;
  c.E_L = 150e3;
  c.E_T = 25e3;
  c.nu_T = 0.4;
  c.nu_LT = 0.3;
  c.G_L = 11e3;
  return c;
}

double rel(double a, double b) { return std::abs(a - b) / std::max(std::abs(a), std::abs(b)); }

// The 6x6 stiffness of PHYSICS.md section 2 written out from the five constants.
Mat6 stiffness_from_constants(double C11, double C12, double C13, double C33, double C55) {
  Mat6 C = Mat6::Zero();
  C(0, 0) = C(1, 1) = C11;
  C(0, 1) = C(1, 0) = C12;
  C(0, 2) = C(2, 0) = C(1, 2) = C(2, 1) = C13;
  C(2, 2) = C33;
  C(3, 3) = 0.5 * (C11 - C12);
  C(4, 4) = C(5, 5) = C55;
  return C;
}

// Isotropic Lame stiffness: lambda on the normal block, 2 mu on its diagonal, mu on shears.
Mat6 isotropic_stiffness(double lambda, double mu) {
  Mat6 C = Mat6::Zero();
  C.topLeftCorner<3, 3>().setConstant(lambda);
  for (int i = 0; i < 3; ++i) C(i, i) += 2 * mu;
  for (int i = 3; i < 6; ++i) C(i, i) = mu;
  return C;
}

double min_eigenvalue(const Mat6& A) { return Eigen::SelfAdjointEigenSolver<Mat6>(A).eigenvalues()(0); }

}  // namespace

// Closed-form inverse of the compliance of PHYSICS.md section 2, derived by splitting the
// normal block into the antisymmetric in-plane mode (1, -1, 0) and the 2x2 block on
// span{(1, 1, 0), (0, 0, 1)}: with D = 1 - nu_T - 2 nu_LT^2 E_T / E_L,
//   C11 - C12 = E_T / (1 + nu_T),  C11 + C12 = E_T / D,
//   C13 = nu_LT E_T / D,           C33 = E_L (1 - nu_T) / D,   C55 = G_L.
TEST(Material, EngineeringFormMatchesClosedFormStiffness) {
  const core::EngineeringConstants e = ti_constants();
  const core::Material m = core::Material::from_engineering(e, kRho);
  const double D = 1 - e.nu_T - 2 * e.nu_LT * e.nu_LT * e.E_T / e.E_L;
  const double diff = e.E_T / (1 + e.nu_T), sum = e.E_T / D;
  const Mat6 expected =
      stiffness_from_constants(0.5 * (sum + diff), 0.5 * (sum - diff), e.nu_LT * e.E_T / D, e.E_L * (1 - e.nu_T) / D, e.G_L);
  EXPECT_LT((m.stiffness() - expected).norm(), 1e-12 * expected.norm());
  const core::StiffnessConstants k = m.constants();
  EXPECT_NEAR(k.C11, expected(0, 0), 1e-12 * expected(0, 0));
  EXPECT_NEAR(k.C12, expected(0, 1), 1e-12 * expected(0, 0));
  EXPECT_NEAR(k.C13, expected(0, 2), 1e-12 * expected(0, 0));
  EXPECT_NEAR(k.C33, expected(2, 2), 1e-12 * expected(2, 2));
  EXPECT_NEAR(k.C55, e.G_L, 1e-12 * e.G_L);
  EXPECT_DOUBLE_EQ(m.density_kg_m3(), kRho);
}

TEST(Material, ComplianceEntriesAreTheEngineeringFormulas) {
  const core::EngineeringConstants e = ti_constants();
  const core::Material m = core::Material::from_engineering(e, kRho);
  const Mat6& S = m.compliance();
  const double tol = 1e-12;
  EXPECT_NEAR(S(0, 0) * e.E_T, 1.0, tol);
  EXPECT_NEAR(S(1, 1) * e.E_T, 1.0, tol);
  EXPECT_NEAR(S(2, 2) * e.E_L, 1.0, tol);
  EXPECT_NEAR(S(0, 1) * e.E_T, -e.nu_T, tol);
  EXPECT_NEAR(S(0, 2) * e.E_L, -e.nu_LT, tol);
  EXPECT_NEAR(S(1, 2) * e.E_L, -e.nu_LT, tol);
  EXPECT_NEAR(S(2, 0) * e.E_L, -e.nu_LT, tol);
  EXPECT_NEAR(S(3, 3) * e.E_T, 2 * (1 + e.nu_T), tol);
  EXPECT_NEAR(S(4, 4) * e.G_L, 1.0, tol);
  EXPECT_NEAR(S(5, 5) * e.G_L, 1.0, tol);
  // No coupling between normal and shear parts, nor between shears.
  EXPECT_LT((S.topRightCorner<3, 3>().norm() * e.E_T), tol);
  for (int i = 3; i < 6; ++i)
    for (int j = 3; j < 6; ++j)
      if (i != j) {
        EXPECT_LT(std::abs(S(i, j)) * e.E_T, tol) << i << "," << j;
      }
  EXPECT_LT((m.stiffness() * S - Mat6::Identity()).norm(), 1e-12);
}

// Each column of S is the strain of one unit stress; applying C to the strain written by
// hand from the engineering definitions must give that stress back.
TEST(Material, StiffnessReproducesHandBuiltLoadCases) {
  const core::EngineeringConstants e = ti_constants();
  const core::Material m = core::Material::from_engineering(e, kRho);
  const double s = 1234.0;  // Pa
  Vec6 eps, sigma;
  // Uniaxial along the fiber: eps_T = -nu_LT sigma_L / E_L.
  eps << -e.nu_LT * s / e.E_L, -e.nu_LT * s / e.E_L, s / e.E_L, 0, 0, 0;
  sigma << 0, 0, s, 0, 0, 0;
  EXPECT_LT((m.stiffness() * eps - sigma).norm(), 1e-10 * s);
  // Uniaxial across the fiber (x): in-plane contraction nu_T, fiber contraction by the
  // reciprocal relation nu_TL / E_T = nu_LT / E_L.
  eps << s / e.E_T, -e.nu_T * s / e.E_T, -e.nu_LT * s / e.E_L, 0, 0, 0;
  sigma << s, 0, 0, 0, 0, 0;
  EXPECT_LT((m.stiffness() * eps - sigma).norm(), 1e-10 * s);
  // In-plane shear: G_T = E_T / (2 (1 + nu_T)), engineering shear strain tau / G_T.
  eps << 0, 0, 0, s * 2 * (1 + e.nu_T) / e.E_T, 0, 0;
  sigma << 0, 0, 0, s, 0, 0;
  EXPECT_LT((m.stiffness() * eps - sigma).norm(), 1e-10 * s);
  // Fiber-plane shears: G_L.
  for (int k : {4, 5}) {
    eps.setZero();
    sigma.setZero();
    eps(k) = s / e.G_L;
    sigma(k) = s;
    EXPECT_LT((m.stiffness() * eps - sigma).norm(), 1e-10 * s) << "shear component " << k;
  }
}

// PHYSICS.md section 3: 1/E(theta) = cos^4/E_L + (1/G_L - 2 nu_LT/E_L) sin^2 cos^2 + sin^4/E_T,
// here from the compliance with a uniaxial stress along n = (sin, 0, cos) and, by
// transverse isotropy, along (0, sin, cos).
TEST(Material, OffAxisYoungsModulusFromCompliance) {
  const core::EngineeringConstants e = ti_constants();
  const core::Material m = core::Material::from_engineering(e, kRho);
  for (double theta : {0.0, 0.2, 0.5, M_PI / 4, 1.1, M_PI / 2}) {
    const double c = std::cos(theta), s = std::sin(theta);
    const double expected_inv = std::pow(c, 4) / e.E_L + (1 / e.G_L - 2 * e.nu_LT / e.E_L) * s * s * c * c +
                                std::pow(s, 4) / e.E_T;
    for (int plane = 0; plane < 2; ++plane) {
      const Eigen::Vector3d n = plane == 0 ? Eigen::Vector3d(s, 0, c) : Eigen::Vector3d(0, s, c);
      Vec6 stress;  // Voigt of n n^T (unit uniaxial stress), order xx yy zz xy yz zx
      stress << n.x() * n.x(), n.y() * n.y(), n.z() * n.z(), n.x() * n.y(), n.y() * n.z(), n.z() * n.x();
      const Vec6 g = m.compliance() * stress;  // engineering strain
      const double strain_along_n = g(0) * n.x() * n.x() + g(1) * n.y() * n.y() + g(2) * n.z() * n.z() +
                                    g(3) * n.x() * n.y() + g(4) * n.y() * n.z() + g(5) * n.z() * n.x();
      EXPECT_NEAR(strain_along_n, expected_inv, 1e-12 * expected_inv) << "theta " << theta << " plane " << plane;
    }
  }
}

TEST(Material, LameFormIsThePapersPattern) {
  core::LameFiberConstants l;
  l.lambda = 35e3;
  l.mu = 9e3;
  l.fiber_factor = 3.5;
  l.shear_factor = 1.7;
  const core::Material m = core::Material::from_lame(l, kRho);
  Mat6 expected = isotropic_stiffness(l.lambda, l.mu);
  expected(2, 2) *= l.fiber_factor;
  expected(4, 4) *= l.shear_factor;
  expected(5, 5) *= l.shear_factor;
  EXPECT_LT((m.stiffness() - expected).norm(), 1e-12 * expected.norm());
  EXPECT_FALSE(m.is_isotropic());
  // The same material given as stiffness constants.
  const core::Material k = core::Material::from_stiffness(
      {l.lambda + 2 * l.mu, l.lambda, l.lambda, (l.lambda + 2 * l.mu) * l.fiber_factor, l.mu * l.shear_factor}, kRho);
  EXPECT_LT((k.stiffness() - m.stiffness()).norm(), 1e-12 * expected.norm());
}

// Engineering constants of a material given by its C, from the inverse of the same
// block decomposition: with Dc = (C11 + C12) C33 - 2 C13^2,
//   E_L = Dc / (C11 + C12), nu_LT = C13 / (C11 + C12), G_L = C55,
//   1/E_T = (C33/Dc + 1/(C11 - C12)) / 2,  nu_T / E_T = (1/(C11 - C12) - C33/Dc) / 2.
TEST(Material, EngineeringConstantsOfAStiffnessFormMaterial) {
  const core::StiffnessConstants k{90e3, 30e3, 25e3, 200e3, 14e3};
  const core::Material m = core::Material::from_stiffness(k, kRho);
  const double Dc = (k.C11 + k.C12) * k.C33 - 2 * k.C13 * k.C13;
  const double inv_ET = 0.5 * (k.C33 / Dc + 1 / (k.C11 - k.C12));
  const double nuT_over_ET = 0.5 * (1 / (k.C11 - k.C12) - k.C33 / Dc);
  const core::EngineeringConstants e = m.engineering();
  EXPECT_LT(rel(e.E_L, Dc / (k.C11 + k.C12)), 1e-12);
  EXPECT_LT(rel(e.nu_LT, k.C13 / (k.C11 + k.C12)), 1e-12);
  EXPECT_LT(rel(e.G_L, k.C55), 1e-12);
  EXPECT_LT(rel(e.E_T, 1 / inv_ET), 1e-12);
  EXPECT_LT(rel(e.nu_T, nuT_over_ET / inv_ET), 1e-12);
  // And back: the engineering form of those constants is the same material.
  const core::Material back = core::Material::from_engineering(e, kRho);
  EXPECT_LT((back.stiffness() - m.stiffness()).norm(), 1e-11 * m.stiffness().norm());
}

TEST(Material, EngineeringRoundTrip) {
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> mod(1e3, 1e6), nu(-0.5, 0.49), nulr(0.0, 0.5);
  int tested = 0;
  for (int trial = 0; trial < 200 && tested < 50; ++trial) {
    core::EngineeringConstants e;
    e.E_L = mod(rng);
    e.E_T = mod(rng);
    e.nu_T = nu(rng);
    e.nu_LT = nulr(rng);
    e.G_L = mod(rng);
    if (1 - e.nu_T - 2 * e.nu_LT * e.nu_LT * e.E_T / e.E_L < 0.05) continue;  // well inside the PD region
    ++tested;
    const core::EngineeringConstants r = core::Material::from_engineering(e, kRho).engineering();
    EXPECT_LT(rel(r.E_L, e.E_L), 1e-10);
    EXPECT_LT(rel(r.E_T, e.E_T), 1e-10);
    EXPECT_LT(rel(r.G_L, e.G_L), 1e-10);
    EXPECT_NEAR(r.nu_T, e.nu_T, 1e-10);
    EXPECT_NEAR(r.nu_LT, e.nu_LT, 1e-10);
  }
  EXPECT_EQ(tested, 50);
}

TEST(Material, IsotropicFactoryIsTheLameStiffness) {
  const double E = 50e3, nu = 0.3;
  const double lambda = E * nu / ((1 + nu) * (1 - 2 * nu)), mu = E / (2 * (1 + nu));
  const Mat6 expected = isotropic_stiffness(lambda, mu);
  const core::Material iso = core::Material::isotropic(E, nu, kRho);
  EXPECT_LT((iso.stiffness() - expected).norm(), 1e-12 * expected.norm());
  EXPECT_TRUE(iso.is_isotropic());
  const core::EngineeringConstants r = iso.engineering();
  EXPECT_LT(rel(r.E_L, E), 1e-12);
  EXPECT_LT(rel(r.E_T, E), 1e-12);
  EXPECT_NEAR(r.nu_T, nu, 1e-12);
  EXPECT_NEAR(r.nu_LT, nu, 1e-12);
  EXPECT_LT(rel(r.G_L, mu), 1e-12);

  // The isotropic special case of the engineering form: E_L = E_T, nu_T = nu_LT, G_L = E/(2(1+nu)).
  core::EngineeringConstants e{E, E, nu, nu, mu};
  const core::Material eng = core::Material::from_engineering(e, kRho);
  EXPECT_LT((eng.stiffness() - expected).norm(), 1e-11 * expected.norm());
  EXPECT_TRUE(eng.is_isotropic());

  // And of the Lame form with both factors one.
  core::LameFiberConstants l;
  l.lambda = lambda;
  l.mu = mu;
  const core::Material lame = core::Material::from_lame(l, kRho);
  EXPECT_LT((lame.stiffness() - expected).norm(), 1e-12 * expected.norm());
  EXPECT_TRUE(lame.is_isotropic());
}

TEST(Material, IsIsotropicDetectsEachAnisotropy) {
  core::LameFiberConstants l;
  l.fiber_factor = 1.01;
  EXPECT_FALSE(core::Material::from_lame(l, kRho).is_isotropic());
  l.fiber_factor = 1.0;
  l.shear_factor = 0.99;
  EXPECT_FALSE(core::Material::from_lame(l, kRho).is_isotropic());
  // C13 different from C12 alone.
  EXPECT_FALSE(core::Material::from_stiffness({60e3, 20e3, 21e3, 60e3, 20e3}, kRho).is_isotropic());
  EXPECT_TRUE(core::Material::from_stiffness({60e3, 20e3, 20e3, 60e3, 20e3}, kRho).is_isotropic());
  // G_L off the isotropic value.
  EXPECT_FALSE(core::Material::from_engineering({30e3, 30e3, 0.3, 0.3, 10e3}, kRho).is_isotropic());
  EXPECT_FALSE(core::Material::from_engineering(ti_constants(), kRho).is_isotropic());
}

// The constructor's positive-definiteness test against the eigenvalues of the matrix built
// by hand, on random constants: accepted exactly when the smallest eigenvalue is positive.
TEST(Material, StiffnessFormAcceptsExactlyPositiveDefiniteMatrices) {
  std::mt19937 rng(22);
  std::uniform_real_distribution<double> u(-1.0, 2.0);
  int accepted = 0, refused = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const double C11 = u(rng), C12 = u(rng), C13 = u(rng), C33 = u(rng), C55 = u(rng);
    const double lmin = min_eigenvalue(stiffness_from_constants(C11, C12, C13, C33, C55));
    if (std::abs(lmin) < 1e-9) continue;  // too close to the boundary to call
    bool ok = true;
    try {
      core::Material::from_stiffness({C11, C12, C13, C33, C55}, kRho);
    } catch (const std::invalid_argument&) {
      ok = false;
    }
    EXPECT_EQ(ok, lmin > 0) << "C11=" << C11 << " C12=" << C12 << " C13=" << C13 << " C33=" << C33
                            << " C55=" << C55 << " min eigenvalue " << lmin;
    (ok ? accepted : refused) += 1;
  }
  EXPECT_GT(accepted, 50);
  EXPECT_GT(refused, 50);
}

// Same for the engineering form: accepted exactly when the compliance is positive definite.
TEST(Material, EngineeringFormAcceptsExactlyPositiveDefiniteCompliance) {
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> mod(-0.5, 2.0), nu(-1.5, 1.5);
  int accepted = 0, refused = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    core::EngineeringConstants e{mod(rng), mod(rng), nu(rng), nu(rng), mod(rng)};
    if (std::abs(e.E_L) < 1e-3 || std::abs(e.E_T) < 1e-3 || std::abs(e.G_L) < 1e-3) continue;
    const Mat6 S = fiberfem::testing::engineering_compliance(e);
    const double lmin = min_eigenvalue(S);
    if (std::abs(lmin) < 1e-6) continue;
    bool ok = true;
    try {
      core::Material::from_engineering(e, kRho);
    } catch (const std::invalid_argument&) {
      ok = false;
    }
    EXPECT_EQ(ok, lmin > 0) << "E_L=" << e.E_L << " E_T=" << e.E_T << " nu_T=" << e.nu_T << " nu_LT=" << e.nu_LT
                            << " G_L=" << e.G_L;
    (ok ? accepted : refused) += 1;
  }
  EXPECT_GT(accepted, 50);
  EXPECT_GT(refused, 50);
}

TEST(Material, EngineeringFormRefusalsNameTheConstant) {
  auto with = [](auto change) {
    core::EngineeringConstants e = ti_constants();
    change(e);
    return [e] { core::Material::from_engineering(e, kRho); };
  };
  expect_invalid(with([](auto& e) { e.E_L = 0; }), {"engineering", "E_L must be > 0"});
  expect_invalid(with([](auto& e) { e.E_L = -5; }), {"E_L must be > 0"});
  expect_invalid(with([](auto& e) { e.E_T = -1; }), {"E_T must be > 0"});
  expect_invalid(with([](auto& e) { e.G_L = 0; }), {"G_L must be > 0"});
  expect_invalid(with([](auto& e) { e.nu_T = 1.0; }), {"nu_T", "|nu_T| < 1"});
  expect_invalid(with([](auto& e) { e.nu_T = -1.2; }), {"nu_T", "|nu_T| < 1"});
  // 1 - 0.4 - 2 * 0.9^2 * 25/150 = 0.33 > 0, but nu_LT = 1.5: 1 - 0.4 - 0.75 < 0.
  expect_invalid(with([](auto& e) { e.nu_LT = 1.5; }), {"not positive definite", "1 - nu_T - 2 nu_LT^2 E_T/E_L", "nu_LT=1.5"});
  expect_invalid(with([](auto& e) { e.E_L = std::numeric_limits<double>::quiet_NaN(); }), {"E_L must be finite"});
  expect_invalid(with([](auto& e) { e.E_T = std::numeric_limits<double>::infinity(); }), {"E_T must be finite"});
  expect_invalid(with([](auto& e) { e.nu_T = std::numeric_limits<double>::quiet_NaN(); }), {"nu_T must be finite"});
  expect_invalid(with([](auto& e) { e.nu_LT = std::numeric_limits<double>::infinity(); }), {"nu_LT must be finite"});
  expect_invalid(with([](auto& e) { e.G_L = -std::numeric_limits<double>::infinity(); }), {"G_L must be finite"});
  // Just inside the boundary is accepted.
  core::EngineeringConstants e = ti_constants();
  e.nu_LT = std::sqrt((1 - e.nu_T) * e.E_L / (2 * e.E_T)) * (1 - 1e-6);
  EXPECT_NO_THROW(core::Material::from_engineering(e, kRho));
}

TEST(Material, StiffnessFormRefusalsNameTheConstant) {
  auto make = [](core::StiffnessConstants k) { return [k] { core::Material::from_stiffness(k, kRho); }; };
  expect_invalid(make({20e3, 30e3, 5e3, 50e3, 8e3}), {"C form", "not positive definite", "C11 > C12", "C12=30000"});
  expect_invalid(make({20e3, -25e3, 5e3, 50e3, 8e3}), {"not positive definite", "C11 + C12 > 0"});
  expect_invalid(make({60e3, 20e3, 5e3, 0, 8e3}), {"not positive definite", "C33 > 0", "C33=0"});
  expect_invalid(make({60e3, 20e3, 5e3, 50e3, -8e3}), {"not positive definite", "C55 > 0", "C55=-8000"});
  // (60 + 20) * 50 = 4000 < 2 * 45^2 = 4050 (in 1e6 Pa^2).
  expect_invalid(make({60e3, 20e3, 45e3, 50e3, 8e3}), {"not positive definite", "(C11 + C12) C33 > 2 C13^2", "C13=45000"});
  const double nan = std::numeric_limits<double>::quiet_NaN();
  expect_invalid(make({nan, 20e3, 5e3, 50e3, 8e3}), {"C11 must be finite"});
  expect_invalid(make({60e3, nan, 5e3, 50e3, 8e3}), {"C12 must be finite"});
  expect_invalid(make({60e3, 20e3, nan, 50e3, 8e3}), {"C13 must be finite"});
  expect_invalid(make({60e3, 20e3, 5e3, nan, 8e3}), {"C33 must be finite"});
  expect_invalid(make({60e3, 20e3, 5e3, 50e3, nan}), {"C55 must be finite"});
}

TEST(Material, LameFormRefusalsNameTheConstant) {
  auto with = [](auto change) {
    core::LameFiberConstants l;
    change(l);
    return [l] { core::Material::from_lame(l, kRho); };
  };
  expect_invalid(with([](auto& l) { l.mu = 0; }), {"lame", "mu must be > 0"});
  expect_invalid(with([](auto& l) { l.lambda = -7e3; }), {"lambda", "mu"});  // 3 lambda + 2 mu < 0
  expect_invalid(with([](auto& l) { l.fiber_factor = 0; }), {"fiber_factor must be > 0"});
  expect_invalid(with([](auto& l) { l.shear_factor = -1; }), {"shear_factor must be > 0"});
  expect_invalid(with([](auto& l) { l.lambda = std::numeric_limits<double>::infinity(); }), {"lambda must be finite"});
  expect_invalid(with([](auto& l) { l.fiber_factor = std::numeric_limits<double>::quiet_NaN(); }),
                 {"fiber_factor must be finite"});
  // A small fiber factor with a large lambda is not positive definite:
  // (2 lambda + 2 mu)(lambda + 2 mu) ff = 100e3 * 60e3 * 0.1 < 2 lambda^2 = 3.2e9.
  expect_invalid(with([](auto& l) { l.fiber_factor = 0.1; }), {"lame", "not positive definite", "C13", "C33"});
}

TEST(Material, IsotropicFactoryRefusals) {
  expect_invalid([] { core::Material::isotropic(0, 0.3, kRho); }, {"isotropic", "E must be > 0"});
  expect_invalid([] { core::Material::isotropic(1e3, 0.5, kRho); }, {"nu must be in (-1, 0.5)"});
  expect_invalid([] { core::Material::isotropic(1e3, -1.0, kRho); }, {"nu must be in (-1, 0.5)"});
  expect_invalid([] { core::Material::isotropic(std::numeric_limits<double>::quiet_NaN(), 0.3, kRho); },
                 {"E must be finite"});
  EXPECT_NO_THROW(core::Material::isotropic(1e3, 0.499, kRho));
  EXPECT_NO_THROW(core::Material::isotropic(1e3, -0.9, kRho));
}

TEST(Material, DensityMustBePositiveAndFinite) {
  const core::EngineeringConstants e = ti_constants();
  for (double rho : {0.0, -1.0}) {
    expect_invalid([&] { core::Material::from_engineering(e, rho); }, {"engineering", "density must be > 0"});
    expect_invalid([&] { core::Material::from_lame({}, rho); }, {"lame", "density must be > 0"});
    expect_invalid([&] { core::Material::from_stiffness({60e3, 20e3, 5e3, 50e3, 8e3}, rho); }, {"density must be > 0"});
    // (isotropic() delegates to from_lame(), so its message says "lame form".)
    expect_invalid([&] { core::Material::isotropic(1e3, 0.3, rho); }, {"density must be > 0"});
  }
  for (double rho : {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()})
    expect_invalid([&] { core::Material::from_engineering(e, rho); }, {"density must be finite"});
}
