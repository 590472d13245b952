#pragma once
/// @file Structured box meshes: hexahedral cells split into six tetrahedra each.

#include "core/mesh.hpp"

namespace fiberfem::core {

/// Parameters of a box mesh. Defaults make a 10 x 1 x 1 cm beam.
struct BoxSpec {
  /// Edge lengths along x, y, z, metres; each > 0. Default (0.1, 0.01, 0.01).
  Vec3 size_m{0.1, 0.01, 0.01};
  /// Hexahedral cells along x, y, z; each >= 1. Default (20, 2, 2).
  std::array<int, 3> cells{20, 2, 2};
  /// Position of the minimum corner, metres. Default the origin.
  Vec3 origin_m{0.0, 0.0, 0.0};

  /// @throws std::invalid_argument naming the offending field.
  void validate() const;
};

/// Builds the box. Each cell is split into six tetrahedra around its main diagonal (Kuhn
/// subdivision), which is conforming across cells. Nodes are numbered with the axis of most
/// cells varying slowest (small bandwidth for long beams). Node sets "xmin", "xmax", "ymin",
/// "ymax", "zmin", "zmax" hold the nodes of each face. Elements are ordered cell by cell,
/// so neighbouring element ids are neighbours in space. All regions are 0.
TetMesh make_box(const BoxSpec& spec);

}  // namespace fiberfem::core
