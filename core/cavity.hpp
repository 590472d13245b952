#pragma once
/// @file Cavity volumes: the volume a part of the boundary (an endocardium) encloses, closed
/// across its open rim (the base), for ejection fractions.

#include "core/mesh.hpp"

#include <cstdint>
#include <vector>

namespace fiberfem::core {

/// The triangles of a cavity wall and the rim where it is open.
struct CavitySurface {
  std::vector<Tri> faces;                        ///< Boundary triangles, oriented out of the solid (into the cavity).
  std::vector<std::pair<int, int>> rim_edges;    ///< Edges (u, v) used by one face only, as oriented in it.
  std::vector<int> rim_nodes;                    ///< Nodes of the rim, sorted.
};

/// The boundary triangles whose three nodes all lie in `surface_nodes`, and their rim.
/// @throws std::invalid_argument if no boundary triangle qualifies.
CavitySurface cavity_surface(const TetMesh& mesh, const std::vector<int>& surface_nodes);

/// Volume enclosed by the surface closed by a fan of triangles from the rim's centroid
/// (positions `x`, 3 x N, metres): (1/6) sum of a . (b x c) over the closed, cavity-outward
/// triangles, m^3. Positive for a cavity; exact for the polyhedron, invariant under rigid
/// motions. A surface without a rim is closed already.
double cavity_volume(const CavitySurface& surface, const Eigen::Ref<const Positions>& x);
/// d cavity_volume / d x (3 x N, zero off the surface and its rim), m^2.
Positions cavity_volume_gradient(const CavitySurface& surface, const Eigen::Ref<const Positions>& x);

/// Rim nodes of `surface` with a component not fixed in `fixed_dofs` (3 per node; empty:
/// nothing fixed). A cavity loaded by a pressure is closed when this is 0: the lid across
/// its rim does not move, so the pressure works on exactly the volume cavity_volume measures.
int open_rim_nodes(const CavitySurface& surface, const std::vector<std::uint8_t>& fixed_dofs);

}  // namespace fiberfem::core
