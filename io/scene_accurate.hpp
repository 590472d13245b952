#pragma once
/// @file A scene on the accurate tier (material.law, mesh.order 2) as the problem its
/// Newton solver takes.

#include "core/hyperelastic/newton.hpp"
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

/// A probe's displacement interpolated with the element's shape functions (all its nodes), m.
core::Vec3 accurate_probe_displacement(const core::hyperelastic::ElementMesh& mesh, const Probe& probe,
                                       const core::Positions& x);

}  // namespace fiberfem::io
