#pragma once
/// @file A scene on the accurate tier (material.law, mesh.order 2) as the problem its
/// Newton solver takes.

#include "core/hyperelastic/circulation_coupling.hpp"
#include "core/hyperelastic/dynamic.hpp"
#include "io/scene.hpp"

#include <memory>

namespace fiberfem::io {

struct AccurateProblem {
  std::shared_ptr<const core::hyperelastic::ElementMesh> mesh;
  std::shared_ptr<core::hyperelastic::Problem> problem;
  core::hyperelastic::NewtonSettings newton;
};

/// @throws SceneError when a region of an accurate scene has no law, or a law needs a
/// sheet direction that the fibers do not give. Nothing for other scenes.
void check_accurate(const Scene& scene);

/// The problem for an accurate scene (check_accurate first): the contraction held at each
/// region's peak tension, pressure loads on the boundary faces they name.
/// @throws SceneError for what the accurate tier does not take (point forces, traction vectors).
AccurateProblem accurate_problem(const Scene& scene);

/// A scene with a circulation: each coupled cavity's wall as a follower pressure load of
/// 1 Pa appended to `ap`'s problem (the coupling scales it by the cavity's pressure each
/// step; a static solve leaves them out by not calling this), and the cavities as the
/// coupling takes them. Empty without a circulation.
std::vector<core::hyperelastic::CoupledCavity> add_circulation_loads(const Scene& scene, AccurateProblem& ap);

/// The time-step settings of an accurate scene: solver.dt, the Newton keys, and the one
/// mass damping of the body. @throws SceneError when a region has stiffness damping or
/// the regions' mass dampings differ (the accurate tier's step takes one alpha).
core::hyperelastic::DynamicSettings accurate_dynamic_settings(const Scene& scene, const AccurateProblem& problem);

/// The loads of an accurate scene at time t_s: each traction at its ramp, the contraction's
/// tension per element (written into `tension_pa`, which the result points to; emptied when
/// the contraction is off).
core::hyperelastic::Loading accurate_loading(const Scene& scene, double t_s, std::vector<double>& tension_pa,
                                             double contraction_origin_s = 0);

/// A probe's displacement interpolated with the element's shape functions (all its nodes), m.
core::Vec3 accurate_probe_displacement(const core::hyperelastic::ElementMesh& mesh, const Probe& probe,
                                       const core::Positions& x);

}  // namespace fiberfem::io
