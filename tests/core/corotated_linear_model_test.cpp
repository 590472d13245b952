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

// The element model and the state and system it works on, as the Simulator holds them
// (elements in chunks of `chunk` for the loop; the Simulator's are 32).
struct Pass {
  explicit Pass(bool isotropic, int chunk = 32) : Pass(small_box(isotropic), chunk) {}
  Pass(core::Model m, int chunk)
      : model(std::move(m)), sys(model.mesh, model.fixed_dofs, chunk), elements(model, sys.block_nodes(), sys.element_order()) {
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

  // A f and f of the last run, by element (not by the loop's numbering): the matrix applied
  // to the vector v of the DOFs.
  Eigen::VectorXd product(const Eigen::VectorXd& v) const {
    Eigen::VectorXd y;
    sys.block_product(v, y, false);
    return y;
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

// A box of 3 x 2 x 1 cells (36 tets: four batches of eight and one of four), free, with
// fibers that differ per element and stiffness damping.
core::Model varied_box() {
  core::CantileverSpec spec;
  spec.box.size_m = {0.03, 0.02, 0.01};
  spec.box.cells = {3, 2, 1};
  core::Model m = core::make_cantilever(spec);
  m.fixed_dofs.clear();
  for (size_t e = 0; e < m.fibers.size(); ++e)
    m.fibers[e] = Vec3(1.0, 0.1 * static_cast<double>(e % 7), 0.05 * static_cast<double>(e % 5)).normalized();
  m.region_damping.assign(m.region_materials.size(), core::RayleighDamping{0.0, 0.02});
  m.validate();
  return m;
}

double relative_difference(const Eigen::VectorXd& a, const Eigen::VectorXd& b) { return (a - b).norm() / b.norm(); }

TEST(CorotatedLinearModel, PassIsTheSameForLoopChunksOfAnySize) {
  // The pass reads its per-element data eight loop positions at a time: chunks of 5 and
  // 1 start batches off those blocks (read lane by lane), 32 on them; the forces, energy
  // and matrix agree to round-off (the forces are summed in another order).
  std::mt19937 rng(13);
  const Mat3 R0 = fiberfem::testing::random_rotation(rng);
  Pass ref(varied_box(), 32);
  const Eigen::VectorXd x = deformed(ref.model, R0, 0.03, rng);
  Eigen::VectorXd v(x.size());
  for (Eigen::Index i = 0; i < v.size(); ++i) v(i) = std::sin(1.0 + static_cast<double>(i));
  const double energy = ref.run(x);
  const Eigen::VectorXd Av = ref.product(v);
  for (int chunk : {5, 1}) {
    Pass p(varied_box(), chunk);
    EXPECT_NEAR(p.run(x), energy, 1e-12 * energy) << "chunk " << chunk;
    EXPECT_LT(relative_difference(p.f, ref.f), 1e-12) << "chunk " << chunk;
    EXPECT_LT(relative_difference(p.product(v), Av), 1e-12) << "chunk " << chunk;
  }
}

TEST(CorotatedLinearModel, ParameterChangesReachThePass) {
  // Fibers (the last element's too, which the padding lanes of the last batch repeat), a
  // region's material and its stiffness damping set on a built model give the pass of a
  // model built with them.
  std::mt19937 rng(17);
  const Mat3 R0 = fiberfem::testing::random_rotation(rng);
  core::Model changed = varied_box();
  const int ne = changed.mesh.num_elements();
  const Vec3 f0 = Vec3(0.2, 1.0, 0.3).normalized(), f1 = Vec3(0.0, 0.4, 1.0).normalized();
  core::LameFiberConstants lame;
  lame.fiber_factor = 4.0;
  lame.shear_factor = 1.5;
  const core::Material stiffer = core::Material::from_lame(lame, 1000.0);
  changed.fibers[0] = f0;
  changed.fibers[static_cast<size_t>(ne - 1)] = f1;
  changed.region_materials[0] = stiffer;
  changed.region_damping[0].stiffness_s = 0.05;
  Pass built(changed, 32), set(varied_box(), 32);
  set.elements.set_fiber(0, f0);
  set.elements.set_fiber(ne - 1, f1);
  set.elements.set_region_material(0, stiffer);
  set.elements.set_region_stiffness_damping(0, 0.05);
  const Eigen::VectorXd x = deformed(built.model, R0, 0.03, rng);
  Eigen::VectorXd v(x.size());
  for (Eigen::Index i = 0; i < v.size(); ++i) v(i) = std::cos(2.0 + static_cast<double>(i));
  const double energy = built.run(x);
  EXPECT_EQ(set.run(x), energy);
  EXPECT_EQ(set.f, built.f);
  EXPECT_EQ(set.product(v), built.product(v));
  // And the change matters: the unchanged model's pass differs.
  Pass before(varied_box(), 32);
  before.run(x);
  EXPECT_GT(relative_difference(before.f, built.f), 1e-3);
  EXPECT_GT(relative_difference(before.product(v), built.product(v)), 1e-3);
}

}  // namespace
