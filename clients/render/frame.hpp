#pragma once
/// @file One frame to draw, independent of where it comes from (a running simulator, an
/// archive, the live bus): borrowed views of the mesh, positions and per-element data.

#include "clients/render/pv_loop.hpp"
#include "core/mesh.hpp"

#include <string>
#include <vector>

namespace fiberfem::render {

/// A frame: everything is borrowed and must outlive the Renderer::render call.
struct FrameView {
  /// @param mesh the rest mesh (the one the Renderer was built for).
  /// @param x current positions, 3 x N, metres.
  FrameView(const core::TetMesh& mesh, Eigen::Ref<const core::Positions> x) : mesh(mesh), x(x) {}

  const core::TetMesh& mesh;
  Eigen::Ref<const core::Positions> x;
  /// Per element activation, tension / region peak, 1 (activation_from_tension()); needed
  /// for Field::activation.
  const std::vector<double>* activation = nullptr;
  /// Per element rest fiber, unit; needed for Field::fiber_strain and fiber glyphs.
  const std::vector<core::Vec3>* fibers = nullptr;
  /// Per element Dm^-1, 1/m; optional: without
  /// it the renderer uses its own copy for the surface elements (Surface::surface_dm_inv()).
  const std::vector<core::Mat3>* dm_inv = nullptr;
  /// The pressure-volume loops so far (a run with a circulation), drawn as an inset when
  /// RenderSettings::pv_inset is on; nullptr or empty: none.
  const PvLoop* pv_loop = nullptr;
  double time_s = 0;    ///< Simulated time, s (for callers' captions).
  std::string caption;  ///< Drawn at the top left when RenderSettings::caption is on.
};

}  // namespace fiberfem::render
