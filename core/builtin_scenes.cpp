#include "core/builtin_scenes.hpp"

namespace fiberfem::core {

Model make_cantilever(const CantileverSpec& spec) {
  Model m(make_box(spec.box));
  m.region_materials.push_back(Material::from_engineering(spec.material, spec.density_kg_m3));
  m.region_damping.push_back(spec.damping);
  m.set_uniform_fiber(spec.fiber);
  m.fix_nodes(m.mesh.node_set("xmin"));
  m.loads.gravity_m_s2 = spec.gravity_m_s2;
  if (!spec.tip_force_n.isZero()) {
    const Vec3 area = spec.box.size_m;
    SurfaceLoad tip;
    const std::vector<int>& face = m.mesh.node_set("xmax");
    for (const Tri& t : m.mesh.boundary_triangles()) {
      bool on = true;
      for (int n : t) on = on && std::binary_search(face.begin(), face.end(), n);
      if (on) tip.faces.push_back(t);
    }
    tip.force_per_area_pa = spec.tip_force_n / (area.y() * area.z());
    m.loads.surface_loads.push_back(tip);
  }
  m.validate();
  return m;
}

double cantilever_tip_deflection(double L, double b, double h, double E, double G, double q, double P) {
  const double I = b * h * h * h / 12.0;
  const double A = b * h;
  const double k = 5.0 / 6.0;
  return q * L * L * L * L / (8 * E * I) + q * L * L / (2 * k * G * A) + P * L * L * L / (3 * E * I) +
         P * L / (k * G * A);
}

}  // namespace fiberfem::core
