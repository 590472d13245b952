// Hyperelastic laws (ACCURATE.md section 1). One property suite runs for every law: zero
// stress at rest and under pure dilation, P = dW/dF and A = dP/dF by fourth-order central
// differences, major symmetry, frame invariance, a positive semi-definite tangent at rest;
// with fibers at 0, 30 and 90 degrees, under a 170-degree rotation and near inversion
// (J ~ 0.05). The volumetric and active pieces are checked the same way. Homogeneous
// incompressible biaxial and uniaxial stretches are checked against the strain energy
// written out here in closed form (no isochoric split: J = 1) and differentiated by
// complex step, independently of law.cpp. Every refusal of validate() names its key.

#include "core/hyperelastic/law.hpp"
#include "test_support.hpp"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <cmath>
#include <complex>
#include <functional>
#include <string>
#include <vector>

namespace hyper = fiberfem::core::hyperelastic;
using fiberfem::core::Mat3;
using fiberfem::core::Vec3;
using fiberfem::testing::expect_invalid;
using hyper::LawKind;
using hyper::LawParameters;
using hyper::MaterialAxes;
using hyper::Mat9;
using hyper::Response;

namespace {

constexpr double kPi = 3.14159265358979323846;
using Vec9 = Eigen::Matrix<double, 9, 1>;
using Cplx = std::complex<double>;
using Mat3c = Eigen::Matrix<Cplx, 3, 3>;

double radians(double degrees) { return degrees * kPi / 180; }

// ------------------------------------------------------------------ the laws under test
struct LawCase {
  std::string name;
  LawParameters law;
};

LawParameters with_bulk(LawParameters p) {
  p.bulk_modulus_pa = 1e6;
  return p;
}

void PrintTo(const LawCase& c, std::ostream* os) { *os << c.name; }

std::vector<LawCase> all_laws() {
  LawParameters neo;
  neo.kind = LawKind::neo_hookean;
  neo.mu_pa = 10e3;
  LawParameters land1;  // Land et al. 2015 problems 1 and 3 (the defaults).
  land1.kind = LawKind::guccione;
  LawParameters land2 = land1;  // Land et al. 2015 problem 2.
  land2.guccione_c_pa = 10e3;
  land2.guccione_b_f = land2.guccione_b_t = land2.guccione_b_fs = 1;
  LawParameters ho;  // Holzapfel and Ogden 2009 (the defaults).
  ho.kind = LawKind::holzapfel_ogden;
  return {{"neo_hookean", with_bulk(neo)},
          {"guccione_land_1", with_bulk(land1)},
          {"guccione_land_2", with_bulk(land2)},
          {"holzapfel_ogden", with_bulk(ho)}};
}

// Fiber at `degrees` from the first in-plane axis of a plane tilted out of the coordinate
// planes, sheet in that plane: no axis of the frame lines up with the coordinates.
MaterialAxes tilted_axes(double degrees) {
  const Eigen::AngleAxisd tilt(0.4, Vec3(1, 2, 3).normalized());
  const double c = std::cos(radians(degrees)), s = std::sin(radians(degrees));
  return MaterialAxes::from(tilt * Vec3(c, s, 0), tilt * Vec3(-s, c, 0));
}

struct NamedF {
  std::string name;
  Mat3 F;
};

std::vector<NamedF> deformations() {
  Mat3 moderate;
  moderate << 1.15, 0.08, -0.05, -0.06, 0.9, 0.07, 0.04, 0.09, 1.12;
  Mat3 stretch;  // symmetric, positive definite
  stretch << 1.2, 0.1, 0.05, 0.1, 0.9, -0.08, 0.05, -0.08, 1.05;
  const Mat3 rotated = Eigen::AngleAxisd(radians(170), Vec3(1, -2, 1).normalized()).toRotationMatrix() * stretch;
  Mat3 near_inversion;  // det = 0.04925
  near_inversion << 0.3, 0.1, 0.0, 0.05, 0.5, 0.1, 0.0, 0.05, 0.35;
  return {{"moderate", moderate}, {"rotated_170", rotated}, {"near_inversion", near_inversion}};
}

const double kFiberAngles[] = {0, 30, 90};

// ------------------------------------------------------------------ finite differences
// Fourth-order central differences: error ~ h^4, so h = 1e-4 keeps both truncation and
// rounding near 1e-10 relative for these exponential laws.
constexpr double kStep = 1e-4;

template <class Fn>
auto central_difference(Fn f, double h) {
  return (8 * (f(h) - f(-h)) - (f(2 * h) - f(-2 * h))) / (12 * h);
}

Mat3 energy_gradient_fd(const std::function<double(const Mat3&)>& W, const Mat3& F) {
  Mat3 g;
  for (int L = 0; L < 3; ++L)
    for (int k = 0; k < 3; ++k)
      g(k, L) = central_difference(
          [&](double h) {
            Mat3 Fh = F;
            Fh(k, L) += h;
            return W(Fh);
          },
          kStep);
  return g;
}

Mat9 stress_jacobian_fd(const std::function<Mat3(const Mat3&)>& P, const Mat3& F) {
  Mat9 A;
  for (int L = 0; L < 3; ++L)
    for (int k = 0; k < 3; ++k) {
      const Mat3 column = central_difference(
          [&](double h) {
            Mat3 Fh = F;
            Fh(k, L) += h;
            return Mat3(P(Fh));
          },
          kStep);
      A.col(k + 3 * L) = Eigen::Map<const Vec9>(column.data());
    }
  return A;
}

// max |a - b| within `rel` of max |b| (the scale of the quantity compared).
template <class A, class B>
void expect_near_rel(const A& a, const B& b, double rel, const std::string& what) {
  const double scale = b.cwiseAbs().maxCoeff();
  const double err = (a - b).cwiseAbs().maxCoeff();
  EXPECT_LE(err, rel * scale) << what << ": max error " << err << " against max " << scale;
}

// ------------------------------------------------------------------ the property suite
class LawProperties : public ::testing::TestWithParam<LawCase> {
 protected:
  const LawParameters& law() const { return GetParam().law; }
  Response response(const MaterialAxes& ax, const Mat3& F, bool tangent = true) const {
    return hyper::isochoric_response(law(), ax, F, tangent);
  }
  // A stress scale of the law: the largest entry of its tangent at rest.
  double modulus() const { return response(MaterialAxes{}, Mat3::Identity()).A.cwiseAbs().maxCoeff(); }

  // Runs `check` for every fiber angle and every deformation.
  void for_each_state(const std::function<void(const MaterialAxes&, const Mat3&, const std::string&)>& check) const {
    for (double deg : kFiberAngles)
      for (const NamedF& d : deformations())
        check(tilted_axes(deg), d.F, d.name + " fiber " + std::to_string(int(deg)) + " deg");
  }
};

TEST_P(LawProperties, ZeroEnergyAndStressAtRestAndUnderPureDilation) {
  ASSERT_NO_THROW(law().validate());
  for (double deg : kFiberAngles)
    for (double c : {1.0, 0.5, 1.7}) {
      const Response r = response(tilted_axes(deg), c * Mat3::Identity());
      EXPECT_NEAR(r.energy_j_m3, 0, 1e-12 * modulus()) << "c " << c;
      EXPECT_LE(r.P.cwiseAbs().maxCoeff(), 1e-12 * modulus()) << "c " << c;
    }
}

TEST_P(LawProperties, TangentAtRestIsPositiveSemidefinite) {
  for (double deg : kFiberAngles) {
    const Mat9 A = response(tilted_axes(deg), Mat3::Identity()).A;
    const double lowest = Eigen::SelfAdjointEigenSolver<Mat9>(0.5 * (A + A.transpose())).eigenvalues()(0);
    EXPECT_GE(lowest, -1e-12 * modulus()) << deg << " deg";
  }
}

TEST_P(LawProperties, StressIsTheDerivativeOfTheEnergy) {
  for_each_state([&](const MaterialAxes& ax, const Mat3& F, const std::string& where) {
    const auto W = [&](const Mat3& G) { return response(ax, G, false).energy_j_m3; };
    expect_near_rel(response(ax, F).P, energy_gradient_fd(W, F), 1e-7, where);
  });
}

TEST_P(LawProperties, TangentIsTheDerivativeOfTheStress) {
  for_each_state([&](const MaterialAxes& ax, const Mat3& F, const std::string& where) {
    const auto P = [&](const Mat3& G) { return response(ax, G, false).P; };
    expect_near_rel(response(ax, F).A, stress_jacobian_fd(P, F), 1e-7, where);
  });
}

TEST_P(LawProperties, StressWithoutTangentIsTheSameAndLeavesTheTangentZero) {
  for_each_state([&](const MaterialAxes& ax, const Mat3& F, const std::string& where) {
    const Response full = response(ax, F, true), forces = response(ax, F, false);
    EXPECT_EQ(full.energy_j_m3, forces.energy_j_m3) << where;
    EXPECT_TRUE(full.P == forces.P) << where;
    EXPECT_TRUE(forces.A.isZero(0)) << where;
  });
}

TEST_P(LawProperties, TangentHasMajorSymmetry) {
  for_each_state([&](const MaterialAxes& ax, const Mat3& F, const std::string& where) {
    const Mat9 A = response(ax, F).A;
    expect_near_rel(A, Mat9(A.transpose()), 1e-12, where);
  });
}

// W(QF) = W(F), P(QF) = Q P(F), and A(QF)[Q dF] = Q A(F)[dF].
TEST_P(LawProperties, FrameInvariance) {
  const Mat3 Q = Eigen::AngleAxisd(2.1, Vec3(0.3, -1, 0.5).normalized()).toRotationMatrix();
  Mat3 dF;
  dF << 0.3, -0.2, 0.1, 0.05, 0.4, -0.3, 0.2, 0.1, -0.1;
  const auto apply = [](const Mat9& A, const Mat3& X) {
    const Vec9 y = A * Eigen::Map<const Vec9>(X.data());
    return Mat3(Eigen::Map<const Mat3>(y.data()));
  };
  for_each_state([&](const MaterialAxes& ax, const Mat3& F, const std::string& where) {
    const Response r = response(ax, F), rq = response(ax, Q * F);
    EXPECT_NEAR(rq.energy_j_m3, r.energy_j_m3, 1e-12 * std::abs(r.energy_j_m3)) << where;
    expect_near_rel(rq.P, Mat3(Q * r.P), 1e-12, where);
    expect_near_rel(apply(rq.A, Q * dF), Mat3(Q * apply(r.A, dF)), 1e-12, where);
  });
}

// The isochoric part sees only Cbar: W(cF) = W(F), so P(cF) = P(F) / c.
TEST_P(LawProperties, IsochoricPartIgnoresPureDilation) {
  for (double c : {0.6, 1.5})
    for_each_state([&](const MaterialAxes& ax, const Mat3& F, const std::string& where) {
      const Response r = response(ax, F), rc = response(ax, c * F);
      EXPECT_NEAR(rc.energy_j_m3, r.energy_j_m3, 1e-12 * std::abs(r.energy_j_m3)) << where;
      expect_near_rel(Mat3(c * rc.P), r.P, 1e-12, where + " c " + std::to_string(c));
    });
}

// A wild Newton iterate (stretch 20 across, J = 0.04) gets a finite stress and tangent.
TEST_P(LawProperties, ExtremeDistortionStaysFinite) {
  const Mat3 F = Eigen::Vector3d(20, 0.2, 0.01).asDiagonal();
  for (double deg : kFiberAngles) {
    const Response r = response(tilted_axes(deg), F);
    EXPECT_TRUE(std::isfinite(r.energy_j_m3)) << deg;
    EXPECT_TRUE(r.P.allFinite()) << deg;
    EXPECT_TRUE(r.A.allFinite()) << deg;
  }
}

INSTANTIATE_TEST_SUITE_P(EveryLaw, LawProperties, ::testing::ValuesIn(all_laws()),
                         [](const ::testing::TestParamInfo<LawCase>& info) { return info.param.name; });

// Holzapfel-Ogden's fiber and sheet terms act only while I4 > 1; (I4 - 1)^2 keeps the
// stress continuous where they switch on (C^1), the tangent jumps there.
TEST(HolzapfelOgden, FiberAndSheetTermsActOnlyInTension) {
  LawParameters ho = with_bulk(LawParameters{});
  ho.kind = LawKind::holzapfel_ogden;
  const MaterialAxes ax;  // fiber e1, sheet e2
  const auto uniaxial = [](int axis, double l) {
    Vec3 d = Vec3::Constant(1 / std::sqrt(l));
    d(axis) = l;
    return Mat3(d.asDiagonal());
  };
  for (auto [axis, a_field] : {std::pair{0, &LawParameters::ho_a_f_pa}, {1, &LawParameters::ho_a_s_pa}}) {
    LawParameters without = ho;
    without.*a_field = 0;
    const auto W = [&](const LawParameters& law, double l) {
      return hyper::isochoric_response(law, ax, uniaxial(axis, l), false).energy_j_m3;
    };
    EXPECT_DOUBLE_EQ(W(ho, 0.9), W(without, 0.9)) << "axis " << axis << " shortened: term off";
    EXPECT_GT(W(ho, 1.1) - W(without, 1.1), 0.01 * W(without, 1.1)) << "axis " << axis << " stretched: term on";
    const Response below = hyper::isochoric_response(ho, ax, uniaxial(axis, 1 - 1e-9), true);
    const Response above = hyper::isochoric_response(ho, ax, uniaxial(axis, 1 + 1e-9), true);
    EXPECT_LE((above.P - below.P).cwiseAbs().maxCoeff(), 1e-6 * ho.*a_field) << "axis " << axis;
    EXPECT_GT((above.A - below.A).cwiseAbs().maxCoeff(), 0.5 * ho.*a_field) << "axis " << axis;
  }
}

// ------------------------------------------------------------------ volumetric and active pieces
TEST(VolumetricPenalty, IsZeroWithZeroSlopeAtJ1AndItsDerivativesMatch) {
  const double kappa = 3e5;
  const hyper::Volumetric at_rest = hyper::volumetric_penalty(kappa, 1.0);
  EXPECT_EQ(at_rest.U, 0);
  EXPECT_EQ(at_rest.dU, 0);
  EXPECT_DOUBLE_EQ(at_rest.d2U, kappa);  // the bulk modulus is the curvature at rest
  for (double J : {0.05, 0.7, 1.3, 2.0}) {
    const hyper::Volumetric v = hyper::volumetric_penalty(kappa, J);
    const double h = 1e-4 * J;
    EXPECT_NEAR(v.dU, central_difference([&](double d) { return hyper::volumetric_penalty(kappa, J + d).U; }, h),
                1e-8 * std::abs(v.dU))
        << J;
    EXPECT_NEAR(v.d2U, central_difference([&](double d) { return hyper::volumetric_penalty(kappa, J + d).dU; }, h),
                1e-8 * v.d2U)
        << J;
    EXPECT_GT(v.U, 0) << J;
  }
}

TEST(VolumetricStress, PenaltyStressAndTangentAreDerivativesOfUOfJ) {
  const double kappa = 3e5;
  for (const NamedF& d : deformations()) {
    const auto stress = [&](const Mat3& F, bool tangent) {
      const hyper::Volumetric v = hyper::volumetric_penalty(kappa, F.determinant());
      Response r;
      hyper::add_volumetric_stress(v.dU, v.d2U, F, r, tangent);
      return r;
    };
    const auto U = [&](const Mat3& F) { return hyper::volumetric_penalty(kappa, F.determinant()).U; };
    const Response r = stress(d.F, true);
    expect_near_rel(r.P, energy_gradient_fd(U, d.F), 1e-7, d.name);
    expect_near_rel(r.A, stress_jacobian_fd([&](const Mat3& F) { return stress(F, false).P; }, d.F), 1e-7, d.name);
    expect_near_rel(r.A, Mat9(r.A.transpose()), 1e-12, d.name);
  }
}

// A mixed formulation's pressure p held fixed: P = -p J F^-T, the derivative of -p (J - 1).
TEST(VolumetricStress, FixedPressureStressAndTangentAreDerivativesOfMinusPJ) {
  const double p = 2e3;
  for (const NamedF& d : deformations()) {
    const auto stress = [&](const Mat3& F, bool tangent) {
      Response r;
      hyper::add_volumetric_stress(-p, 0, F, r, tangent);
      return r;
    };
    const Response r = stress(d.F, true);
    expect_near_rel(r.P, Mat3(-p * d.F.determinant() * d.F.inverse().transpose()), 1e-12, d.name);
    expect_near_rel(r.P, energy_gradient_fd([&](const Mat3& F) { return -p * (F.determinant() - 1); }, d.F), 1e-7,
                    d.name);
    expect_near_rel(r.A, stress_jacobian_fd([&](const Mat3& F) { return stress(F, false).P; }, d.F), 1e-7, d.name);
  }
}

TEST(Cofactor, IsJTimesInverseTransposeAndTheDerivativeOfJ) {
  for (const NamedF& d : deformations()) {
    const Mat3 cof = hyper::cofactor(d.F);
    expect_near_rel(cof, Mat3(d.F.determinant() * d.F.inverse().transpose()), 1e-13, d.name);
    expect_near_rel(cof, energy_gradient_fd([](const Mat3& F) { return F.determinant(); }, d.F), 1e-9, d.name);
  }
  Mat3 singular;  // rank 2: the third column is the sum of the first two
  singular << 1, 2, 3, 0, 1, 1, 2, 0, 2;
  const Mat3 cof = hyper::cofactor(singular);
  EXPECT_TRUE(cof.allFinite());
  EXPECT_GT(cof.norm(), 0);
  EXPECT_LE((singular.transpose() * cof).cwiseAbs().maxCoeff(), 1e-14);
}

// S_a = T_a f0 (x) f0 is, at fixed T_a, the derivative of T_a/2 (f0 . C f0 - 1).
TEST(ActiveStress, IsTaFf0f0AndItsTangentIsItsDerivative) {
  const double Ta = 60e3;
  for (double deg : kFiberAngles)
    for (const NamedF& d : deformations()) {
      const Vec3 f0 = tilted_axes(deg).f;
      const std::string where = d.name + " fiber " + std::to_string(int(deg));
      const auto stress = [&](const Mat3& F, bool tangent) {
        Response r;
        hyper::add_active_stress(Ta, f0, F, r, tangent);
        return r;
      };
      const Response r = stress(d.F, true);
      expect_near_rel(r.P, Mat3(Ta * d.F * f0 * f0.transpose()), 1e-14, where);
      const auto W = [&](const Mat3& F) { return 0.5 * Ta * (f0.dot(F.transpose() * F * f0) - 1); };
      expect_near_rel(r.P, energy_gradient_fd(W, d.F), 1e-9, where);
      expect_near_rel(r.A, stress_jacobian_fd([&](const Mat3& F) { return stress(F, false).P; }, d.F), 1e-9, where);
    }
}

// The pieces add onto what the response already holds.
TEST(Pieces, AddToAnExistingResponse) {
  const LawCase neo = all_laws()[0];
  const Mat3 F = deformations()[0].F;
  const Vec3 f0 = tilted_axes(30).f;
  Response r = hyper::isochoric_response(neo.law, tilted_axes(30), F, true);
  const Response iso = r;
  hyper::add_volumetric_stress(-1e3, 0, F, r, true);
  hyper::add_active_stress(5e3, f0, F, r, true);
  Response pieces;
  hyper::add_volumetric_stress(-1e3, 0, F, pieces, true);
  hyper::add_active_stress(5e3, f0, F, pieces, true);
  expect_near_rel(r.P, Mat3(iso.P + pieces.P), 1e-15, "P");
  expect_near_rel(r.A, Mat9(iso.A + pieces.A), 1e-15, "A");
  EXPECT_EQ(r.energy_j_m3, iso.energy_j_m3);
}

// ------------------------------------------------------------------ material axes
TEST(MaterialAxes, SheetIsMadeOrthogonalToTheFiberAndTheFrameIsRightHanded) {
  const MaterialAxes ax = MaterialAxes::from(Vec3(2, 0, 0), Vec3(1, 3, 0));
  EXPECT_TRUE(ax.f.isApprox(Vec3::UnitX()));
  EXPECT_TRUE(ax.s.isApprox(Vec3::UnitY()));
  EXPECT_TRUE(ax.n.isApprox(Vec3::UnitZ()));
  for (const Vec3& sheet : {Vec3(0, 0, 0), Vec3(-3, 0, 0), Vec3(0.4, 0.2, -0.7)}) {
    const MaterialAxes a = MaterialAxes::from(Vec3(1, 2, -0.5), sheet);
    Mat3 R;
    R << a.f, a.s, a.n;
    EXPECT_TRUE((R.transpose() * R).isIdentity(1e-14)) << sheet.transpose();
    EXPECT_NEAR(R.determinant(), 1, 1e-14) << sheet.transpose();
    EXPECT_TRUE(a.f.isApprox(Vec3(1, 2, -0.5).normalized()));
  }
  // The sheet stays in the plane of fiber and given sheet, on the sheet's side.
  const MaterialAxes a = MaterialAxes::from(Vec3(1, 2, -0.5), Vec3(0.4, 0.2, -0.7));
  EXPECT_NEAR(a.n.dot(Vec3(0.4, 0.2, -0.7)), 0, 1e-14);
  EXPECT_GT(a.s.dot(Vec3(0.4, 0.2, -0.7)), 0);
  expect_invalid([] { MaterialAxes::from(Vec3::Zero()); }, {"fiber"});
}

// ------------------------------------------------------------------ validation
TEST(LawParameters, DefaultsOfEachLawAreValidOnceTheRequiredFieldsAreSet) {
  for (const LawCase& c : all_laws()) EXPECT_NO_THROW(c.law.validate()) << c.name;
  LawParameters incompressible;
  incompressible.kind = LawKind::guccione;
  incompressible.incompressible = true;  // no bulk modulus needed
  EXPECT_NO_THROW(incompressible.validate());
  LawParameters neo;
  expect_invalid([&] { neo.validate(); }, {"material.mu"});  // mu has no usable default
}

TEST(LawParameters, EveryBadFieldIsNamed) {
  struct Bad {
    LawKind kind;
    double LawParameters::*field;
    double value;
    const char* key;
  };
  const double nan = std::nan("");
  const Bad cases[] = {
      {LawKind::neo_hookean, &LawParameters::mu_pa, 0, "material.mu must be > 0"},
      {LawKind::neo_hookean, &LawParameters::mu_pa, nan, "material.mu must be > 0"},
      {LawKind::guccione, &LawParameters::guccione_c_pa, -1, "material.C must be > 0"},
      {LawKind::guccione, &LawParameters::guccione_b_f, -0.5, "material.b_f must be >= 0"},
      {LawKind::guccione, &LawParameters::guccione_b_t, nan, "material.b_t must be >= 0"},
      {LawKind::guccione, &LawParameters::guccione_b_fs, -2, "material.b_fs must be >= 0"},
      {LawKind::holzapfel_ogden, &LawParameters::ho_a_pa, 0, "material.a must be > 0"},
      {LawKind::holzapfel_ogden, &LawParameters::ho_b, 0, "material.b must be > 0"},
      {LawKind::holzapfel_ogden, &LawParameters::ho_a_f_pa, -1, "material.a_f must be >= 0"},
      {LawKind::holzapfel_ogden, &LawParameters::ho_b_f, 0, "material.b_f must be > 0"},
      {LawKind::holzapfel_ogden, &LawParameters::ho_a_s_pa, -1, "material.a_s must be >= 0"},
      {LawKind::holzapfel_ogden, &LawParameters::ho_b_s, -3, "material.b_s must be > 0"},
      {LawKind::holzapfel_ogden, &LawParameters::ho_a_fs_pa, INFINITY, "material.a_fs must be >= 0"},
      {LawKind::holzapfel_ogden, &LawParameters::ho_b_fs, 0, "material.b_fs must be > 0"},
  };
  for (const Bad& bad : cases)
    for (LawParameters p : {with_bulk(LawParameters{}), LawParameters{}}) {
      p.kind = bad.kind;
      p.mu_pa = 1e3;
      p.incompressible = p.bulk_modulus_pa == 0;
      p.*bad.field = bad.value;
      expect_invalid([&] { p.validate(); }, {bad.key});
    }
  for (double kappa : {0.0, -1e5, nan}) {
    LawParameters p;
    p.mu_pa = 1e3;
    p.bulk_modulus_pa = kappa;
    expect_invalid([&] { p.validate(); }, {"material.bulk_modulus must be > 0", "unless material.incompressible"});
  }
}

TEST(LawParameters, OnlyTheChosenLawsFieldsAreChecked) {
  LawParameters p = with_bulk(LawParameters{});
  p.kind = LawKind::guccione;
  p.mu_pa = -1;      // a neo-Hookean field
  p.ho_b = 0;        // a Holzapfel-Ogden field
  EXPECT_NO_THROW(p.validate());
}

// ------------------------------------------------------------------ homogeneous stretches
// The strain energy written out from its definition for an isochoric F (J = 1, so
// Cbar = C), fiber f = (cos t, sin t, 0), sheet s = (-sin t, cos t, 0), normal e3, in any
// scalar type so that complex-step differentiation gives its exact derivatives.
template <class T>
T closed_form_energy(const LawParameters& law, double theta, const Eigen::Matrix<T, 3, 3>& F) {
  const Eigen::Matrix<T, 3, 3> C = F.transpose() * F;
  const double c = std::cos(theta), s = std::sin(theta);
  const T I1 = C(0, 0) + C(1, 1) + C(2, 2);
  const T I4f = c * c * C(0, 0) + 2 * c * s * C(0, 1) + s * s * C(1, 1);
  const T I4s = s * s * C(0, 0) - 2 * c * s * C(0, 1) + c * c * C(1, 1);
  const T I8fs = -c * s * C(0, 0) + (c * c - s * s) * C(0, 1) + c * s * C(1, 1);
  const T Cfn = c * C(0, 2) + s * C(1, 2), Csn = -s * C(0, 2) + c * C(1, 2);
  switch (law.kind) {
    case LawKind::neo_hookean: return law.mu_pa / 2 * (I1 - 3.0);
    case LawKind::guccione: {
      const T Eff = (I4f - 1.0) / 2.0, Ess = (I4s - 1.0) / 2.0, Enn = (C(2, 2) - 1.0) / 2.0;
      const T Efs = I8fs / 2.0, Efn = Cfn / 2.0, Esn = Csn / 2.0;
      const T Q = law.guccione_b_f * Eff * Eff + law.guccione_b_t * (Ess * Ess + Enn * Enn + 2.0 * Esn * Esn) +
                  law.guccione_b_fs * (2.0 * Efs * Efs + 2.0 * Efn * Efn);
      return law.guccione_c_pa / 2 * (std::exp(Q) - 1.0);
    }
    case LawKind::holzapfel_ogden: {
      const auto term = [](double a, double b, T x) { return a / (2 * b) * (std::exp(b * x * x) - 1.0); };
      T W = law.ho_a_pa / (2 * law.ho_b) * (std::exp(law.ho_b * (I1 - 3.0)) - 1.0);
      if (std::real(I4f) > 1) W += term(law.ho_a_f_pa, law.ho_b_f, I4f - 1.0);
      if (std::real(I4s) > 1) W += term(law.ho_a_s_pa, law.ho_b_s, I4s - 1.0);
      return W + term(law.ho_a_fs_pa, law.ho_b_fs, I8fs);
    }
  }
  return T(0);
}

// Cauchy stress of an isochoric F from the closed form: sigma = dW/dF F^T, every
// dW/dF_kL by complex step (exact to rounding). Defined up to a pressure, like any
// incompressible stress: only differences of normal stresses and shears are compared.
constexpr double kComplexStep = 1e-30;
Mat3 closed_form_cauchy(const LawParameters& law, double theta, const Mat3& F) {
  Mat3 P;
  for (int L = 0; L < 3; ++L)
    for (int k = 0; k < 3; ++k) {
      Mat3c Fc = F.cast<Cplx>();
      Fc(k, L) += Cplx(0, kComplexStep);
      P(k, L) = std::imag(closed_form_energy(law, theta, Fc)) / kComplexStep;
    }
  return P * F.transpose();
}

// sigma = P F^T / J of law.cpp's isochoric response, fiber and sheet in the 1-2 plane.
Mat3 law_cauchy(const LawParameters& law, double theta, const Mat3& F) {
  const MaterialAxes ax =
      MaterialAxes::from(Vec3(std::cos(theta), std::sin(theta), 0), Vec3(-std::sin(theta), std::cos(theta), 0));
  return hyper::isochoric_response(law, ax, F, false).P * F.transpose() / F.determinant();
}

// The pressure-independent part: sigma_11 - sigma_33, sigma_22 - sigma_33, sigma_12.
Eigen::Vector3d measurable(const Mat3& sigma) {
  return {sigma(0, 0) - sigma(2, 2), sigma(1, 1) - sigma(2, 2), sigma(0, 1)};
}

class HomogeneousStretch : public ::testing::TestWithParam<LawCase> {};

bool anisotropic(const LawParameters& law) {
  const bool isotropic_guccione = law.guccione_b_f == law.guccione_b_t && law.guccione_b_t == law.guccione_b_fs;
  return law.kind == LawKind::holzapfel_ogden || (law.kind == LawKind::guccione && !isotropic_guccione);
}

// F = diag(l1, l2, 1/(l1 l2)). sigma_11 - sigma_33 = l1 dW/dl1 and sigma_22 - sigma_33 =
// l2 dW/dl2 with l3 eliminated, sigma_12 = l2 dW/dF_12 (a shear that keeps J = 1).
TEST_P(HomogeneousStretch, BiaxialMatchesTheStrainEnergyDifferentiatedDirectly) {
  const LawParameters& law = GetParam().law;
  double theta = 0;
  const auto W = [&](Cplx l1, Cplx l2, Cplx shear) {
    Mat3c F = Mat3c::Zero();
    F(0, 0) = l1, F(1, 1) = l2, F(2, 2) = 1.0 / (l1 * l2), F(0, 1) = shear;
    return closed_form_energy(law, theta, F);
  };
  const Cplx ih(0, kComplexStep);
  for (double deg : kFiberAngles)
    for (const auto& [l1, l2] : {std::pair{1.1, 1.05}, {1.15, 0.95}, {0.92, 1.08}}) {
      theta = radians(deg);
      const Eigen::Vector3d expected(l1 * std::imag(W(l1 + ih, l2, 0)) / kComplexStep,
                                     l2 * std::imag(W(l1, l2 + ih, 0)) / kComplexStep,
                                     l2 * std::imag(W(l1, l2, ih)) / kComplexStep);
      const Mat3 F = Eigen::Vector3d(l1, l2, 1 / (l1 * l2)).asDiagonal();
      const std::string where = std::to_string(l1) + " x " + std::to_string(l2) + " fiber " + std::to_string(int(deg));
      expect_near_rel(measurable(law_cauchy(law, theta, F)), expected, 1e-10, where);
      expect_near_rel(measurable(closed_form_cauchy(law, theta, F)), expected, 1e-10, where + " (both routes)");
      if (deg == 30 && anisotropic(law)) {  // the shear of an off-axis fiber is part of the check
        EXPECT_GT(std::abs(expected(2)), 1e-3 * expected.cwiseAbs().maxCoeff()) << where;
      }
    }
}

// Uniaxial Cauchy stress along e1: F = [[l, g, 0], [0, l2, 0], [0, 0, 1/(l l2)]] with the
// lateral stretch l2 and the shear g found (Newton on the closed form) so that the
// lateral faces are traction-free: sigma_22 = sigma_33 and sigma_12 = 0.
TEST_P(HomogeneousStretch, UniaxialMatchesTheStrainEnergyDifferentiatedDirectly) {
  const LawParameters& law = GetParam().law;
  for (double deg : kFiberAngles)
    for (double l : {1.12, 0.9}) {
      const double theta = radians(deg);
      const auto F_of = [&](const Eigen::Vector2d& x) {
        Mat3 F = Mat3::Zero();
        F(0, 0) = l, F(0, 1) = x(1), F(1, 1) = x(0), F(2, 2) = 1 / (l * x(0));
        return F;
      };
      const auto lateral = [&](const Eigen::Vector2d& x) {
        const Eigen::Vector3d m = measurable(closed_form_cauchy(law, theta, F_of(x)));
        return Eigen::Vector2d(m(1), m(2));
      };
      const auto axial = [&](const Eigen::Vector2d& x) {
        return std::abs(measurable(closed_form_cauchy(law, theta, F_of(x)))(0));
      };
      Eigen::Vector2d x(1 / std::sqrt(l), 0);
      for (int it = 0; it < 50 && lateral(x).norm() > 1e-12 * axial(x); ++it) {
        Eigen::Matrix2d jac;
        for (int j = 0; j < 2; ++j) {
          Eigen::Vector2d dx = Eigen::Vector2d::Zero();
          dx(j) = 1e-7;
          jac.col(j) = (lateral(x + dx) - lateral(x - dx)) / 2e-7;
        }
        x -= jac.lu().solve(lateral(x));
      }
      const Mat3 F = F_of(x);
      const std::string where = "stretch " + std::to_string(l) + " fiber " + std::to_string(int(deg));
      const Eigen::Vector3d expected = measurable(closed_form_cauchy(law, theta, F));
      ASSERT_LE(expected.tail<2>().cwiseAbs().maxCoeff(), 1e-9 * std::abs(expected(0))) << where << " not solved";
      expect_near_rel(measurable(law_cauchy(law, theta, F)), expected, 1e-10, where);
      EXPECT_GT(expected(0) * (l - 1), 0) << where << ": tension pulls, compression pushes";
      if (law.kind == LawKind::neo_hookean) {  // the textbook uniaxial relation
        EXPECT_NEAR(expected(0), law.mu_pa * (l * l - 1 / l), 1e-10 * law.mu_pa) << where;
      }
    }
}

INSTANTIATE_TEST_SUITE_P(EveryLaw, HomogeneousStretch, ::testing::ValuesIn(all_laws()),
                         [](const ::testing::TestParamInfo<LawCase>& info) { return info.param.name; });

}  // namespace
