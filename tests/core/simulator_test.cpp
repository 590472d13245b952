// The dynamic engine (PHYSICS.md sections 4-6) against independent answers: the damped
// dynamics settle on the static Newton solution; backward Euler's exact energy ratio
// 1 / (1 + w^2 h^2) for a single mode (w from a dense generalised eigensolve); free fall
// exact; linear momentum conserved and no energy gained by a free body; active tension
// giving the uniaxial strain -T / E_L; solvers, rotation methods, warm start and thread
// counts agreeing; rollback and substepping; parameter changes between steps; and the
// validation messages.

#include "core/box_generator.hpp"
#include "core/builtin_scenes.hpp"
#include "core/element.hpp"
#include "core/simulator.hpp"
#include "core/static_solver.hpp"
#include "test_support.hpp"

#include <Eigen/Eigenvalues>

#include <omp.h>

#include <cmath>
#include <functional>
#include <limits>
#include <random>

namespace core = fiberfem::core;
using core::Mat3;
using core::Vec3;

namespace {

core::CantileverSpec small_beam() {
  core::CantileverSpec spec;
  spec.box.size_m = {0.08, 0.01, 0.01};
  spec.box.cells = {8, 2, 2};
  spec.damping.mass_1_s = 16.0;  // about critical for the first bending mode (~8 rad/s)
  return spec;
}

core::SimulatorSettings settings(core::LinearSolverKind kind, double tol = 1e-10) {
  core::SimulatorSettings s;
  s.solver.method = kind;
  s.solver.tolerance = tol;
  s.solver.max_iterations = 5000;
  return s;
}

// Steps until the largest node speed drops below `speed` (or `max_steps`); returns steps.
int settle(core::Simulator& sim, double speed, int max_steps) {
  for (int i = 1; i <= max_steps; ++i) {
    const core::StepReport r = sim.step();
    EXPECT_NE(r.status, core::StepStatus::failed) << r.message;
    if (r.max_speed_m_s < speed) return i;
  }
  return max_steps;
}

double max_abs_diff(const core::Positions& a, const core::Positions& b) { return (a - b).cwiseAbs().maxCoeff(); }

// Largest displacement of the rest shape (the scale for relative comparisons).
double max_displacement(const core::Positions& x, const core::TetMesh& mesh) {
  return (x - mesh.rest_positions()).colwise().norm().maxCoeff();
}

core::Model free_box(const Vec3& size, std::array<int, 3> cells, const core::Material& mat) {
  core::BoxSpec b;
  b.size_m = size;
  b.cells = cells;
  core::Model m(core::make_box(b));
  m.region_materials.push_back(mat);
  m.validate();
  return m;
}

core::EngineeringConstants heart_like() {
  core::EngineeringConstants c;
  c.E_L = 60e3;
  c.E_T = 20e3;
  c.nu_T = 0.45;
  c.nu_LT = 0.3;
  c.G_L = 8e3;
  return c;
}

}  // namespace

// The fixed point of the damped step is f_el(x) + f_ext = 0: the static equilibrium of the
// same corotational model, found independently by Newton with the consistent tangent.
TEST(Simulator, DampedDynamicsSettleOnTheStaticSolution) {
  const core::Model model = core::make_cantilever(small_beam());
  core::Positions xs;
  const core::StaticReport sr = core::solve_static(model, xs);
  ASSERT_TRUE(sr.converged) << sr.message;
  const double scale = max_displacement(xs, model.mesh);
  ASSERT_GT(scale, 1e-3);  // a visibly bent beam (millimetres), not a trivial state
  struct Case {
    const char* name;
    core::LinearSolverKind kind;
    core::PreconditionerKind pre;
  };
  for (const Case& c : {Case{"direct", core::LinearSolverKind::direct, core::PreconditionerKind::cholesky},
                        Case{"pcg/cholesky", core::LinearSolverKind::pcg, core::PreconditionerKind::cholesky},
                        Case{"pcg/block_jacobi", core::LinearSolverKind::pcg, core::PreconditionerKind::block_jacobi}}) {
    core::SimulatorSettings st = settings(c.kind);
    st.solver.preconditioner = c.pre;
    st.dt_s = 0.02;
    core::Simulator sim(model, st);
    const int steps = settle(sim, 1e-9, 3000);
    EXPECT_LT(steps, 3000) << c.name << " did not settle";
    const double err = max_abs_diff(sim.positions(), xs) / scale;
    EXPECT_LT(err, 1e-6) << c.name << ": settled state differs from the static solution by " << err
                         << " of the deflection";
  }
}

// Corotation off, no damping: the step is exactly linear backward Euler, which multiplies
// the energy of an eigenmode (K phi = w^2 M phi) by 1 / (1 + w^2 h^2) per step.
TEST(Simulator, BackwardEulerDampsEachModeByTheExactFactor) {
  core::CantileverSpec spec = small_beam();
  spec.box.cells = {4, 1, 1};
  spec.damping = {};
  spec.gravity_m_s2 = Vec3::Zero();
  const core::Model model = core::make_cantilever(spec);
  core::SimulatorSettings st = settings(core::LinearSolverKind::direct);
  st.corotation = false;
  st.dt_s = 1e-3;
  core::Simulator sim(model, st);

  // Dense K and M over the free DOFs, assembled here from element_stiffness (the stored-K^e
  // route, independent of the closed form the step uses).
  const auto& sys = sim.system();
  const int nf = sys.num_free();
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(nf, nf);
  for (int e = 0; e < model.mesh.num_elements(); ++e) {
    const core::Tet& t = model.mesh.tets()[static_cast<size_t>(e)];
    const core::Mat12 Ke = core::element_stiffness(
        core::gather(model.mesh.rest_positions(), t),
        model.region_materials[static_cast<size_t>(model.mesh.regions()[static_cast<size_t>(e)])],
        model.fibers[static_cast<size_t>(e)]);
    for (int a = 0; a < 12; ++a)
      for (int b = 0; b < 12; ++b) {
        const int i = sys.free_index()[static_cast<size_t>(3 * t[static_cast<size_t>(a / 3)] + a % 3)];
        const int j = sys.free_index()[static_cast<size_t>(3 * t[static_cast<size_t>(b / 3)] + b % 3)];
        if (i >= 0 && j >= 0) K(i, j) += Ke(a, b);
      }
  }
  const Eigen::VectorXd m_full = model.lumped_node_masses();
  Eigen::VectorXd m(nf);
  for (int d = 0; d < 3 * model.mesh.num_nodes(); ++d)
    if (sys.free_index()[static_cast<size_t>(d)] >= 0) m(sys.free_index()[static_cast<size_t>(d)]) = m_full(d / 3);
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> eig(K, Eigen::MatrixXd(m.asDiagonal()));
  ASSERT_EQ(eig.info(), Eigen::Success);

  for (int mode : {0, 3, nf / 2}) {
    const double w2 = eig.eigenvalues()(mode);
    const Eigen::VectorXd phi = eig.eigenvectors().col(mode);
    Eigen::VectorXd u_full = Eigen::VectorXd::Zero(3 * model.mesh.num_nodes());
    sys.scatter_free(1e-4 / phi.cwiseAbs().maxCoeff() * phi, u_full);
    const core::Positions x0 = model.mesh.rest_positions() + Eigen::Map<core::Positions>(u_full.data(), 3, model.mesh.num_nodes());
    sim.set_state(x0, core::Positions::Zero(3, model.mesh.num_nodes()));
    double e_prev = sim.energies().elastic_j;
    const double h = st.dt_s;
    for (int s = 0; s < 5; ++s) {
      sim.step();
      const core::Energies en = sim.energies();
      const double e = en.kinetic_j + en.elastic_j;
      EXPECT_NEAR(e / e_prev, 1.0 / (1.0 + w2 * h * h), 1e-8) << "mode " << mode << " (w = " << std::sqrt(w2)
                                                              << " rad/s) step " << s;
      e_prev = e;
    }
  }

  // With Rayleigh damping D = alpha M + beta K each mode follows the scalar recurrence
  //   (1 + h alpha + h beta w^2 + h^2 w^2) v1 = v0 - h w^2 u0,   u1 = u0 + h v1
  // in its modal coordinates (phi M-normalised): checks both damping terms.
  const double alpha = 3.0, beta = 2e-3;
  sim.set_region_damping(0, {alpha, beta});
  const double h = st.dt_s;
  auto modal = [&](const Eigen::VectorXd& full, const Eigen::VectorXd& phi) {
    return phi.dot(m.asDiagonal() * sys.restrict_to_free(full));
  };
  for (int mode : {1, nf / 3}) {
    const double w2 = eig.eigenvalues()(mode);
    const Eigen::VectorXd phi = eig.eigenvectors().col(mode);
    Eigen::VectorXd u_full = Eigen::VectorXd::Zero(3 * model.mesh.num_nodes());
    sys.scatter_free(1e-4 / phi.cwiseAbs().maxCoeff() * phi, u_full);
    const Eigen::Map<const Eigen::VectorXd> rest(model.mesh.rest_positions().data(), 3 * model.mesh.num_nodes());
    sim.set_state(model.mesh.rest_positions() + Eigen::Map<core::Positions>(u_full.data(), 3, model.mesh.num_nodes()),
                  core::Positions::Zero(3, model.mesh.num_nodes()));
    double u = modal(u_full, phi), v = 0;
    for (int s = 0; s < 5; ++s) {
      sim.step();
      v = (v - h * w2 * u) / (1 + h * alpha + h * beta * w2 + h * h * w2);
      u += h * v;
      const Eigen::VectorXd x = Eigen::Map<const Eigen::VectorXd>(sim.positions().data(), 3 * model.mesh.num_nodes());
      const Eigen::VectorXd vel = Eigen::Map<const Eigen::VectorXd>(sim.velocities().data(), 3 * model.mesh.num_nodes());
      EXPECT_NEAR(modal(x - rest, phi), u, 1e-9 * std::abs(u) + 1e-15) << "damped mode " << mode << " step " << s;
      EXPECT_NEAR(modal(vel, phi), v, 1e-8 * std::abs(v) + 1e-15) << "damped mode " << mode << " step " << s;
    }
  }
}

// A free body under gravity falls exactly as backward Euler predicts for a constant force:
// v_n = n h g, x_n = X + h^2 g n (n + 1) / 2, with no deformation.
TEST(Simulator, FreeFallIsExact) {
  core::Model model = free_box({0.02, 0.01, 0.01}, {2, 1, 1}, core::Material::from_engineering(heart_like(), 1000));
  model.loads.gravity_m_s2 = {0.3, -1.0, -9.81};
  core::SimulatorSettings st = settings(core::LinearSolverKind::pcg, 1e-12);
  core::Simulator sim(model, st);
  const double h = st.dt_s;
  const Vec3 g = model.loads.gravity_m_s2;
  for (int n = 1; n <= 30; ++n) sim.step();
  const double n = 30;
  for (int i = 0; i < model.mesh.num_nodes(); ++i) {
    const Vec3 expect_x = model.mesh.rest_positions().col(i) + h * h * g * n * (n + 1) / 2;
    EXPECT_LT((sim.positions().col(i) - expect_x).norm(), 1e-9 * expect_x.norm()) << "node " << i;
    EXPECT_LT((sim.velocities().col(i) - n * h * g).norm(), 1e-9 * (n * h * g).norm()) << "node " << i;
  }
  EXPECT_LT(sim.energies().elastic_j, 1e-18);
}

// Backward Euler with no external work never gains energy (PHYSICS.md section 9): a
// cantilever bent by gravity, then released with gravity off and no damping, loses
// energy every step, with either rotation method.
TEST(Simulator, ReleasedBodyNeverGainsEnergy) {
  core::CantileverSpec spec = small_beam();
  spec.damping = {};
  const core::Model model = core::make_cantilever(spec);
  for (auto rotation : {core::RotationMethod::svd, core::RotationMethod::polar}) {
    core::SimulatorSettings st = settings(core::LinearSolverKind::direct);
    st.rotation = rotation;
    core::Simulator sim(model, st);
    core::Positions xs;
    ASSERT_TRUE(core::solve_static(model, xs).converged);
    sim.set_state(xs, core::Positions::Zero(3, model.mesh.num_nodes()));
    sim.set_gravity(Vec3::Zero());
    const core::Energies e0 = sim.energies();
    ASSERT_GT(e0.elastic_j, 0);
    double e_prev = e0.kinetic_j + e0.elastic_j;
    for (int s = 0; s < 300; ++s) {
      ASSERT_EQ(sim.step().status, core::StepStatus::ok);
      const core::Energies en = sim.energies();
      const double e = en.kinetic_j + en.elastic_j;
      EXPECT_LE(e, e_prev * (1 + 1e-12)) << core::to_string(rotation) << " step " << s;
      e_prev = e;
    }
    EXPECT_LT(e_prev, e0.elastic_j);
  }
}

// A deformed, spinning free body: element forces sum to zero, so linear momentum is
// conserved to round-off, and the spin is kept. Known limit (docs/physics-notes.md): the
// linearised step gives a rigidly spinning body no centripetal acceleration until it has
// stretched, so a body spinning at h w = 0.1 rad per step settles with about 0.6 of its
// kinetic energy as spurious stretch; the test bounds that (no growth after the first
// second) rather than asserting a monotone decrease.
TEST(Simulator, SpinningFreeBodyConservesMomentumAndStaysBounded) {
  const core::Model model = free_box({0.03, 0.02, 0.01}, {3, 2, 2}, core::Material::from_engineering(heart_like(), 1000));
  for (auto rotation : {core::RotationMethod::svd, core::RotationMethod::polar}) {
    core::SimulatorSettings st = settings(core::LinearSolverKind::direct);
    st.rotation = rotation;
    core::Simulator sim(model, st);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1, 1);
    const int nn = model.mesh.num_nodes();
    core::Positions x = model.mesh.rest_positions(), v(3, nn);
    const Vec3 omega(0, 0, 6.0), vel(0.01, 0.02, 0);
    for (int i = 0; i < nn; ++i) {
      x.col(i) += 2e-5 * Vec3(u(rng), u(rng), u(rng));
      v.col(i) = vel + omega.cross(x.col(i) - Vec3(0.015, 0.01, 0.005));
    }
    sim.set_state(x, v);
    const Eigen::VectorXd m = model.lumped_node_masses();
    auto momentum = [&] {
      Vec3 p = Vec3::Zero();
      for (int i = 0; i < nn; ++i) p += m(i) * sim.velocities().col(i);
      return p;
    };
    const Vec3 p0 = momentum();
    const core::Energies e0 = sim.energies();
    double after_1s = 0, peak_later = 0;
    for (int s = 1; s <= 360; ++s) {
      ASSERT_NE(sim.step().status, core::StepStatus::failed);
      const core::Energies en = sim.energies();
      const double e = en.kinetic_j + en.elastic_j;
      ASSERT_TRUE(std::isfinite(e));
      if (s == 60) after_1s = e;
      if (s > 60) peak_later = std::max(peak_later, e);
    }
    EXPECT_LT((momentum() - p0).norm(), 1e-10 * p0.norm()) << core::to_string(rotation);
    EXPECT_LT(after_1s, 2.0 * (e0.kinetic_j + e0.elastic_j)) << core::to_string(rotation);
    EXPECT_LT(peak_later, 1.01 * after_1s) << core::to_string(rotation);
    EXPECT_GT(sim.energies().kinetic_j, 0.9 * e0.kinetic_j) << core::to_string(rotation);
  }
}

// Active tension T along x in a bar free to contract (roller supports on three faces):
// uniform passive stress -T along the fiber, so strain -T / E_L along and +nu_LT T / E_L
// across (PHYSICS.md section 6); turning the fibers to y moves the contraction to y.
TEST(Simulator, ActiveTensionGivesUniaxialStrainAlongTheFiber) {
  core::BoxSpec b;
  b.size_m = {0.04, 0.01, 0.01};
  b.cells = {4, 2, 2};
  core::Model model(core::make_box(b));
  const core::EngineeringConstants c = heart_like();
  model.region_materials.push_back(core::Material::from_engineering(c, 1000));
  model.region_damping.push_back({30.0, 0.0});
  model.set_uniform_fiber(Vec3::UnitX());
  model.fix_nodes(model.mesh.node_set("xmin"), 0b001);
  model.fix_nodes(model.mesh.node_set("ymin"), 0b010);
  model.fix_nodes(model.mesh.node_set("zmin"), 0b100);
  model.validate();
  core::SimulatorSettings st = settings(core::LinearSolverKind::direct);
  st.dt_s = 0.01;
  core::Simulator sim(model, st);
  const double T = 3e3;  // Pa: 5 % strain along the fiber
  sim.set_active_tension(std::vector<double>(static_cast<size_t>(model.mesh.num_elements()), T));
  EXPECT_LT(settle(sim, 1e-10, 5000), 5000);
  auto strain = [&](int axis) {
    const auto [lo, hi] = model.mesh.bounding_box();
    double mx = -1e300, mn = 1e300;
    for (int i = 0; i < model.mesh.num_nodes(); ++i) {
      mx = std::max(mx, sim.positions()(axis, i));
      mn = std::min(mn, sim.positions()(axis, i));
    }
    return (mx - mn) / (hi - lo)(axis) - 1.0;
  };
  // Corotated linear elasticity is exact for a uniform stretch along the axes (R = I).
  EXPECT_NEAR(strain(0), -T / c.E_L, 1e-8);
  EXPECT_NEAR(strain(1), c.nu_LT * T / c.E_L, 1e-8);
  EXPECT_NEAR(strain(2), c.nu_LT * T / c.E_L, 1e-8);

  sim.set_fibers(std::vector<Vec3>(static_cast<size_t>(model.mesh.num_elements()), Vec3::UnitY()));
  EXPECT_LT(settle(sim, 1e-10, 5000), 5000);
  EXPECT_NEAR(strain(1), -T / c.E_L, 1e-8);
  EXPECT_NEAR(strain(0), c.nu_LT * T / c.E_L, 1e-8);

  sim.set_active_tension({});  // off: back to rest
  EXPECT_LT(settle(sim, 1e-10, 5000), 5000);
  EXPECT_LT(max_abs_diff(sim.positions(), model.mesh.rest_positions()), 1e-9);
}

// Every solver and rotation method follows the same trajectory (tight tolerances), and
// the thread count does not change the answer.
TEST(Simulator, SolversRotationMethodsAndThreadsAgree) {
  core::CantileverSpec spec = small_beam();
  spec.damping = {1.0, 0.0};
  const core::Model model = core::make_cantilever(spec);
  auto run = [&](core::LinearSolverKind kind, core::PreconditionerKind pre, core::RotationMethod rot, int threads) {
    core::SimulatorSettings st = settings(kind, 1e-12);
    st.solver.preconditioner = pre;
    st.rotation = rot;
    st.threads = threads;
    core::Simulator sim(model, st);
    for (int s = 0; s < 40; ++s) EXPECT_EQ(sim.step().status, core::StepStatus::ok);
    return core::Positions(sim.positions());
  };
  const core::Positions ref = run(core::LinearSolverKind::direct, {}, core::RotationMethod::svd, 2);
  const double scale = max_displacement(ref, model.mesh);
  ASSERT_GT(scale, 1e-3);
  EXPECT_LT(max_abs_diff(run(core::LinearSolverKind::pcg, core::PreconditionerKind::cholesky, core::RotationMethod::svd, 2), ref), 1e-8 * scale);
  EXPECT_LT(max_abs_diff(run(core::LinearSolverKind::pcg, core::PreconditionerKind::block_jacobi, core::RotationMethod::svd, 2), ref), 1e-8 * scale);
  // The polar iteration stops at 1e-12 rad, so it agrees with the SVD to about that.
  EXPECT_LT(max_abs_diff(run(core::LinearSolverKind::direct, {}, core::RotationMethod::polar, 2), ref), 1e-8 * scale);
  EXPECT_LT(max_abs_diff(run(core::LinearSolverKind::direct, {}, core::RotationMethod::svd, 1), ref), 1e-12 * scale);
  omp_set_num_threads(2);
}

// A looser PCG tolerance moves the answer by about that tolerance, not more.
TEST(Simulator, PcgToleranceBoundsTheError) {
  const core::Model model = core::make_cantilever(small_beam());
  auto run = [&](core::LinearSolverKind kind, double tol) {
    core::SimulatorSettings st = settings(kind, tol);
    st.solver.preconditioner = core::PreconditionerKind::block_jacobi;
    core::Simulator sim(model, st);
    for (int s = 0; s < 30; ++s) sim.step();
    return core::Positions(sim.positions());
  };
  const core::Positions ref = run(core::LinearSolverKind::direct, 1e-6);
  const double scale = max_displacement(ref, model.mesh);
  const double e4 = max_abs_diff(run(core::LinearSolverKind::pcg, 1e-4), ref) / scale;
  const double e8 = max_abs_diff(run(core::LinearSolverKind::pcg, 1e-8), ref) / scale;
  EXPECT_LT(e8, 1e-5);
  EXPECT_LT(e8, e4);
  EXPECT_LT(e4, 1e-1);
}

// Warm start: PCG starts from the last velocity extrapolated linearly, which is exact for
// uniformly accelerated motion, so a free fall needs no iterations once two velocities are
// known, against a full solve from zero. On a swinging beam the saving is small (measured
// 2 %: the step's error is in the fast modes no extrapolation predicts) and the answer
// does not change.
TEST(Simulator, WarmStartFollowsSmoothMotionAndChangesNothing) {
  core::Model fall = free_box({0.02, 0.01, 0.01}, {2, 1, 1}, core::Material::from_engineering(heart_like(), 1000));
  fall.loads.gravity_m_s2 = {0, 0, -9.81};
  for (auto pre : {core::PreconditionerKind::cholesky, core::PreconditionerKind::block_jacobi}) {
    core::SimulatorSettings st = settings(core::LinearSolverKind::pcg, 1e-8);
    st.solver.preconditioner = pre;
    core::Simulator warm(fall, st);
    st.solver.warm_start = false;
    core::Simulator cold(fall, st);
    for (int s = 0; s < 5; ++s) {
      const int w = warm.step().solver_iterations, c = cold.step().solver_iterations;
      if (s >= 2) {
        EXPECT_EQ(w, 0) << core::to_string(pre) << " step " << s;
        EXPECT_GE(c, 1) << core::to_string(pre) << " step " << s;
      }
    }
  }

  core::CantileverSpec spec = small_beam();
  spec.damping = {0.5, 0.0};
  const core::Model model = core::make_cantilever(spec);
  core::Positions xs;
  ASSERT_TRUE(core::solve_static(model, xs).converged);
  auto run = [&](bool warm) {
    core::SimulatorSettings st = settings(core::LinearSolverKind::pcg, 1e-10);
    st.solver.warm_start = warm;
    core::Simulator sim(model, st);
    sim.set_state(xs, core::Positions::Zero(3, model.mesh.num_nodes()));
    sim.set_gravity(Vec3::Zero());
    for (int s = 0; s < 30; ++s) sim.step();
    return core::Positions(sim.positions());
  };
  EXPECT_LT(max_abs_diff(run(false), run(true)), 1e-7 * max_displacement(xs, model.mesh));
}

// A solver with no remembered solutions (the first step) starts from the better of the
// given velocity and the free flight D^-1 b (the velocity if the stiffness were dropped):
// a free body falling from rest then needs no iteration (a translation is free of
// stress, so the free flight solves the step exactly); a cantilever falling from rest
// needs fewer block-Jacobi iterations (a few) for the same answer; and where the stiffness
// dominates (an active contraction, whose free flight is far off) the start is no worse.
TEST(Simulator, TheFirstSolveStartsFromTheFreeFlight) {
  auto first_step = [](const core::Model& model, core::PreconditionerKind pre, int recycled, core::Positions* x = nullptr,
                       const std::vector<double>& tension = {}) {
    core::SimulatorSettings st = settings(core::LinearSolverKind::pcg, 1e-8);
    st.solver.preconditioner = pre;
    st.solver.recycled_solutions = recycled;  // 0: the given guess always, here the rest velocity 0
    st.max_energy_gain = std::numeric_limits<double>::infinity();
    core::Simulator sim(model, st);
    if (!tension.empty()) sim.set_active_tension(tension);
    const core::StepReport r = sim.step();
    EXPECT_EQ(r.status, core::StepStatus::ok) << r.message;
    if (x) *x = sim.positions();
    return r.solver_iterations;
  };
  core::Model fall = free_box({0.02, 0.01, 0.01}, {2, 1, 1}, core::Material::from_engineering(heart_like(), 1000));
  fall.loads.gravity_m_s2 = {0, 0, -9.81};
  for (auto pre : {core::PreconditionerKind::cholesky, core::PreconditionerKind::block_jacobi}) {
    EXPECT_EQ(first_step(fall, pre, 8), 0) << core::to_string(pre);
    EXPECT_GE(first_step(fall, pre, 0), 1) << core::to_string(pre);
  }

  // A soft 1 m cantilever falling from rest: the free flight is exact away from the support.
  core::CantileverSpec spec;
  spec.box.size_m = {1.0, 0.1, 0.1};
  spec.box.cells = {40, 4, 4};
  const core::Model beam = core::make_cantilever(spec);
  core::Positions x_flight, x_zero, x_direct;
  const int flight = first_step(beam, core::PreconditionerKind::block_jacobi, 8, &x_flight);
  const int zero = first_step(beam, core::PreconditionerKind::block_jacobi, 0, &x_zero);
  // (Only some: the residual left at the support is as large as the load there, and
  // block Jacobi reduces it as slowly as it would have built the flight: 98 against 102.)
  EXPECT_LT(flight, zero);
  {
    core::Simulator direct(beam, settings(core::LinearSolverKind::direct));
    direct.step();
    x_direct = direct.positions();
  }
  const double scale = max_displacement(x_direct, beam.mesh);
  EXPECT_LT(max_abs_diff(x_flight, x_direct), 1e-6 * scale);
  EXPECT_LT(max_abs_diff(x_zero, x_direct), 1e-6 * scale);

  // An active contraction of the same beam: stiffness-dominated.
  core::Model contract = beam;
  contract.loads.gravity_m_s2 = Vec3::Zero();
  const std::vector<double> tension(static_cast<size_t>(beam.mesh.num_elements()), 5e3);
  const int t_flight = first_step(contract, core::PreconditionerKind::block_jacobi, 8, nullptr, tension);
  const int t_zero = first_step(contract, core::PreconditionerKind::block_jacobi, 0, nullptr, tension);
  EXPECT_LE(t_flight, t_zero + 2);
}

// The warp-Cholesky preconditioner refreshes its factor when the matrix changes (time
// step) and otherwise reuses it: most steps factorise nothing.
TEST(Simulator, CholeskyPreconditionerRefreshesOnlyWhenNeeded) {
  const core::Model model = core::make_cantilever(small_beam());
  core::SimulatorSettings st = settings(core::LinearSolverKind::pcg, 1e-6);
  st.solver.jacobi_first = 0;  // the factor from the first step (block Jacobi would do on this beam)
  core::Simulator sim(model, st);
  int factorizations = 0;
  for (int s = 0; s < 60; ++s) {
    const core::StepReport r = sim.step();
    EXPECT_LE(r.solver_iterations, 2 * st.solver.refresh_iterations + 10) << "step " << s;
    factorizations += r.solver_factorizations;
  }
  EXPECT_GE(factorizations, 1);
  EXPECT_LT(factorizations, 20);
  sim.set_time_step(st.dt_s / 3);
  EXPECT_GE(sim.step().solver_factorizations, 1);
}

// A step whose solve cannot reach failure_residual within the iteration cap is rolled
// back and retried with substeps (a smaller h is better conditioned); the result matches
// a run that took those substeps as steps.
TEST(Simulator, FailedStepIsRetriedWithSubsteps) {
  const core::Model model = core::make_cantilever(small_beam());
  core::SimulatorSettings st = settings(core::LinearSolverKind::pcg, 1e-9);
  st.solver.preconditioner = core::PreconditionerKind::block_jacobi;
  st.solver.warm_start = false;
  st.solver.max_iterations = 80;  // enough for dt / 16, not for dt (measured: 149 needed)
  st.solver.failure_residual = 1e-8;
  st.dt_s = 0.05;
  core::Simulator sim(model, st);
  const core::StepReport r = sim.step();
  ASSERT_EQ(r.status, core::StepStatus::recovered) << r.message;
  EXPECT_GT(r.substeps, 1);
  EXPECT_EQ(r.attempts, 1 + static_cast<int>(std::log2(r.substeps)));
  EXPECT_NE(r.message.find("failure_residual"), std::string::npos) << r.message;
  EXPECT_NEAR(r.time_s, st.dt_s, 1e-15);

  core::SimulatorSettings fine = settings(core::LinearSolverKind::direct);
  fine.dt_s = st.dt_s / r.substeps;
  core::Simulator ref(model, fine);
  for (int s = 0; s < r.substeps; ++s) ref.step();
  EXPECT_LT(max_abs_diff(sim.positions(), ref.positions()), 1e-6 * max_displacement(ref.positions(), model.mesh));
}

// When every retry fails the state is rolled back exactly and the report says why.
TEST(Simulator, StepThatAlwaysFailsIsRolledBack) {
  const core::Model model = core::make_cantilever(small_beam());
  core::SimulatorSettings st = settings(core::LinearSolverKind::pcg, 1e-12);
  st.solver.preconditioner = core::PreconditionerKind::block_jacobi;
  st.solver.max_iterations = 1;         // one CG iteration cannot reach...
  st.solver.failure_residual = 1e-11;   // ...this, at any substep
  st.max_substep_halvings = 2;
  core::Simulator sim(model, st);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  core::Positions x = model.mesh.rest_positions(), v = core::Positions::Zero(3, model.mesh.num_nodes());
  for (int i = 0; i < model.mesh.num_nodes(); ++i) v.col(i) = 0.01 * Vec3(u(rng), u(rng), u(rng));
  sim.set_state(x, v);
  const core::Positions x0 = sim.positions(), v0 = sim.velocities();
  const core::StepReport r = sim.step();
  EXPECT_EQ(r.status, core::StepStatus::failed);
  EXPECT_EQ(r.attempts, 3);
  EXPECT_NE(r.message.find("dt/4"), std::string::npos) << r.message;
  EXPECT_NE(r.message.find("failure_residual"), std::string::npos) << r.message;
  EXPECT_EQ(max_abs_diff(sim.positions(), x0), 0.0);
  EXPECT_EQ(max_abs_diff(sim.velocities(), v0), 0.0);
  EXPECT_EQ(sim.time_s(), 0.0);
  EXPECT_EQ(sim.step_count(), 0);
}

// The inversion limit judges the state a step leaves: a very soft free tetrahedron whose
// vertex flies through the opposite face within the step fails it (and is rolled back).
TEST(Simulator, InversionLimitFailsAStepThatEndsInverted) {
  core::Positions X(3, 4);
  X << 0, 0.01, 0, 0, 0, 0, 0.01, 0, 0, 0, 0, 0.01;
  core::Model model(core::TetMesh(X, {{0, 1, 2, 3}}));
  model.region_materials.push_back(core::Material::isotropic(1.0, 0.3, 1000));  // 1 Pa
  model.validate();
  core::SimulatorSettings st = settings(core::LinearSolverKind::direct);
  st.max_inverted_fraction = 0.5;
  st.max_substep_halvings = 1;
  core::Simulator sim(model, st);
  core::Positions v = core::Positions::Zero(3, 4);
  v.col(3) = Vec3(0, 0, -1.5);  // 2.5 cm in a 1/60 s step, through the face z = 0
  sim.set_state(X, v);
  const core::StepReport r = sim.step();
  EXPECT_EQ(r.status, core::StepStatus::failed) << r.message;
  EXPECT_NE(r.message.find("inverted elements after the step"), std::string::npos) << r.message;
  EXPECT_EQ(max_abs_diff(sim.positions(), X), 0.0);
  // Without the limit the same step is taken and counted.
  st.max_inverted_fraction = 1.0;
  core::Simulator free_sim(model, st);
  free_sim.set_state(X, v);
  const core::StepReport r2 = free_sim.step();
  EXPECT_NE(r2.status, core::StepStatus::failed);
  EXPECT_EQ(r2.inverted_elements, 1);
}

// Changes between steps: a new material, gravity or time step gives the static answer of
// the changed model.
TEST(Simulator, ParameterChangesBetweenSteps) {
  core::CantileverSpec spec = small_beam();
  core::Model model = core::make_cantilever(spec);
  core::SimulatorSettings st = settings(core::LinearSolverKind::pcg, 1e-10);
  st.dt_s = 0.02;
  core::Simulator sim(model, st);
  settle(sim, 1e-9, 3000);

  core::EngineeringConstants stiffer = spec.material;
  stiffer.E_L *= 2;
  stiffer.G_L *= 1.5;
  const core::Material mat = core::Material::from_engineering(stiffer, spec.density_kg_m3);
  sim.set_region_material(0, mat);
  sim.set_gravity({0, 0, -2 * 9.81});
  sim.set_time_step(0.03);
  sim.set_region_damping(0, {12.0, 1e-4});
  EXPECT_LT(settle(sim, 1e-9, 3000), 3000);

  core::Model changed = model;
  changed.region_materials[0] = mat;
  changed.loads.gravity_m_s2 = {0, 0, -2 * 9.81};
  core::Positions xs;
  ASSERT_TRUE(core::solve_static(changed, xs).converged);
  EXPECT_LT(max_abs_diff(sim.positions(), xs), 1e-6 * max_displacement(xs, model.mesh));
}

// With the energy check on, the checks of a step make the next step's element pass ahead
// of time (assembled_ahead_). A change of what that pass reads (material, damping, fibers,
// active tension) between two steps must reach the very next step: the step after the
// change equals the step of a simulator built with the changed model from the same
// checkpoint (whose first step makes its own pass), and differs from the unchanged step.
TEST(Simulator, ChangesBetweenStepsReachTheNextStepDespiteTheAssemblyAhead) {
  core::CantileverSpec spec = small_beam();
  spec.material = heart_like();
  core::Model model = core::make_cantilever(spec);
  core::SimulatorSettings st = settings(core::LinearSolverKind::pcg, 1e-10);
  st.dt_s = 0.01;
  ASSERT_LT(st.max_energy_gain, std::numeric_limits<double>::infinity());  // the check is on by default
  const int ne = model.mesh.num_elements();
  const core::Material softer = core::Material::from_engineering(
      [] {
        core::EngineeringConstants c = heart_like();
        c.E_L *= 0.5;
        c.E_T *= 0.7;
        c.G_L *= 0.6;
        return c;
      }(),
      spec.density_kg_m3);
  std::vector<Vec3> turned(static_cast<size_t>(ne), Vec3(0, 0.6, 0.8));
  const std::vector<double> tension(static_cast<size_t>(ne), 3e3);
  struct Change {
    const char* name;
    std::function<void(core::Simulator&)> apply;
  };
  const std::vector<Change> changes = {
      {"material", [&](core::Simulator& s) { s.set_region_material(0, softer); }},
      {"damping", [&](core::Simulator& s) { s.set_region_damping(0, {2.0, 5e-3}); }},
      {"fibers", [&](core::Simulator& s) { s.set_fibers(turned); }},
      {"active tension", [&](core::Simulator& s) { s.set_active_tension(tension); }},
  };
  core::Simulator plain(model, st);
  for (int i = 0; i < 4; ++i) ASSERT_NE(plain.step().status, core::StepStatus::failed);
  const core::SimulatorCheckpoint cp = plain.checkpoint();
  ASSERT_NE(plain.step().status, core::StepStatus::failed);
  const core::Positions unchanged = plain.positions();
  for (const Change& c : changes) {
    SCOPED_TRACE(c.name);
    core::Simulator live(model, st);
    for (int i = 0; i < 4; ++i) ASSERT_NE(live.step().status, core::StepStatus::failed);
    c.apply(live);
    ASSERT_NE(live.step().status, core::StepStatus::failed);
    core::Simulator fresh(model, st);
    fresh.restore(cp);
    c.apply(fresh);
    ASSERT_NE(fresh.step().status, core::StepStatus::failed);
    const double scale = max_displacement(unchanged, model.mesh);
    EXPECT_LE(max_abs_diff(live.positions(), fresh.positions()), 1e-12 * scale);
    EXPECT_GT(max_abs_diff(live.positions(), unchanged), 1e-6 * scale);  // the change matters
  }
}

// The report's energies are those of the state the step started from.
TEST(Simulator, ReportEnergiesMatchTheState) {
  const core::Model model = core::make_cantilever(small_beam());
  core::Simulator sim(model, settings(core::LinearSolverKind::direct));
  for (int s = 0; s < 10; ++s) {
    const core::Energies before = sim.energies();
    const core::StepReport r = sim.step();
    EXPECT_NEAR(r.kinetic_energy_j, before.kinetic_j, 1e-12 * (before.kinetic_j + 1e-30));
    EXPECT_NEAR(r.elastic_energy_j, before.elastic_j, 1e-9 * (before.elastic_j + 1e-30));
    EXPECT_GE(r.time.total_s, r.time.rotations_s + r.time.assembly_s + r.time.solve_s);
  }
}

TEST(Simulator, InvalidSettingsAndChangesAreRefusedByName) {
  using fiberfem::testing::expect_invalid;
  const core::Model model = core::make_cantilever(small_beam());
  auto with = [&](auto edit) {
    core::SimulatorSettings s;
    edit(s);
    return [model, s] { core::Simulator sim(model, s); };
  };
  expect_invalid(with([](auto& s) { s.dt_s = 0; }), {"dt_s"});
  expect_invalid(with([](auto& s) { s.dt_s = std::nan(""); }), {"dt_s"});
  expect_invalid(with([](auto& s) { s.max_substep_halvings = 13; }), {"max_substep_halvings"});
  expect_invalid(with([](auto& s) { s.max_inverted_fraction = 0; }), {"max_inverted_fraction"});
  expect_invalid(with([](auto& s) { s.threads = -1; }), {"threads"});
  expect_invalid(with([](auto& s) { s.max_energy_gain = -1; }), {"max_energy_gain"});
  expect_invalid(with([](auto& s) { s.polar_tolerance_rad = 0; }), {"polar_tolerance_rad"});
  expect_invalid(with([](auto& s) { s.solver.tolerance = 1; }), {"tolerance"});
  expect_invalid(with([](auto& s) { s.solver.max_iterations = 0; }), {"max_iterations"});
  expect_invalid(with([](auto& s) { s.solver.refresh_iterations = 0; }), {"refresh_iterations"});
  expect_invalid(with([](auto& s) { s.solver.failure_residual = -1; }), {"failure_residual"});

  core::Simulator sim(model);
  const int nn = model.mesh.num_nodes(), ne = model.mesh.num_elements();
  expect_invalid([&] { sim.set_state(core::Positions::Zero(3, nn - 1), core::Positions::Zero(3, nn - 1)); }, {"nodes"});
  core::Positions bad = model.mesh.rest_positions();
  bad(1, 3) = std::nan("");
  expect_invalid([&] { sim.set_state(bad, core::Positions::Zero(3, nn)); }, {"non-finite"});
  expect_invalid([&] { sim.set_time_step(-1); }, {"dt_s"});
  expect_invalid([&] { sim.set_gravity({0, std::nan(""), 0}); }, {"gravity"});
  expect_invalid([&] { sim.set_region_material(3, model.region_materials[0]); }, {"region 3"});
  expect_invalid([&] { sim.set_region_damping(0, {-1.0, 0.0}); }, {"mass"});
  std::vector<Vec3> fibers(static_cast<size_t>(ne), Vec3::UnitX());
  fibers[5] = Vec3::Zero();
  expect_invalid([&] { sim.set_fibers(fibers); }, {"element 5"});
  expect_invalid([&] { sim.set_fibers({}); }, {"fibers"});
  expect_invalid([&] { sim.set_active_tension(std::vector<double>(3, 1.0)); }, {"3 values"});
  std::vector<double> tension(static_cast<size_t>(ne), 0.0);
  tension[7] = std::numeric_limits<double>::infinity();
  expect_invalid([&] { sim.set_active_tension(tension); }, {"element 7"});
  core::SolverSettings s;
  s.tolerance = 0;
  expect_invalid([&] { sim.set_solver_settings(s); }, {"tolerance"});
  // None of the refused changes touched the simulation.
  EXPECT_EQ(sim.step().status, core::StepStatus::ok);
}

// Ramped and follower surface loads. A ramp scales the load by t / ramp_s; a follower
// pressure acts on the current faces, so turning the body rigidly turns the force with it
// (a dead pressure keeps its rest direction). Totals over the loaded face are compared
// with the rotation applied to the rest total: a geometric identity, independent of the
// elasticity.
TEST(Simulator, RampedAndFollowerPressures) {
  core::BoxSpec b;
  b.size_m = Vec3(0.02, 0.01, 0.01);
  b.cells = {4, 2, 2};
  auto make = [&](bool follower, double ramp) {
    core::Model m(core::make_box(b));
    m.region_materials = {core::Material::isotropic(1e5, 0.3, 1000)};
    core::SurfaceLoad load;
    const auto& top = m.mesh.node_set("zmax");
    for (const core::Tri& t : m.mesh.boundary_triangles())
      if (std::all_of(t.begin(), t.end(), [&](int n) { return std::find(top.begin(), top.end(), n) != top.end(); }))
        load.faces.push_back(t);
    load.pressure_pa = 100.0;
    load.follower = follower;
    load.ramp_s = ramp;
    m.loads.surface_loads = {load};
    return m;
  };
  auto total = [](const Eigen::VectorXd& f) {
    Vec3 s = Vec3::Zero();
    for (Eigen::Index i = 0; i < f.size(); i += 3) s += f.segment<3>(i);
    return s;
  };
  const Vec3 full(0, 0, -100.0 * 0.02 * 0.01);  // pressure x area, along the inward normal (-z)
  {  // ramp: a quarter of the load at a quarter of the ramp
    core::SimulatorSettings st;
    st.dt_s = 0.01;
    core::Simulator sim(make(false, 0.1), st);
    EXPECT_LT(total(sim.external_force()).norm(), 1e-15);
    for (int s = 0; s < 2; ++s) sim.step();  // t = 0.02 s
    sim.set_time_step(0.005);
    sim.step();  // ends at t = 0.025
    EXPECT_LT((total(sim.external_force()) - 0.25 * full).norm(), 1e-12 * full.norm());
  }
  // A quarter turn about x, at rest: follower turns, dead does not.
  const Eigen::Matrix3d R = Eigen::AngleAxisd(M_PI / 2, Vec3::UnitX()).toRotationMatrix();
  for (bool follower : {true, false}) {
    core::SimulatorSettings st;
    st.dt_s = 1e-4;
    core::Simulator sim(make(follower, 0.0), st);
    const core::Positions X = sim.model().mesh.rest_positions();
    sim.set_state(R * X, core::Positions::Zero(3, X.cols()));
    sim.step();
    const Vec3 expected = follower ? Vec3(R * full) : full;
    EXPECT_LT((total(sim.external_force()) - expected).norm(), 1e-9 * full.norm()) << (follower ? "follower" : "dead");
  }
  // The static solver refuses a follower pressure by name.
  core::Positions x;
  fiberfem::testing::expect_invalid([&] { core::solve_static(make(true, 0.0), x); }, {"follower pressure"});
}
