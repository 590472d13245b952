// The accurate tier's problem for a scene (docs/scenes.md, "The accurate tier"): the
// element mesh of the scene's order (edge nodes on the generator's curved surfaces), the
// law of every region, material axes, the fixed components, and the loads.

#include "io/scene_accurate.hpp"

#include "core/hyperelastic/curved_placement.hpp"
#include "core/hyperelastic/ellipsoid_fibers.hpp"
#include "core/hyperelastic/quadrature.hpp"
#include "core/hyperelastic/shape_functions.hpp"

#include <algorithm>
#include <map>
#include <stdexcept>

namespace fiberfem::io {

namespace {

using core::hyperelastic::ElementMesh;
using core::hyperelastic::PressureLoad;
using core::hyperelastic::Problem;

std::array<int, 3> sorted(const core::Tri& t) {
  std::array<int, 3> s{t[0], t[1], t[2]};
  std::sort(s.begin(), s.end());
  return s;
}

// Each boundary triangle of the corner mesh (sorted nodes) to its index in
// ElementMesh::boundary_faces (the element mesh keeps the corner mesh's boundary order).
std::map<std::array<int, 3>, int> boundary_face_index(const core::TetMesh& mesh) {
  std::map<std::array<int, 3>, int> face_of;
  const auto& boundary = mesh.boundary_triangles();
  for (size_t f = 0; f < boundary.size(); ++f) face_of[sorted(boundary[f])] = static_cast<int>(f);
  return face_of;
}

std::shared_ptr<const ElementMesh> element_mesh(const Scene& sc) {
  const core::TetMesh& corners = sc.model.mesh;
  if (sc.mesh_order == 2 && sc.file_elements) return sc.file_elements;
  if (sc.mesh_order == 2 && sc.lv_ellipsoid)
    return std::make_shared<const ElementMesh>(corners, 2, core::hyperelastic::lv_ellipsoid_edge_placement(*sc.lv_ellipsoid, corners));
  return std::make_shared<const ElementMesh>(corners, sc.mesh_order);
}

}  // namespace

bool Scene::accurate() const {
  const std::optional<Tier> tier = parameters.solver.tier;
  if (tier && *tier != Tier::automatic) return *tier == Tier::accurate;
  if (mesh_order != 1) return true;
  return std::any_of(parameters.regions.begin(), parameters.regions.end(),
                     [](const RegionParameters& r) { return r.material.law.has_value(); });
}

void check_accurate(const Scene& sc) {
  const bool tier_given = sc.parameters.solver.tier && *sc.parameters.solver.tier != Tier::automatic;
  if (tier_given && !sc.accurate() && sc.mesh_order != 1)
    throw SceneError(sc.name + ": solver.tier: real_time runs linear tetrahedra, but the mesh is of order 2" +
                     (sc.file_elements ? " (the mesh file's 10-node tetrahedra): give mesh.order: 1 to run its corners"
                                       : ": give mesh.order: 1") +
                     ", or solver.tier: accurate");
  if (!sc.accurate()) return;
  for (size_t r = 0; r < sc.parameters.regions.size(); ++r) {
    const auto& law = sc.parameters.regions[r].material.law;
    if (!law)
      throw SceneError(sc.name + ": regions[" + std::to_string(r) + "].material: needs a law" +
                       (tier_given           ? " (solver.tier: accurate runs hyperelastic laws only)"
                        : sc.mesh_order != 2 ? " (another region has one)"
                        : sc.file_elements ? " (the mesh file has 10-node tetrahedra, which run on the accurate tier; "
                                             "mesh.order: 1 runs its corner mesh on the real-time tier)"
                                           : " (mesh.order 2 runs on the accurate tier)") +
                       ": neo_hookean, guccione or holzapfel_ogden");
    if (law->needs_sheet() && sc.sheets.empty())
      throw SceneError(sc.name + ": regions[" + std::to_string(r) +
                       "].material: holzapfel_ogden needs a sheet direction: fibers.rule (its transmural direction), "
                       "fibers.sheet (with uniform, strokes or file), or a fiber file whose lines give 'fx fy fz sx sy sz'");
  }
}

AccurateProblem accurate_problem(const Scene& sc) {
  check_accurate(sc);
  const core::Model& model = sc.model;
  AccurateProblem out{element_mesh(sc), nullptr, {}};
  auto problem = std::make_shared<Problem>(out.mesh);
  const ElementMesh& mesh = *out.mesh;
  for (const RegionParameters& r : sc.parameters.regions) {
    problem->region_laws.push_back(*r.material.law);
    problem->region_density_kg_m3.push_back(r.material.density_kg_m3);
  }
  problem->element_region = model.mesh.regions();
  const auto& fibers = sc.parameters.fibers;
  if (sc.lv_ellipsoid && fibers && fibers->kind == FiberSpec::Kind::rule && !fibers->inner && !fibers->outer &&
      fibers->rule.apex_to_base.normalized().isApprox(core::Vec3::UnitZ())) {
    // The helix rule on the generator's shell: evaluated at every quadrature point in the
    // shell's own coordinates (Land et al. 2015's definition), not per element.
    const int points = sc.parameters.solver.quadrature.value_or(Problem::default_points(mesh.order()));
    const core::hyperelastic::TetRule& rule = core::hyperelastic::tetrahedron_rule(points);
    problem->axes.reserve(static_cast<size_t>(mesh.num_elements() * points));
    for (int e = 0; e < mesh.num_elements(); ++e)
      for (const Eigen::Vector3d& xi : rule.points) {
        // The element's padded node columns times its shape values: the point at xi.
        const core::Vec3 X = mesh.element_positions(e) * core::hyperelastic::tet_shape(mesh.order(), xi).N;
        problem->axes.push_back(core::hyperelastic::ellipsoid_helix_axes(*sc.lv_ellipsoid, fibers->rule.endo_angle_deg,
                                                                          fibers->rule.epi_angle_deg, X));
      }
  }
  const bool per_point = !problem->axes.empty();
  for (int e = 0; !per_point && e < mesh.num_elements(); ++e) {
    const core::Vec3 f = model.fibers.empty() ? core::Vec3::UnitX() : model.fibers[static_cast<size_t>(e)];
    problem->axes.push_back(core::hyperelastic::MaterialAxes::from(f, sc.sheets.empty() ? core::Vec3::Zero()
                                                                                         : sc.sheets[static_cast<size_t>(e)]));
  }
  // A static solve holds the contraction at its peak: each region's peak tension.
  if (model.contraction.enabled()) {
    problem->active_tension_pa.resize(static_cast<size_t>(mesh.num_elements()));
    for (int e = 0; e < mesh.num_elements(); ++e)
      problem->active_tension_pa[static_cast<size_t>(e)] =
          model.contraction.region_peak_pa[static_cast<size_t>(problem->element_region[static_cast<size_t>(e)])];
  }
  problem->gravity_m_s2 = model.loads.gravity_m_s2;
  if (!model.fixed_dofs.empty()) problem->fixed_dofs = mesh.fixed_dofs(model.fixed_dofs);
  if (!model.loads.point_forces.empty()) throw SceneError(sc.name + ": loads.forces: the accurate tier takes pressures and gravity, not point forces");
  const std::map<std::array<int, 3>, int> face_of = boundary_face_index(model.mesh);
  for (size_t i = 0; i < model.loads.surface_loads.size(); ++i) {
    const core::SurfaceLoad& load = model.loads.surface_loads[i];
    if (load.force_per_area_pa != core::Vec3::Zero())
      throw SceneError(sc.name + ": loads.tractions[" + std::to_string(i) + "]: the accurate tier takes pressures, not traction vectors");
    PressureLoad p;
    p.pressure_pa = load.pressure_pa;
    p.follower = load.follower;
    for (const core::Tri& t : load.faces) {
      const auto it = face_of.find(sorted(t));
      if (it == face_of.end()) throw SceneError(sc.name + ": loads.tractions[" + std::to_string(i) + "]: a face is not on the boundary");
      p.faces.push_back(it->second);
    }
    problem->pressures.push_back(std::move(p));
  }
  const SolverSpec& s = sc.parameters.solver;
  if (s.quadrature) problem->quadrature_points = *s.quadrature;
  if (s.load_steps) out.newton.load_steps = *s.load_steps;
  if (s.newton_tolerance) out.newton.tolerance = *s.newton_tolerance;
  // Loose increments before the last pay on the mixed form (Land problem 3: 41 -> 19 Newton
  // iterations) but not with a penalty, whose loosely converged states start the next
  // increment worse (problem 2 with a 100 kPa penalty: 97 -> 127 iterations, 12 -> 23 s).
  const bool mixed = std::all_of(problem->region_laws.begin(), problem->region_laws.end(),
                                 [](const core::hyperelastic::LawParameters& l) { return l.incompressible; });
  if (s.newton_increment_tolerance)
    out.newton.increment_tolerance = *s.newton_increment_tolerance;
  else if (mixed)
    out.newton.increment_tolerance = core::hyperelastic::NewtonSettings::kMixedIncrementTolerance;
  if (s.newton_max_iterations) out.newton.max_iterations = *s.newton_max_iterations;
  if (s.newton_line_search) out.newton.line_search = *s.newton_line_search;
  if (s.threads) out.newton.threads = *s.threads;
  problem->validate();
  out.problem = std::move(problem);
  return out;
}

std::vector<core::hyperelastic::CoupledCavity> add_circulation_loads(const Scene& sc, AccurateProblem& ap) {
  std::vector<core::hyperelastic::CoupledCavity> out;
  const std::map<std::array<int, 3>, int> face_of = boundary_face_index(sc.model.mesh);
  for (const core::circulation::CoupledCavity& c : sc.model.circulation.cavities) {
    PressureLoad p;
    p.pressure_pa = 1.0;
    p.follower = true;
    for (const core::Tri& t : c.surface.faces) {
      const auto it = face_of.find(sorted(t));
      if (it == face_of.end()) throw SceneError(sc.name + ": circulation.ventricles: a face of cavity '" + c.name + "' is not on the boundary");
      p.faces.push_back(it->second);
    }
    core::hyperelastic::CoupledCavity cc;
    cc.chamber = c.chamber;
    cc.pressure_load = static_cast<int>(ap.problem->pressures.size());
    cc.surface = c.surface;
    ap.problem->pressures.push_back(std::move(p));
    out.push_back(std::move(cc));
  }
  return out;
}

core::hyperelastic::DynamicSettings accurate_dynamic_settings(const Scene& sc, const AccurateProblem& problem) {
  // One mass-proportional damping for the body: the accurate tier's step takes a single
  // alpha; stiffness-proportional damping is not available there.
  double alpha = -1;
  for (size_t r = 0; r < sc.model.region_damping.size(); ++r) {
    const core::RayleighDamping& d = sc.model.region_damping[r];
    if (d.stiffness_s != 0)
      throw SceneError(sc.name + ": regions[" + std::to_string(r) +
                       "].damping.stiffness: the accurate tier's time steps take mass damping only");
    if (alpha >= 0 && d.mass_1_s != alpha)
      throw SceneError(sc.name + ": regions[" + std::to_string(r) +
                       "].damping.mass: the accurate tier's time steps take one mass damping for the body");
    alpha = d.mass_1_s;
  }
  core::hyperelastic::DynamicSettings ds;
  ds.dt_s = sc.settings.dt_s;
  ds.mass_damping_1_s = std::max(alpha, 0.0);
  ds.newton = problem.newton;
  return ds;
}

core::hyperelastic::Loading accurate_loading(const Scene& sc, double t_s, std::vector<double>& tension, double contraction_origin_s) {
  core::hyperelastic::Loading l;
  for (const core::SurfaceLoad& load : sc.model.loads.surface_loads)
    l.pressure_factors.push_back(load.ramp_s > 0 ? std::min(1.0, t_s / load.ramp_s) : 1.0);
  const core::Contraction& c = sc.model.contraction;
  if (!c.enabled()) {
    tension.clear();
    l.active_factor = 0;
    return l;
  }
  const auto& regions = sc.model.mesh.regions();
  tension.resize(regions.size());
  for (size_t e = 0; e < regions.size(); ++e)
    tension[e] = c.tension(regions[e], c.element_delay_s.empty() ? 0.0 : c.element_delay_s[e], t_s - contraction_origin_s);
  l.active_tension_pa = &tension;
  return l;
}

core::Vec3 accurate_probe_displacement(const ElementMesh& mesh, const Probe& probe, const core::Positions& x) {
  const Eigen::Vector3d xi(probe.weights(1), probe.weights(2), probe.weights(3));
  const core::hyperelastic::TetShape sh = core::hyperelastic::tet_shape(mesh.order(), xi);
  const auto& nodes = mesh.elements()[static_cast<size_t>(probe.element)];
  core::Vec3 u = core::Vec3::Zero();
  for (int a = 0; a < mesh.nodes_per_element(); ++a) {
    const int n = nodes[static_cast<size_t>(a)];
    u += sh.N(a) * (x.col(n) - mesh.rest_positions().col(n));
  }
  return u;
}

}  // namespace fiberfem::io
