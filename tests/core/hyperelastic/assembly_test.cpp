// The residual and tangent of the accurate tier: the tangent is the derivative of the
// residual (central differences) for each law at orders 1 and 2, with a mixed pressure,
// a follower pressure (its load stiffness) and an active tension; rigid motions give no
// residual.

#include "core/hyperelastic/assembly.hpp"

#include "core/box_generator.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <random>

namespace fiberfem::core::hyperelastic {
namespace {

struct Case {
  LawKind kind;
  int order;
  bool incompressible;
};

std::shared_ptr<const ElementMesh> box_mesh(int order) {
  BoxSpec spec;
  spec.size_m = Vec3(0.01, 0.004, 0.003);
  spec.cells = {2, 1, 1};
  return std::make_shared<const ElementMesh>(make_box(spec), order);
}

LawParameters law_of(LawKind kind, bool incompressible) {
  LawParameters l;
  l.kind = kind;
  l.mu_pa = 3000;
  l.incompressible = incompressible;
  l.bulk_modulus_pa = incompressible ? 0 : 2e4;
  return l;
}

// A problem on a small box: fibers at an angle, a follower pressure on the top, a dead one
// on the bottom, an active tension, the x = 0 face fixed.
Problem make_problem(const Case& c) {
  Problem p(box_mesh(c.order));
  const ElementMesh& m = *p.mesh;
  p.region_laws = {law_of(c.kind, c.incompressible)};
  p.element_region.assign(static_cast<size_t>(m.num_elements()), 0);
  p.axes.assign(static_cast<size_t>(m.num_elements()),
                MaterialAxes::from(Vec3(std::cos(0.5), std::sin(0.5), 0.2), Vec3(0, 0.3, 1)));
  p.active_tension_pa.assign(static_cast<size_t>(m.num_elements()), 800.0);
  p.region_density_kg_m3 = {1000};
  p.gravity_m_s2 = Vec3(0, 0, -9.81);
  PressureLoad top, bottom;
  top.pressure_pa = 500;
  bottom.pressure_pa = 200;
  bottom.follower = false;
  const Positions& X = m.rest_positions();
  for (size_t f = 0; f < m.boundary_faces().size(); ++f) {
    const auto& n = m.boundary_faces()[f];
    const double z = (X.col(n[0]) + X.col(n[1]) + X.col(n[2])).z() / 3;
    if (z > 0.003 - 1e-9) top.faces.push_back(static_cast<int>(f));
    if (z < 1e-9) bottom.faces.push_back(static_cast<int>(f));
  }
  p.pressures = {top, bottom};
  p.fixed_dofs.assign(static_cast<size_t>(3 * m.num_nodes()), 0);
  for (int n = 0; n < m.num_nodes(); ++n)
    if (X(0, n) < 1e-9)
      for (int i = 0; i < 3; ++i) p.fixed_dofs[static_cast<size_t>(3 * n + i)] = 1;
  p.quadrature_points = c.order == 1 ? 1 : 4;
  return p;
}

// A deformed state: a large rotation of the rest shape plus a smooth non-affine field.
Positions deformed(const ElementMesh& m, double rotation_rad) {
  const Mat3 R = Eigen::AngleAxisd(rotation_rad, Vec3(0.2, 1, 0.3).normalized()).toRotationMatrix();
  Positions x(3, m.num_nodes());
  for (int n = 0; n < m.num_nodes(); ++n) {
    const Vec3 X = m.rest_positions().col(n);
    const Vec3 u(0.08 * X.y() + 30 * X.x() * X.x(), -0.05 * X.z() + 20 * X.x() * X.y(), 0.1 * X.x() - 40 * X.y() * X.z());
    x.col(n) = R * (X + u);
  }
  return x;
}

class AssemblyTangent : public ::testing::TestWithParam<Case> {};

std::string case_name(const ::testing::TestParamInfo<Case>& info) {
  static const char* const kLaw[] = {"NeoHookean", "Guccione", "HolzapfelOgden"};
  return std::string(kLaw[static_cast<int>(info.param.kind)]) + "Order" + std::to_string(info.param.order) +
         (info.param.incompressible ? "Mixed" : "Penalty");
}

TEST_P(AssemblyTangent, IsTheDerivativeOfTheResidual) {
  const Case c = GetParam();
  const Problem problem = make_problem(c);
  const Assembler a(problem);
  Positions x = deformed(*problem.mesh, 0.0);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  Eigen::VectorXd p(a.num_pressures());
  for (int i = 0; i < p.size(); ++i) p(i) = 300 * u(rng);
  Eigen::VectorXd R;
  SparseMatrix K;
  const Evaluation ev = a.evaluate(x, p, 0.9, R, &K);
  ASSERT_EQ(ev.inverted_elements, 0);
  const Eigen::MatrixXd Kd = Eigen::MatrixXd(K);
  // Central differences along each unknown, scaled to the body (1e-7 m, 1e-3 Pa).
  double worst = 0;
  for (int j = 0; j < a.num_equations(); ++j) {
    Eigen::VectorXd d = Eigen::VectorXd::Zero(a.num_equations());
    const double h = j < a.num_free_displacements() ? 1e-8 : 1e-2;
    d(j) = 1.0;
    Positions xp = x, xm = x;
    Eigen::VectorXd pp = p, pm = p, Rp, Rm;
    a.add_increment(d, h, xp, pp);
    a.add_increment(d, -h, xm, pm);
    a.evaluate(xp, pp, 0.9, Rp, nullptr);
    a.evaluate(xm, pm, 0.9, Rm, nullptr);
    const Eigen::VectorXd fd = (Rp - Rm) / (2 * h);
    const double scale = std::max(Kd.col(j).norm(), 1e-12);
    worst = std::max(worst, (fd - Kd.col(j)).norm() / scale);
  }
  EXPECT_LT(worst, 1e-5);
}

INSTANTIATE_TEST_SUITE_P(LawsOrders, AssemblyTangent,
                         ::testing::Values(Case{LawKind::neo_hookean, 1, false}, Case{LawKind::neo_hookean, 2, false},
                                           Case{LawKind::guccione, 1, true}, Case{LawKind::guccione, 2, true},
                                           Case{LawKind::holzapfel_ogden, 2, false}, Case{LawKind::holzapfel_ogden, 2, true}),
                         case_name);

TEST(Assembly, ARigidMotionOfTheRestShapeHasNoInternalForce) {
  for (int order : {1, 2}) {
    Problem problem = make_problem({LawKind::guccione, order, false});
    problem.pressures.clear();
    problem.active_tension_pa.clear();
    problem.gravity_m_s2.setZero();
    problem.fixed_dofs.clear();
    const Assembler a(problem);
    const ElementMesh& m = *problem.mesh;
    const Mat3 R = Eigen::AngleAxisd(2.5, Vec3(1, 2, 3).normalized()).toRotationMatrix();
    Positions x = (R * m.rest_positions()).colwise() + Vec3(0.3, -0.1, 2.0);
    Eigen::VectorXd R0, p;
    const Evaluation ev = a.evaluate(x, p, 1.0, R0, nullptr);
    EXPECT_EQ(ev.inverted_elements, 0);
    EXPECT_LT(R0.norm(), 1e-9) << "order " << order;
    EXPECT_NEAR(ev.energy_j, 0.0, 1e-12);
  }
}

TEST(Assembly, TheFollowerPressureOnAClosedSurfaceSumsToZeroForce) {
  // A pressure on every boundary face of a body has no net force, deformed or not.
  for (int order : {1, 2}) {
    Problem problem = make_problem({LawKind::neo_hookean, order, false});
    problem.active_tension_pa.clear();
    problem.gravity_m_s2.setZero();
    problem.fixed_dofs.clear();
    problem.region_laws[0].mu_pa = 1e-12;
    problem.region_laws[0].bulk_modulus_pa = 1e-12;
    PressureLoad all;
    all.pressure_pa = 1000;
    for (size_t f = 0; f < problem.mesh->boundary_faces().size(); ++f) all.faces.push_back(static_cast<int>(f));
    problem.pressures = {all};
    const Assembler a(problem);
    Eigen::VectorXd R, p;
    a.evaluate(deformed(*problem.mesh, 1.0), p, 1.0, R, nullptr);
    Vec3 net = Vec3::Zero();
    for (int n = 0; n < problem.mesh->num_nodes(); ++n) net += R.segment<3>(3 * n);
    EXPECT_LT(net.norm(), 1e-9 * 1000 * 1e-5) << "order " << order;
  }
}

TEST(Assembly, AnInvertedElementIsCountedNotANumber) {
  Problem problem = make_problem({LawKind::neo_hookean, 2, false});
  const Assembler a(problem);
  Positions x = problem.mesh->rest_positions();
  x.row(2) *= -1;  // a mirror image: every element inverted
  Eigen::VectorXd R, p;
  const Evaluation ev = a.evaluate(x, p, 1.0, R, nullptr);
  EXPECT_EQ(ev.inverted_elements, problem.mesh->num_elements());
  EXPECT_TRUE(R.allFinite());
}

}  // namespace
}  // namespace fiberfem::core::hyperelastic
