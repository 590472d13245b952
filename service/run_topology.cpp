#include "service/run_topology.hpp"

namespace fiberfem::service {

TopologyData topology_record(const core::TetMesh& m, const std::vector<core::Vec3>& fibers,
                             const std::vector<std::uint8_t>& fixed_dofs, const std::vector<std::string>& region_names,
                             const std::vector<int>& state_nodes) {
  TopologyData t;
  const int nn = m.num_nodes(), ne = m.num_elements();
  t.num_nodes = nn;
  t.num_elements = ne;
  t.rest_positions.resize(3 * static_cast<size_t>(nn));
  for (int n = 0; n < nn; ++n)
    for (int d = 0; d < 3; ++d) t.rest_positions[3 * static_cast<size_t>(n) + d] = static_cast<float>(m.rest_positions()(d, n));
  for (const auto& e : m.tets()) t.tets.insert(t.tets.end(), e.begin(), e.end());
  for (const auto& f : m.boundary_triangles()) t.triangles.insert(t.triangles.end(), f.begin(), f.end());
  t.triangle_elements.assign(m.boundary_triangle_elements().begin(), m.boundary_triangle_elements().end());
  t.element_regions.assign(m.regions().begin(), m.regions().end());
  t.region_names = region_names;
  t.fibers.resize(3 * static_cast<size_t>(ne));
  for (int e = 0; e < ne; ++e)
    for (int d = 0; d < 3; ++d)
      t.fibers[3 * static_cast<size_t>(e) + d] =
          fibers.empty() ? (d == 0 ? 1.f : 0.f) : static_cast<float>(fibers[static_cast<size_t>(e)](d));
  t.state_nodes.assign(state_nodes.begin(), state_nodes.end());
  if (!fixed_dofs.empty())
    for (int n = 0; n < nn; ++n)
      if (fixed_dofs[3 * static_cast<size_t>(n)] || fixed_dofs[3 * static_cast<size_t>(n) + 1] ||
          fixed_dofs[3 * static_cast<size_t>(n) + 2])
        t.fixed_nodes.push_back(n);
  return t;
}

}  // namespace fiberfem::service
