#pragma once
/// @file Where the mid-edge nodes of a generated mesh go when the generator's surfaces are
/// curved: on the surface, not on the chord (ACCURATE.md section 3).

#include "core/hyperelastic/element_mesh.hpp"
#include "core/lv_ellipsoid.hpp"

namespace fiberfem::core::hyperelastic {

/// The placement for a mesh made by make_lv_ellipsoid(spec). The wall is the family of
/// ellipsoids of revolution whose radii are interpolated linearly in the transmural
/// coordinate w (0 on the endocardium, 1 on the epicardium; LvEllipsoidSpec); each corner's
/// w is found from its position. An edge node goes to the point of the ellipsoid at the
/// mean w of its corners closest to the edge's midpoint: the nodes of endocardial edges on
/// the endocardium, of epicardial edges on the epicardium, every other layer along its own
/// ellipsoid (so a coarse mesh's strongly curved apex does not tangle its elements). An
/// edge with both corners on the base plane goes to that ellipsoid's circle at
/// z = base_z_m exactly, so the base stays flat. Every resolution with longitudinal >= 3
/// gives untangled elements (measured for circumferential 6..48, longitudinal 3..16,
/// transmural 1..5); longitudinal 2, one element from the apex to the base, does not, and
/// ElementMesh refuses it.
/// @throws std::invalid_argument when the spec is invalid or a node of `mesh` is not in
/// the spec's wall (naming it).
EdgePlacement lv_ellipsoid_edge_placement(const LvEllipsoidSpec& spec, const TetMesh& mesh);

}  // namespace fiberfem::core::hyperelastic
