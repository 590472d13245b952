// The accurate tier's time steps as the service's engine (service/engine_accurate.hpp).

#include "service/engine_accurate.hpp"

#include <chrono>
#include <optional>
#include <stdexcept>

namespace fiberfem::service {

namespace {

using Clock = std::chrono::steady_clock;

}  // namespace

AccurateEngine::AccurateEngine(const io::Scene& scene)
    : scene_(scene), problem_(io::accurate_problem(scene)), cavities_(io::add_circulation_loads(scene_, problem_)) {
  start(io::accurate_dynamic_settings(scene_, problem_));
}

void AccurateEngine::start(const core::hyperelastic::DynamicSettings& settings) {
  coupled_.reset();  // it refers to the solver it replaces
  solver_ = std::make_unique<core::hyperelastic::DynamicSolver>(*problem_.problem, settings);
  if (!cavities_.empty()) {
    const core::circulation::Coupling& c = scene_.model.circulation;
    coupled_ = std::make_unique<core::hyperelastic::CirculationCoupledDynamics>(*solver_, *problem_.problem, c.parameters, c.initial,
                                                                                 cavities_, c.volume_tolerance, c.max_iterations);
  }
  update_tension();
}

// A step of dt as `n` substeps, the loads at each substep's end time (backward Euler), as
// `fiberfem run` steps them. A failed substep leaves the state where it stopped, and the
// solver in the middle of the step's substeps (the caller restores it).
core::StepReport AccurateEngine::attempt(int n) {
  const double t_start = solver_->time_s(), dt = dt_s();
  core::StepReport rep;
  rep.substeps = n;
  solver_->set_substeps(n);
  for (int i = 1; i <= n && rep.status != core::StepStatus::failed; ++i) {
    std::vector<double> tension;
    core::hyperelastic::Loading loading = io::accurate_loading(scene_, t_start + dt * i / n, tension, contraction_origin_s_);
    if (nodal_forces_n_.cols() > 0) loading.nodal_forces_n = &nodal_forces_n_;
    bool converged = false;
    if (coupled_) {  // the cavities' pressures solved with the body's Newton iteration
      const core::hyperelastic::CoupledStepReport r = coupled_->step(loading);
      converged = r.converged;
      rep.message = r.message;
      rep.solver_iterations += r.newton_iterations;
      rep.circulation_iterations += r.pressure_iterations;
    } else {
      const core::hyperelastic::DynamicStepReport r = solver_->step(loading);
      converged = r.converged;
      rep.message = r.message;
      rep.solver_iterations += r.iterations;
    }
    if (!converged) rep.status = core::StepStatus::failed;
    else if (i == n) tension_pa_ = std::move(tension);
  }
  if (rep.status != core::StepStatus::failed) solver_->set_substeps(1);  // else after the caller's restore
  return rep;
}

// A step that fails whole (Newton from the predictor does not converge, or an element
// would invert) is retried as 2, 4, ... kMaxSubsteps substeps from the state before it.
core::StepReport AccurateEngine::step() {
  const auto t0 = Clock::now();
  const core::hyperelastic::NewtonReport before = solver_->totals();
  core::StepReport rep = attempt(1);  // a failed whole step changes nothing
  std::optional<EngineCheckpoint> saved;
  for (int n = 2; rep.status == core::StepStatus::failed && n <= kMaxSubsteps; n *= 2) {
    if (!saved) saved = checkpoint();
    const int attempts = rep.attempts + 1;
    rep = attempt(n);
    rep.attempts = attempts;
    if (rep.status == core::StepStatus::failed) {
      restore_state(*saved);
      solver_->set_substeps(1);
    }
  }
  if (rep.status == core::StepStatus::failed)
    rep.message += " (also in " + std::to_string(kMaxSubsteps) + " substeps)";
  const core::hyperelastic::NewtonReport after = solver_->totals();
  rep.solver_factorizations = after.factorisations - before.factorisations;
  rep.time.assembly_s = after.assembly_s - before.assembly_s;
  rep.time.solve_s = after.factor_s - before.factor_s;
  rep.time_s = solver_->time_s();
  // Energies (kinetic of the lumped masses) and the fastest node, of the state now.
  rep.elastic_energy_j = solver_->elastic_energy_j();
  const Eigen::VectorXd& m = solver_->node_masses();
  const core::Positions& v = solver_->velocities();
  for (int n = 0; n < v.cols(); ++n) {
    rep.kinetic_energy_j += 0.5 * m(n) * v.col(n).squaredNorm();
    rep.max_speed_m_s = std::max(rep.max_speed_m_s, v.col(n).norm());
  }
  rep.time.total_s = std::chrono::duration<double>(Clock::now() - t0).count();
  return rep;
}

void AccurateEngine::update_tension() { io::accurate_loading(scene_, solver_->time_s(), tension_pa_, contraction_origin_s_); }

EngineCheckpoint AccurateEngine::checkpoint() const {
  core::hyperelastic::DynamicState s = coupled_ ? coupled_->checkpoint() : solver_->state();
  s.contraction_origin_s = contraction_origin_s_;
  return s;
}

void AccurateEngine::set_point_forces(const std::vector<core::PointForce>& forces) {
  const core::hyperelastic::ElementMesh& mesh = *problem_.mesh;
  core::Positions f = core::Positions::Zero(3, forces.empty() ? 0 : mesh.num_nodes());
  for (const core::PointForce& p : forces) {
    if (p.node < 0 || p.node >= mesh.num_corner_nodes())
      throw std::invalid_argument("point force on node " + std::to_string(p.node) + ": the mesh has " +
                                  std::to_string(mesh.num_corner_nodes()) + " nodes");
    if (!p.force_n.allFinite()) throw std::invalid_argument("point force on node " + std::to_string(p.node) + " is not finite");
    f.col(p.node) += p.force_n;
  }
  nodal_forces_n_ = std::move(f);
}

void AccurateEngine::restore(const EngineCheckpoint& c) {
  restore_state(c);
  update_tension();
}

void AccurateEngine::restore_state(const EngineCheckpoint& c) {
  const auto* s = std::get_if<core::hyperelastic::DynamicState>(&c);
  if (s == nullptr) throw std::invalid_argument("checkpoint of the real-time tier: this run is on the accurate tier");
  contraction_origin_s_ = s->contraction_origin_s;
  if (coupled_) coupled_->restore(*s);
  else if (!s->cavity_volume_m3.empty()) throw std::invalid_argument("checkpoint of a run with a circulation: this scene has none");
  else solver_->restore(*s);
}

void AccurateEngine::reset() {
  contraction_origin_s_ = 0;
  start(solver_->settings());
}

std::unique_ptr<AccurateEngine> AccurateEngine::rebuilt(const io::Scene& running) {
  auto next = std::make_unique<AccurateEngine>(running);
  if (static_cast<bool>(next->coupled_) != static_cast<bool>(coupled_))
    throw std::invalid_argument("the running scene adds or removes the circulation");
  if (coupled_) next->coupled_->continue_from(*coupled_);
  next->solver_->continue_from(*solver_);
  next->nodal_forces_n_ = nodal_forces_n_;
  const core::Contraction &before = scene_.model.contraction, &after = next->scene_.model.contraction;
  next->contraction_origin_s_ = contraction_origin_s_;
  if (before.enabled() && after.enabled() && after.period_s != before.period_s)
    next->contraction_origin_s_ = core::Contraction::continued_origin(before, contraction_origin_s_, after, solver_->time_s());
  next->update_tension();
  return next;
}

}  // namespace fiberfem::service
