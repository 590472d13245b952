#pragma once
/// @file Idealised left ventricle: a truncated thick-walled ellipsoid of revolution.

#include "core/mesh.hpp"

namespace fiberfem::core {

/// Geometry and resolution of a truncated ellipsoidal shell. Defaults are the
/// benchmark left ventricle of Land et al. 2015 (Proc. R. Soc. A 471: 20150641), in metres.
///
/// Each surface is the ellipsoid of revolution x = rs sin(u) cos(v), y = rs sin(u) sin(v),
/// z = rl cos(u), u in [u_base, pi] (apex at u = pi, i.e. z = -rl), v in [0, 2 pi),
/// cut by the base plane z = base_z_m (u_base = acos(base_z_m / rl)). The wall between the
/// endocardium (t = 0) and the epicardium (t = 1) is the family of ellipsoids whose radii
/// are interpolated linearly in the transmural coordinate t.
struct LvEllipsoidSpec {
  /// Endocardial short-axis (x, y) radius, metres; > 0, < epi_rs_m. Default 0.007.
  double endo_rs_m = 0.007;
  /// Endocardial long-axis (z) radius, metres; > 0, < epi_rl_m. Default 0.017.
  double endo_rl_m = 0.017;
  /// Epicardial short-axis radius, metres; > endo_rs_m, finite. Default 0.010.
  double epi_rs_m = 0.010;
  /// Epicardial long-axis radius, metres; > endo_rl_m, finite. Default 0.020.
  double epi_rl_m = 0.020;
  /// Height of the base plane, metres; in (-endo_rl_m, endo_rl_m) exclusive, so the cavity
  /// is closed below the base and open above it. Default 0.005.
  double base_z_m = 0.005;
  /// Nodes around the base ring (and every ring away from the apex); >= 6. Default 24.
  int circumferential = 24;
  /// Node rings from the apex (one node) to the base, both included; >= 2. Default 10.
  int longitudinal = 10;
  /// Element layers through the wall; >= 1. Default 3.
  int transmural = 3;
  /// Grading of the rings towards the apex, exponent p: ring k of K sits at the fraction
  /// (k / K)^p of the apex-to-base meridian. 1 spaces them evenly; p > 1 puts them closer
  /// near the apex (spacing about p (k / K)^(p - 1) / K), where the helix fibers of a
  /// ventricle meet; in [1, 3]. Default 1.
  double apex_grading = 1.0;

  /// @throws std::invalid_argument naming the offending field.
  void validate() const;
};

/// Builds the truncated ellipsoidal shell, with good element shapes at every resolution
/// (no collapsed grid at the apex).
///
/// Construction. One triangulation of a polar parameter disk serves every surface of the
/// wall: the apex is its centre, the polar radius s in [0, 1] is the fraction of the
/// meridional arc length from the apex to the base (measured on each surface separately),
/// the polar angle is v. Ring k = 0 .. K (K = longitudinal - 1) sits at s = (k / K)^p
/// (p = apex_grading, 1 by default: evenly spaced) and holds
/// n_k = min(C, max(6 k, ceil(C k / K))) nodes evenly spaced in v (C = circumferential;
/// 1 node at k = 0), so near the apex the rings grow like the hexagonal rings of an
/// equilateral lattice and every ring away from it has C nodes; rings of equal size are
/// staggered by half a step. Consecutive rings are stitched by a sweep that always adds the
/// triangle whose new vertex has the smaller angle, which gives nearly isosceles triangles.
/// The disk is repeated on transmural + 1 ellipsoids (t evenly spaced in [0, 1]) and each
/// pair of triangles one layer apart forms a prism, split into three tetrahedra by the
/// global-index rule (each quad face is cut along the diagonal through its lowest-numbered
/// node), which is conforming across neighbouring prisms. Tetrahedra are positively
/// oriented (`reoriented_elements()` is empty).
///
/// Node numbering: in-plane node p (ring by ring from the apex) on layer t has id
/// p (transmural + 1) + t, so the bandwidth is about (transmural + 1) times a ring size.
/// Node sets: "endo" (layer t = 0), "epi" (t = 1), "base" (the outermost ring of every
/// layer, exactly on z = base_z_m), "apex_endo" and "apex_epi" (the apex node of each
/// surface, at (0, 0, -rl)). All regions are 0. Elements are ordered prism by prism, ring
/// by ring from the apex, with a prism's layers from endo to epi.
///
/// Quality. Every prism has a tetrahedron standing on its top or bottom triangle, so the
/// smallest dihedral angle is set by the prisms' proportions, A = meridional spacing / layer
/// thickness and B = circumferential spacing at the base / meridional spacing (spacings on
/// the epicardium, thickness at the apex), not by the apex. Measured over 1100 resolutions
/// of the default geometry with 0.7 <= A <= 3.3 and 0.5 <= B <= 1.5: smallest dihedral
/// angle >= 15 degrees, largest <= 131, radius ratio >= 0.36; (12, 4, 1), the default
/// (24, 10, 3), (48, 20, 4) and (96, 40, 6) give 18, 17, 24 and 32 degrees (the test prints
/// the table). Outside that range it degrades: about 8 degrees at A = 6, towards 0 as B
/// grows past 4 (too few nodes around for the number of rings); geometries with the base
/// close to the cavity's apex or top (|base_z_m| near endo_rl_m) degrade too. Grading
/// shrinks the apex prisms' meridional spacing against their thickness (A above):
/// apex_grading 1.5 keeps (24, 10, 2), (36, 15, 3) and (48, 20, 4) at 19 degrees, 2 takes
/// (36, 15, 3) down to 6, and 1.5 with six layers, (24, 10, 6), gives 6.
///
/// @throws std::invalid_argument if the spec is invalid (naming the field), or if the
/// resolution is so anisotropic that an element would be inverted or flat (e.g. 6 nodes
/// around and 200 rings: ring chords cut deeper than the ring spacing).
TetMesh make_lv_ellipsoid(const LvEllipsoidSpec& spec);

}  // namespace fiberfem::core
