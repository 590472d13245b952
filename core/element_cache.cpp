#include "core/element_cache.hpp"

#include "core/element.hpp"

namespace fiberfem::core {

void ElementCaches::build(const Model& model, bool with_stiffness) {
  const int ne = model.mesh.num_elements();
  X.resize(static_cast<size_t>(ne));
  Dm_inv.resize(static_cast<size_t>(ne));
  K.clear();
  if (with_stiffness) K.resize(static_cast<size_t>(ne));
#pragma omp parallel for schedule(static)
  for (int e = 0; e < ne; ++e) {
    const size_t i = static_cast<size_t>(e);
    X[i] = gather(model.mesh.rest_positions(), model.mesh.tets()[i]);
    Dm_inv[i] = rest_shape_inverse(X[i]);
    if (with_stiffness)
      K[i] = element_stiffness(X[i], model.region_materials[static_cast<size_t>(model.mesh.regions()[i])],
                               model.fibers[i]);
  }
  if (!g.empty()) build_active(model);
}

void ElementCaches::rebuild(const Model& model, const std::vector<int>& elements) {
  const int n = static_cast<int>(elements.size());
#pragma omp parallel for schedule(static)
  for (int k = 0; k < n; ++k) {
    const size_t i = static_cast<size_t>(elements[static_cast<size_t>(k)]);
    if (!K.empty())
      K[i] = element_stiffness(X[i], model.region_materials[static_cast<size_t>(model.mesh.regions()[i])],
                               model.fibers[i]);
    if (!g.empty()) g[i] = active_stress_vector(X[i], model.fibers[i]);
  }
}

void ElementCaches::build_active(const Model& model) {
  const int ne = model.mesh.num_elements();
  g.resize(static_cast<size_t>(ne));
#pragma omp parallel for schedule(static)
  for (int e = 0; e < ne; ++e)
    g[static_cast<size_t>(e)] = active_stress_vector(X[static_cast<size_t>(e)], model.fibers[static_cast<size_t>(e)]);
}

}  // namespace fiberfem::core
