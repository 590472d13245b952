#include "core/model.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace fiberfem::core {

void RayleighDamping::validate() const {
  if (!(std::isfinite(mass_1_s) && mass_1_s >= 0))
    throw std::invalid_argument("damping: mass (alpha, 1/s) must be >= 0, got " + std::to_string(mass_1_s));
  if (!(std::isfinite(stiffness_s) && stiffness_s >= 0))
    throw std::invalid_argument("damping: stiffness (beta, s) must be >= 0, got " + std::to_string(stiffness_s));
}

void Model::fix_nodes(const std::vector<int>& nodes, unsigned mask) {
  if (fixed_dofs.empty()) fixed_dofs.assign(static_cast<size_t>(3 * mesh.num_nodes()), 0);
  for (int i : nodes) {
    if (i < 0 || i >= mesh.num_nodes())
      throw std::invalid_argument("fixed: node " + std::to_string(i) + " out of range");
    for (int c = 0; c < 3; ++c)
      if (mask & (1u << c)) fixed_dofs[static_cast<size_t>(3 * i + c)] = 1;
  }
}

void Model::set_uniform_fiber(const Vec3& f) { fibers.assign(static_cast<size_t>(mesh.num_elements()), f); }

void Model::validate() {
  const int nr = mesh.num_regions();
  if (static_cast<int>(region_materials.size()) < nr)
    throw std::invalid_argument("model: " + std::to_string(region_materials.size()) +
                                " region materials for " + std::to_string(nr) + " regions");
  if (!region_damping.empty()) {
    if (static_cast<int>(region_damping.size()) < nr)
      throw std::invalid_argument("model: " + std::to_string(region_damping.size()) +
                                  " region dampings for " + std::to_string(nr) + " regions");
    for (size_t r = 0; r < region_damping.size(); ++r) {
      try {
        region_damping[r].validate();
      } catch (const std::invalid_argument& e) {
        throw std::invalid_argument("region " + std::to_string(r) + ": " + e.what());
      }
    }
  }
  if (fibers.empty()) set_uniform_fiber(Vec3::UnitX());
  if (static_cast<int>(fibers.size()) != mesh.num_elements())
    throw std::invalid_argument("fibers: " + std::to_string(fibers.size()) + " vectors for " +
                                std::to_string(mesh.num_elements()) + " elements");
  for (size_t e = 0; e < fibers.size(); ++e) {
    const double n = fibers[e].norm();
    if (!(std::isfinite(n) && n > 1e-12))
      throw std::invalid_argument("fibers: element " + std::to_string(e) + " has a zero or non-finite fiber");
    fibers[e] /= n;
  }
  if (!fixed_dofs.empty() && static_cast<int>(fixed_dofs.size()) != 3 * mesh.num_nodes())
    throw std::invalid_argument("fixed: mask has " + std::to_string(fixed_dofs.size()) +
                                " entries for " + std::to_string(3 * mesh.num_nodes()) + " DOFs");
  if (!loads.gravity_m_s2.allFinite()) throw std::invalid_argument("loads: gravity must be finite");
  contraction.validate(nr, mesh.num_elements());
  for (size_t i = 0; i < loads.point_forces.size(); ++i) {
    const PointForce& p = loads.point_forces[i];
    if (p.node < 0 || p.node >= mesh.num_nodes())
      throw std::invalid_argument("loads: point force " + std::to_string(i) + " node " +
                                  std::to_string(p.node) + " out of range");
    if (!p.force_n.allFinite())
      throw std::invalid_argument("loads: point force " + std::to_string(i) + " is not finite");
  }
  for (size_t i = 0; i < loads.surface_loads.size(); ++i) {
    const SurfaceLoad& s = loads.surface_loads[i];
    if (!std::isfinite(s.pressure_pa) || !s.force_per_area_pa.allFinite())
      throw std::invalid_argument("loads: surface load " + std::to_string(i) + " is not finite");
    if (!(s.ramp_s >= 0 && std::isfinite(s.ramp_s)))
      throw std::invalid_argument("loads: surface load " + std::to_string(i) + " ramp_s must be >= 0");
    for (const Tri& t : s.faces)
      for (int n : t)
        if (n < 0 || n >= mesh.num_nodes())
          throw std::invalid_argument("loads: surface load " + std::to_string(i) + " node out of range");
  }
}

Eigen::VectorXd Model::lumped_node_masses() const {
  Eigen::VectorXd m = Eigen::VectorXd::Zero(mesh.num_nodes());
  for (int e = 0; e < mesh.num_elements(); ++e) {
    const double me = region_materials[static_cast<size_t>(mesh.regions()[static_cast<size_t>(e)])].density_kg_m3() *
                      mesh.rest_volume(e);
    for (int n : mesh.tets()[static_cast<size_t>(e)]) m(n) += 0.25 * me;
  }
  return m;
}

void add_surface_load(const Positions& rest, const SurfaceLoad& load, Eigen::VectorXd& f) {
  for (const Tri& t : load.faces) {
    const Vec3 a = rest.col(t[0]), b = rest.col(t[1]), c = rest.col(t[2]);
    const Vec3 n2 = (b - a).cross(c - a);  // outward normal times twice the area
    const Vec3 total = -load.pressure_pa * 0.5 * n2 + load.force_per_area_pa * 0.5 * n2.norm();
    for (int n : t) f.segment<3>(3 * n) += total / 3.0;
  }
}

void add_surface_load_at(const Positions& rest, const Eigen::Ref<const Positions>& x, const SurfaceLoad& load, double t_s,
                         Eigen::VectorXd& f) {
  const double scale = load.ramp_s > 0 ? std::clamp(t_s / load.ramp_s, 0.0, 1.0) : 1.0;
  if (scale == 0.0) return;
  for (const Tri& t : load.faces) {
    const Vec3 a = rest.col(t[0]), b = rest.col(t[1]), c = rest.col(t[2]);
    const Vec3 n_rest = (b - a).cross(c - a);
    Vec3 n_press = n_rest;
    if (load.follower) {
      const Vec3 xa = x.col(t[0]), xb = x.col(t[1]), xc = x.col(t[2]);
      n_press = (xb - xa).cross(xc - xa);
    }
    const Vec3 total = scale * (-load.pressure_pa * 0.5 * n_press + load.force_per_area_pa * 0.5 * n_rest.norm());
    for (int n : t) f.segment<3>(3 * n) += total / 3.0;
  }
}

Eigen::VectorXd Model::constant_external_forces() const {
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * mesh.num_nodes());
  if (!loads.gravity_m_s2.isZero()) {
    const Eigen::VectorXd m = lumped_node_masses();
    for (int i = 0; i < mesh.num_nodes(); ++i) f.segment<3>(3 * i) += m(i) * loads.gravity_m_s2;
  }
  for (const PointForce& p : loads.point_forces) f.segment<3>(3 * p.node) += p.force_n;
  for (const SurfaceLoad& s : loads.surface_loads)
    if (!s.varies()) add_surface_load(mesh.rest_positions(), s, f);
  return f;
}

Eigen::VectorXd Model::external_forces() const {
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * mesh.num_nodes());
  if (!loads.gravity_m_s2.isZero()) {
    const Eigen::VectorXd m = lumped_node_masses();
    for (int i = 0; i < mesh.num_nodes(); ++i) f.segment<3>(3 * i) += m(i) * loads.gravity_m_s2;
  }
  for (const PointForce& p : loads.point_forces) f.segment<3>(3 * p.node) += p.force_n;
  for (const SurfaceLoad& s : loads.surface_loads) add_surface_load(mesh.rest_positions(), s, f);
  return f;
}

}  // namespace fiberfem::core
