#include "core/simulator.hpp"

#include "core/corotated_linear_model.hpp"

#include <omp.h>

#include <algorithm>
#include <stdexcept>

namespace fiberfem::core {

const char* to_string(StepStatus s) {
  switch (s) {
    case StepStatus::ok: return "ok";
    case StepStatus::recovered: return "recovered";
    case StepStatus::failed: return "failed";
  }
  return "?";
}

void SimulatorSettings::validate() const {
  if (!(dt_s > 0 && dt_s <= 10))
    throw std::invalid_argument("simulator: dt_s must be in (0, 10] s, got " + std::to_string(dt_s));
  solver.validate();
  if (max_substep_halvings < 0 || max_substep_halvings > 12)
    throw std::invalid_argument("simulator: max_substep_halvings must be in [0, 12], got " +
                                std::to_string(max_substep_halvings));
  if (!(max_inverted_fraction > 0 && max_inverted_fraction <= 1))
    throw std::invalid_argument("simulator: max_inverted_fraction must be in (0, 1], got " +
                                std::to_string(max_inverted_fraction));
  if (!(max_energy_gain >= 0))
    throw std::invalid_argument("simulator: max_energy_gain must be >= 0 (infinity turns the check off), got " +
                                std::to_string(max_energy_gain));
  if (!(polar_tolerance_rad > 0 && polar_tolerance_rad <= 0.1))
    throw std::invalid_argument("simulator: polar_tolerance_rad must be in (0, 0.1], got " +
                                std::to_string(polar_tolerance_rad));
  if (threads < 0) throw std::invalid_argument("simulator: threads must be >= 0, got " + std::to_string(threads));
}

namespace {

// The governor's ceiling: the count OpenMP gave this process (OMP_NUM_THREADS, or every
// core), taken once, before any simulator here set its own.
int process_threads() {
  static const int n = std::max(1, omp_get_max_threads());
  return n;
}

// A fixed thread count applies from the set-up on (its loops start no more threads).
const SimulatorSettings& with_threads_applied(const SimulatorSettings& s) {
  process_threads();
  if (s.threads > 0) omp_set_num_threads(s.threads);
  return s;
}

}  // namespace

Simulator::Simulator(Model model, SimulatorSettings settings)
    : model_((model.validate(), std::move(model))),
      settings_((settings.validate(), with_threads_applied(settings))),
      sys_(model_.mesh, model_.fixed_dofs, 32, LoopSchedule::automatic, settings_.dof_order) {
  governor_ = ThreadGovernor(process_threads());
  const int ne = model_.mesh.num_elements();
  // The one element family of the engine; another (core/element_model.hpp) would be
  // chosen here from the model.
  elements_ = std::make_unique<CorotatedLinearModel>(model_, sys_.block_nodes(), sys_.element_order());
  update_node_masses();
  refresh_external_forces();
  check_solver_fits(settings_.solver);
  install_solver(settings_.solver);
  st_.R.assign(static_cast<size_t>(ne), Mat3::Identity());
  st_.q.assign(static_cast<size_t>(ne), Eigen::Quaterniond::Identity());
  if (model_.contraction.enabled()) {  // per-step tensions come from the schedule
    st_.active_tension_pa.assign(static_cast<size_t>(ne), 0.0);
    tension_table_ = model_.contraction.tabulate();
  }
  if (model_.circulation.enabled()) setup_circulation();
  reset();
}

void Simulator::refresh_external_forces() {
  f_ext_const_ = model_.constant_external_forces();
  varying_loads_.clear();
  for (const SurfaceLoad& s : model_.loads.surface_loads)
    if (s.varies()) varying_loads_.push_back(&s);
  st_.f_ext = f_ext_const_;
  const Positions& rest = model_.mesh.rest_positions();
  const bool have_state = st_.x.size() == rest.size();  // not yet in the constructor
  for (const SurfaceLoad* s : varying_loads_)
    if (have_state)
      add_surface_load_at(rest, positions(), *s, st_.time_s, st_.f_ext);
    else
      add_surface_load_at(rest, rest, *s, 0.0, st_.f_ext);
}

void Simulator::update_node_masses() {
  mass_ = model_.lumped_node_masses();
  st_.energy_floor_j = 0;
  for (int e = 0; e < model_.mesh.num_elements(); ++e) {
    const Material& m = model_.region_materials[static_cast<size_t>(model_.mesh.regions()[static_cast<size_t>(e)])];
    st_.energy_floor_j += 0.5 * model_.mesh.rest_volume(e) * m.stiffness().diagonal().maxCoeff() * 1e-16;
  }
  mass_alpha_ = Eigen::VectorXd::Zero(model_.mesh.num_nodes());
  if (model_.region_damping.empty()) return;
  for (int e = 0; e < model_.mesh.num_elements(); ++e) {
    const int r = model_.mesh.regions()[static_cast<size_t>(e)];
    const double me = model_.region_materials[static_cast<size_t>(r)].density_kg_m3() * model_.mesh.rest_volume(e);
    const double alpha = model_.region_damping[static_cast<size_t>(r)].mass_1_s;
    for (int n : model_.mesh.tets()[static_cast<size_t>(e)]) mass_alpha_(n) += 0.25 * alpha * me;
  }
}

void Simulator::reset() {
  const int n = model_.mesh.num_nodes();
  st_.x = Eigen::Map<const Eigen::VectorXd>(model_.mesh.rest_positions().data(), 3 * n);
  st_.v = Eigen::VectorXd::Zero(3 * n);
  std::fill(st_.R.begin(), st_.R.end(), Mat3::Identity());
  std::fill(st_.q.begin(), st_.q.end(), Eigen::Quaterniond::Identity());
  st_.rotations_current = false;
  assembled_ahead_ = false;
  st_.block_q.assign(sys_.block_nodes().size(), Eigen::Quaterniond::Identity());
  st_.block_R.assign(sys_.block_nodes().size(), Mat3::Identity());
  solver_->invalidate();
  solver_->forget_solutions();
  st_.vfree = Eigen::VectorXd::Zero(sys_.num_free());
  st_.vfree_prev = st_.vfree;
  st_.time_s = 0;
  st_.step_count = 0;
  st_.contraction_origin_s = 0;
  if (model_.circulation.enabled()) reset_circulation();
}

void Simulator::apply_fixed() {
  if (model_.fixed_dofs.empty()) return;
  const auto& rest = model_.mesh.rest_positions();
  for (int d = 0; d < sys_.num_dofs(); ++d)
    if (model_.fixed_dofs[static_cast<size_t>(d)]) {
      st_.x(d) = rest.data()[d];
      st_.v(d) = 0;
    }
}

void Simulator::set_state(const Positions& x, const Positions& v) {
  const int n = model_.mesh.num_nodes();
  if (x.cols() != n || v.cols() != n)
    throw std::invalid_argument("set_state: expected " + std::to_string(n) + " nodes");
  if (!x.allFinite() || !v.allFinite()) throw std::invalid_argument("set_state: non-finite values");
  st_.x = Eigen::Map<const Eigen::VectorXd>(x.data(), 3 * n);
  st_.v = Eigen::Map<const Eigen::VectorXd>(v.data(), 3 * n);
  apply_fixed();
  st_.vfree = sys_.restrict_to_free(st_.v);
  st_.vfree_prev = st_.vfree;
  solver_->forget_solutions();
  // Re-seed the warm-started rotations from the new shape.
  elements_->seed_rotations(st_, settings_.corotation);
  st_.rotations_current = false;
  assembled_ahead_ = false;
  solver_->invalidate();
}

void Simulator::check_solver_fits(const SolverSettings& s) const {
  // The amg hierarchy is built on 3 x 3 node blocks (the rigid-body modes are per node).
  if (s.method == LinearSolverKind::pcg && s.preconditioner == PreconditionerKind::amg && !sys_.has_blocks())
    throw std::invalid_argument(
        "solver: preconditioner amg needs every node wholly free or wholly fixed, and this model fixes single "
        "components of some nodes: use preconditioner cholesky");
}

}  // namespace fiberfem::core
