#pragma once
/// @file The benchmark ventricle shared by bench_features and bench_step: the lv_ellipsoid
/// generator's left ventricle with its base held, fibers by the helix rule, and each model
/// term switchable.

#include "core/contraction.hpp"
#include "core/fiber_fields.hpp"
#include "core/lv_ellipsoid.hpp"
#include "core/model.hpp"

#include <array>
#include <vector>

namespace fiberfem::bench {

/// Which model terms the ventricle carries.
struct VentricleTerms {
  bool fibers = false;             ///< transversely isotropic along the helix-rule fibers (else isotropic)
  bool mass_damping = false;       ///< Rayleigh mass damping 10 1/s
  bool stiffness_damping = false;  ///< Rayleigh stiffness damping 0.002 s
  bool gravity = false;            ///< 9.81 m/s^2 along -z
  int contraction = 0;             ///< 0 off, 1 active stress, 2 nodal forces (peak 5 kPa, paced from the apex)
};

/// The mesh: lv_ellipsoid at (circumferential, longitudinal, transmural) resolution.
inline core::TetMesh ventricle_mesh(const std::array<int, 3>& resolution) {
  core::LvEllipsoidSpec spec;
  spec.circumferential = resolution[0];
  spec.longitudinal = resolution[1];
  spec.transmural = resolution[2];
  return core::make_lv_ellipsoid(spec);
}

/// The helix rule's fibers on the ventricle mesh (Laplace coordinate endo -> epi).
inline std::vector<core::Vec3> ventricle_fibers(const core::TetMesh& mesh) {
  return core::helix_rule_fibers(mesh, core::laplace_coordinate(mesh, mesh.node_set("endo"), mesh.node_set("epi")),
                                 core::HelixRule{})
      .fiber;
}

/// The model: default engineering constants (density 1060 kg/m^3), base held.
inline core::Model ventricle_model(const core::TetMesh& mesh, const std::vector<core::Vec3>& rule_fibers,
                                   const VentricleTerms& v) {
  core::Model m(mesh);
  core::EngineeringConstants c;
  if (!v.fibers) c.E_T = c.E_L, c.nu_T = c.nu_LT, c.G_L = c.E_L / (2 * (1 + c.nu_LT));  // isotropic
  m.region_materials = {core::Material::from_engineering(c, 1060.0)};
  if (v.mass_damping || v.stiffness_damping)
    m.region_damping = {core::RayleighDamping{v.mass_damping ? 10.0 : 0.0, v.stiffness_damping ? 0.002 : 0.0}};
  if (v.fibers) m.fibers = rule_fibers;
  m.fix_nodes(mesh.node_set("base"));
  if (v.gravity) m.loads.gravity_m_s2 = core::Vec3(0, 0, -9.81);
  if (v.contraction) {
    m.contraction.mode = v.contraction == 2 ? core::ContractionMode::nodal_forces : core::ContractionMode::active_stress;
    m.contraction.region_peak_pa = {5e3};
    m.contraction.element_delay_s = core::pacing_delays(mesh.rest_positions(), mesh.tets(), core::Vec3(0, 0, -0.02), 0.6);
  }
  return m;
}

/// The ventricle that beats (bench_step's 250,000-tet case): helix fibers, active stress
/// paced from the apex, mass damping.
inline core::Model beating_ventricle(const std::array<int, 3>& resolution) {
  const core::TetMesh mesh = ventricle_mesh(resolution);
  VentricleTerms terms;
  terms.fibers = terms.mass_damping = true;
  terms.contraction = 1;
  return ventricle_model(mesh, ventricle_fibers(mesh), terms);
}

}  // namespace fiberfem::bench
