#include "core/hyperelastic/problem.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace fiberfem::core::hyperelastic {

bool Problem::mixed() const {
  for (const LawParameters& l : region_laws)
    if (l.incompressible) return true;
  return false;
}

void Problem::validate() const {
  if (!mesh) throw std::invalid_argument("problem: no mesh");
  const int ne = mesh->num_elements();
  const size_t nodes = static_cast<size_t>(mesh->num_nodes());
  if (region_laws.empty()) throw std::invalid_argument("problem: no material law");
  for (const LawParameters& l : region_laws) l.validate();
  if (element_region.size() != static_cast<size_t>(ne))
    throw std::invalid_argument("problem: element_region has " + std::to_string(element_region.size()) + " entries for " +
                                std::to_string(ne) + " elements");
  for (int e = 0; e < ne; ++e) {
    const int r = element_region[static_cast<size_t>(e)];
    if (r < 0 || static_cast<size_t>(r) >= region_laws.size())
      throw std::invalid_argument("problem: element " + std::to_string(e) + " has region " + std::to_string(r) + " without a law");
  }
  if (!region_density_kg_m3.empty() && region_density_kg_m3.size() != region_laws.size())
    throw std::invalid_argument("problem: region_density_kg_m3 needs one value per region");
  for (double rho : region_density_kg_m3)
    if (!(rho >= 0) || !std::isfinite(rho)) throw std::invalid_argument("problem: density must be finite and >= 0");
  const int pts = points();
  if (pts != 1 && pts != 4 && pts != 11 && pts != 14)
    throw std::invalid_argument("solver.quadrature must be 1, 4, 11 or 14 points (got " + std::to_string(pts) + ")");
  if (!axes.empty() && axes.size() != static_cast<size_t>(ne) && axes.size() != static_cast<size_t>(ne) * static_cast<size_t>(pts))
    throw std::invalid_argument("problem: axes need one entry per element or per quadrature point");
  if (!active_tension_pa.empty() && active_tension_pa.size() != static_cast<size_t>(ne))
    throw std::invalid_argument("problem: active_tension_pa needs one value per element");
  for (double t : active_tension_pa)
    if (!std::isfinite(t)) throw std::invalid_argument("problem: active tension must be finite");
  if (!gravity_m_s2.allFinite()) throw std::invalid_argument("problem: gravity must be finite");
  if (!fixed_dofs.empty() && fixed_dofs.size() != 3 * nodes)
    throw std::invalid_argument("problem: fixed_dofs needs 3 entries per node");
  for (size_t i = 0; i < pressures.size(); ++i) {
    if (!std::isfinite(pressures[i].pressure_pa))
      throw std::invalid_argument("problem: pressure load " + std::to_string(i) + " is not finite");
    for (int f : pressures[i].faces)
      if (f < 0 || static_cast<size_t>(f) >= mesh->boundary_faces().size())
        throw std::invalid_argument("problem: pressure load " + std::to_string(i) + " names face " + std::to_string(f) +
                                    ", not a boundary face");
  }
}

}  // namespace fiberfem::core::hyperelastic
