// The corotated linear tetrahedron through the element-model interface the integrator
// calls (core/element_model.hpp): the pass's forces are minus the gradient of the model's
// energy (central finite differences), its energy and inverted-element count equal the
// model's own evaluations, and the node-block rotations follow a rigid rotation.

#include "core/builtin_scenes.hpp"
#include "core/corotated_linear_model.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <random>

namespace core = fiberfem::core;
using core::Mat3;
using core::Vec3;

namespace {

// A 2 x 1 x 1 cell box (12 tets), every node free, with the cantilever's transversely
// isotropic material or an isotropic one.
core::Model small_box(bool isotropic) {
  core::CantileverSpec spec;
  spec.box.size_m = {0.02, 0.01, 0.01};
  spec.box.cells = {2, 1, 1};
  spec.fiber = Vec3(1.0, 0.5, 0.2).normalized();
  core::Model m = core::make_cantilever(spec);
  m.fixed_dofs.clear();
  if (isotropic) m.region_materials.assign(m.region_materials.size(), core::Material::isotropic(3e4, 0.3, 1000.0));
  m.validate();
  return m;
}

// The element model and the state and system it works on, as the Simulator holds them.
struct Pass {
  explicit Pass(bool isotropic)
      : model(small_box(isotropic)), sys(model.mesh, model.fixed_dofs), elements(model, sys.block_nodes(), sys.element_order()) {
    const size_t ne = static_cast<size_t>(model.mesh.num_elements());
    st.R.assign(ne, Mat3::Identity());
    st.q.assign(ne, Eigen::Quaterniond::Identity());
    st.block_R.assign(static_cast<size_t>(model.mesh.num_nodes()), Mat3::Identity());
    st.block_q.assign(static_cast<size_t>(model.mesh.num_nodes()), Eigen::Quaterniond::Identity());
  }
  // One pass at positions x with exact (SVD) rotations; returns its elastic energy.
  double run(const Eigen::VectorXd& x) {
    st.x = x;
    st.rotations_current = false;
    core::ElementPass pass;
    pass.h_s = 0.01;
    pass.rotation = core::RotationMethod::svd;
    return elements.assemble(pass, st, sys, f, f_active);
  }

  core::Model model;
  core::SparseSystem sys;
  core::CorotatedLinearModel elements;
  core::SimulatorState st;
  Eigen::VectorXd f, f_active;
};

// Rest positions rotated by `R0` and strained by a random gradient of size `strain`.
Eigen::VectorXd deformed(const core::Model& m, const Mat3& R0, double strain, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Mat3 G;
  for (int i = 0; i < 9; ++i) G(i / 3, i % 3) = strain * u(rng);
  const core::Positions& X = m.mesh.rest_positions();
  Eigen::VectorXd x(X.size());
  for (Eigen::Index n = 0; n < X.cols(); ++n) x.segment<3>(3 * n) = R0 * (Mat3::Identity() + G) * X.col(n);
  return x;
}

// Largest |f + dE/dx| over the DOFs, with dE/dx by central differences of the model's
// energy, relative to the largest force.
double gradient_mismatch(Pass& p, const Eigen::VectorXd& x) {
  p.run(x);
  const Eigen::VectorXd f = p.f;
  const double step = 1e-8;  // m, on a 1 cm body
  double worst = 0;
  for (Eigen::Index d = 0; d < x.size(); ++d) {
    Eigen::VectorXd xp = x, xm = x;
    xp(d) += step;
    xm(d) -= step;
    const double dE = (p.elements.elastic_energy(xp, true) - p.elements.elastic_energy(xm, true)) / (2 * step);
    worst = std::max(worst, std::abs(f(d) + dE));
  }
  return worst / f.cwiseAbs().maxCoeff();
}

TEST(CorotatedLinearModel, ForcesAreMinusTheEnergyGradientForAnIsotropicLaw) {
  // Isotropic: the stress commutes with the stretch, so the rotation's own derivative adds
  // nothing and -R sigma g_a is the exact gradient, at any rotation and finite strain.
  std::mt19937 rng(7);
  Pass p(/*isotropic=*/true);
  const Eigen::VectorXd x = deformed(p.model, fiberfem::testing::random_rotation(rng), 0.05, rng);
  EXPECT_LT(gradient_mismatch(p, x), 1e-7);
}

TEST(CorotatedLinearModel, ForcesApproachTheEnergyGradientForAFiberLaw) {
  // Transversely isotropic: the corotated force leaves out the rotation's derivative,
  // sigma : sym(W eps), which is second order in the strain: the mismatch relative to the
  // force shrinks with the strain.
  std::mt19937 rng(11);
  Pass p(/*isotropic=*/false);
  const Mat3 R0 = fiberfem::testing::random_rotation(rng);
  const double at_1e3 = gradient_mismatch(p, deformed(p.model, R0, 1e-3, rng));
  const double at_1e4 = gradient_mismatch(p, deformed(p.model, R0, 1e-4, rng));
  EXPECT_LT(at_1e3, 1e-3);
  EXPECT_LT(at_1e4, 1e-4);
  EXPECT_LT(at_1e4, 0.2 * at_1e3);
}

TEST(CorotatedLinearModel, PassEnergyEqualsTheModelEnergy) {
  std::mt19937 rng(3);
  Pass p(/*isotropic=*/false);
  const Eigen::VectorXd x = deformed(p.model, fiberfem::testing::random_rotation(rng), 0.02, rng);
  const double pass_energy = p.run(x);
  const double energy = p.elements.elastic_energy(x, true);
  EXPECT_GT(energy, 0.0);
  EXPECT_NEAR(pass_energy, energy, 1e-10 * energy);
  EXPECT_TRUE(p.st.rotations_current);
}

TEST(CorotatedLinearModel, PassCountsInvertedElements) {
  Pass p(/*isotropic=*/true);
  std::mt19937 rng(5);
  const Eigen::VectorXd x = deformed(p.model, Mat3::Identity(), 0.01, rng);
  p.run(x);
  EXPECT_EQ(p.st.inverted_current, 0);
  // Mirrored through x = 0: every element is inside out.
  Eigen::VectorXd mirrored = x;
  for (Eigen::Index n = 0; n < mirrored.size() / 3; ++n) mirrored(3 * n) = -mirrored(3 * n);
  p.run(mirrored);
  EXPECT_EQ(p.st.inverted_current, p.model.mesh.num_elements());
  EXPECT_EQ(p.elements.count_inverted(mirrored), p.model.mesh.num_elements());
}

TEST(CorotatedLinearModel, NodeRotationsFollowARigidRotation) {
  std::mt19937 rng(9);
  Pass p(/*isotropic=*/false);
  const Mat3 R0 = fiberfem::testing::random_rotation(rng);
  p.run(deformed(p.model, R0, 0.0, rng));
  p.elements.update_node_rotations(p.st, /*corotation=*/true);
  for (const Mat3& R : p.st.block_R) EXPECT_LT((R - R0).norm(), 1e-5);
  p.elements.update_node_rotations(p.st, /*corotation=*/false);
  for (const Mat3& R : p.st.block_R) EXPECT_TRUE(R.isIdentity());
}

}  // namespace
