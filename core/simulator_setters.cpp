#include "core/simulator.hpp"

#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

namespace fiberfem::core {

void Simulator::set_region_material(int region, const Material& material) {
  if (region < 0 || region >= static_cast<int>(model_.region_materials.size()))
    throw std::invalid_argument("set_region_material: no region " + std::to_string(region));
  model_.region_materials[static_cast<size_t>(region)] = material;
  elements_->set_region_material(region, material);
  assembled_ahead_ = false;
  update_node_masses();
  solver_->invalidate();
  refresh_external_forces();
}

void Simulator::set_region_damping(int region, const RayleighDamping& damping) {
  damping.validate();
  if (region < 0 || region >= model_.mesh.num_regions())
    throw std::invalid_argument("set_region_damping: no region " + std::to_string(region));
  if (model_.region_damping.empty()) model_.region_damping.assign(static_cast<size_t>(model_.mesh.num_regions()), {});
  model_.region_damping[static_cast<size_t>(region)] = damping;
  elements_->set_region_stiffness_damping(region, damping.stiffness_s);
  assembled_ahead_ = false;
  update_node_masses();
  solver_->invalidate();
}

void Simulator::set_fibers(std::vector<Vec3> fibers) {
  const int ne = model_.mesh.num_elements();
  if (static_cast<int>(fibers.size()) != ne)
    throw std::invalid_argument("set_fibers: " + std::to_string(fibers.size()) + " fibers for " +
                                std::to_string(ne) + " elements");
  for (int e = 0; e < ne; ++e) {
    const double n = fibers[static_cast<size_t>(e)].norm();
    if (!(std::isfinite(n) && n > 1e-12))
      throw std::invalid_argument("set_fibers: element " + std::to_string(e) + " has a zero or non-finite fiber");
    fibers[static_cast<size_t>(e)] /= n;
  }
  // The element pass reads the fiber (stiffness and active stress alike): a changed
  // fiber of an anisotropic region changes the matrix, so lagged factors are refreshed.
  bool matrix_changed = false;
  for (int e = 0; e < ne; ++e) {
    const size_t i = static_cast<size_t>(e);
    if (fibers[i] == model_.fibers[i]) continue;
    model_.fibers[i] = fibers[i];
    elements_->set_fiber(e, fibers[i]);
    assembled_ahead_ = false;  // the active stress follows the fiber, isotropic or not
    if (!model_.region_materials[static_cast<size_t>(model_.mesh.regions()[i])].is_isotropic()) matrix_changed = true;
  }
  if (matrix_changed) solver_->invalidate();
}

void Simulator::set_time_step(double dt_s) {
  SimulatorSettings s = settings_;
  s.dt_s = dt_s;
  s.validate();
  if (s.dt_s != settings_.dt_s) solver_->invalidate();
  settings_ = s;
  assembled_ahead_ = false;
}

void Simulator::set_gravity(const Vec3& g) {
  if (!g.allFinite()) throw std::invalid_argument("set_gravity: gravity must be finite");
  model_.loads.gravity_m_s2 = g;
  refresh_external_forces();
}

void Simulator::set_loads(const Loads& loads) {
  Model probe = model_;
  probe.loads = loads;
  probe.validate();
  model_.loads = loads;
  refresh_external_forces();
}

void Simulator::set_solver_settings(const SolverSettings& s) {
  s.validate();
  check_solver_fits(s);
  settings_.solver = s;
  assembled_ahead_ = false;
  install_solver(s);
}

void Simulator::install_solver(const SolverSettings& s) {
  solver_ = make_linear_solver(s);
  solver_->set_blocks(sys_.node_block_starts());
  solver_->set_system(&sys_);
  // Node rotations for a solve that turns to the warp while they were skipped (solve_free).
  solver_->set_block_rotation_source([this]() -> const std::vector<Mat3>& {
    elements_->update_node_rotations(st_, settings_.corotation);
    return st_.block_R;
  });
}

void Simulator::set_rotation_method(RotationMethod m) {
  if (m == RotationMethod::polar && settings_.rotation != RotationMethod::polar)
    for (size_t i = 0; i < st_.R.size(); ++i) st_.q[i] = Eigen::Quaterniond(st_.R[i]);
  settings_.rotation = m;
  st_.rotations_current = false;
  assembled_ahead_ = false;
}

void Simulator::set_corotation(bool on) {
  st_.rotations_current = false;
  assembled_ahead_ = false;
  if (on != settings_.corotation) solver_->invalidate();
  settings_.corotation = on;
}

void Simulator::set_active_tension(std::vector<double> tension_pa) {
  if (model_.contraction.enabled())
    throw std::invalid_argument("set_active_tension: the model's contraction schedule sets the tension");
  assembled_ahead_ = false;
  if (tension_pa.empty()) {
    st_.active_tension_pa.clear();
    return;
  }
  if (static_cast<int>(tension_pa.size()) != model_.mesh.num_elements())
    throw std::invalid_argument("set_active_tension: " + std::to_string(tension_pa.size()) +
                                " values for " + std::to_string(model_.mesh.num_elements()) + " elements");
  for (size_t e = 0; e < tension_pa.size(); ++e)
    if (!std::isfinite(tension_pa[e]))
      throw std::invalid_argument("set_active_tension: element " + std::to_string(e) + " is not finite");
  st_.active_tension_pa = std::move(tension_pa);
}

void Simulator::set_contraction(Contraction contraction) {
  contraction.validate(model_.mesh.num_regions(), model_.mesh.num_elements());
  assembled_ahead_ = false;
  const bool was_on = model_.contraction.enabled();
  const bool on = contraction.enabled();
  if (on) {
    // Keep the phase of the beat under way (a rate change must not jump the twitch).
    const double origin =
        was_on ? Contraction::continued_origin(model_.contraction, st_.contraction_origin_s, contraction, st_.time_s) : st_.time_s;
    TwitchTable table = contraction.tabulate();
    tension_table_ = std::move(table);
    st_.contraction_origin_s = origin;
    st_.active_tension_pa.assign(static_cast<size_t>(model_.mesh.num_elements()), 0.0);
  } else {
    st_.active_tension_pa.clear();
  }
  model_.contraction = std::move(contraction);
}

}  // namespace fiberfem::core
