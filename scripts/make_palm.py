#!/usr/bin/env python3
"""Regenerates meshes/palm.msh: the paper's palm tree (Figs. 1 to 3), a trunk with a crown
of five leaves, meshed with linear tetrahedra by gmsh's OpenCASCADE kernel.

    .venv/bin/python scripts/make_palm.py [--size 0.01] [--out meshes/palm.msh]

Geometry (metres, z up): trunk a cylinder of radius TRUNK_R from z = 0 to TRUNK_H; five
leaves, flattened ellipsoids (semi-axes LEAF_A along the leaf, LEAF_B across, LEAF_C thick)
whose axis leaves the trunk top at azimuth 72 k degrees, tilted DROOP below horizontal,
their inner end buried in the trunk top. Physical groups: volumes "trunk" (tag 1) and
"leaves" (tag 2, conforming with the trunk where they meet); surface "base" (z = 0).
Leaf k's vein runs from leaf_base(k) to leaf_tip(k) below; scenes put strokes there.
"""
import argparse
import math

import gmsh
import gmsh_meshing

TRUNK_R, TRUNK_H = 0.018, 0.30
LEAF_A, LEAF_B, LEAF_C = 0.10, 0.025, 0.005
DROOP = math.radians(20.0)
N_LEAVES = 5


def leaf_axis(k):
    phi = 2 * math.pi * k / N_LEAVES
    return (math.cos(phi) * math.cos(DROOP), math.sin(phi) * math.cos(DROOP), -math.sin(DROOP))


def leaf_base(k):
    return (0.0, 0.0, TRUNK_H)


def leaf_tip(k):
    d = leaf_axis(k)
    c = leaf_centre(k)
    return tuple(c[i] + LEAF_A * d[i] for i in range(3))


def leaf_centre(k):
    d = leaf_axis(k)
    # The inner end reaches the trunk axis, so the leaf is anchored in the trunk top.
    return tuple((0.0, 0.0, TRUNK_H)[i] + LEAF_A * d[i] for i in range(3))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=float, default=0.01, help="target element size, m (default 0.01)")
    ap.add_argument("--out", default="meshes/palm.msh")
    args = ap.parse_args()
    occ = gmsh_meshing.start("palm")
    trunk = occ.addCylinder(0, 0, 0, 0, 0, TRUNK_H, TRUNK_R)
    leaves = []
    for k in range(N_LEAVES):
        c = leaf_centre(k)
        s = occ.addSphere(c[0], c[1], c[2], 1.0)
        occ.dilate([(3, s)], c[0], c[1], c[2], LEAF_A, LEAF_B, LEAF_C)
        phi = 2 * math.pi * k / N_LEAVES
        # Tilt down about the leaf's horizontal normal, then turn to its azimuth.
        occ.rotate([(3, s)], c[0], c[1], c[2], 0, 1, 0, DROOP)
        occ.rotate([(3, s)], c[0], c[1], c[2], 0, 0, 1, phi)
        leaves.append((3, s))
    crown, _ = occ.fuse([leaves[0]], leaves[1:]) if len(leaves) > 1 else (leaves, None)
    crown, _ = occ.cut(crown, [(3, trunk)], removeTool=False)
    out, _ = occ.fragment([(3, trunk)], crown)
    occ.synchronize()
    trunk_vols, leaf_vols = [], []
    for dim, tag in gmsh.model.getEntities(3):
        x, y, z = occ.getCenterOfMass(dim, tag)
        (trunk_vols if math.hypot(x, y) < TRUNK_R and z < TRUNK_H else leaf_vols).append(tag)
    if not trunk_vols or not leaf_vols:
        raise SystemExit(f"volume classification failed: trunk {trunk_vols}, leaves {leaf_vols}")
    base = []
    for dim, tag in gmsh.model.getBoundary([(3, t) for t in trunk_vols], oriented=False):
        if abs(occ.getCenterOfMass(2, tag)[2]) < 1e-9:
            base.append(tag)
    if not base:
        raise SystemExit("no base surface found")
    gmsh.model.addPhysicalGroup(3, trunk_vols, 1, name="trunk")
    gmsh.model.addPhysicalGroup(3, leaf_vols, 2, name="leaves")
    gmsh.model.addPhysicalGroup(2, base, 10, name="base")
    n_tets = gmsh_meshing.mesh_and_write(args.out, args.size, 0.5, 5)
    print(f"{args.out}: {n_tets} tetrahedra; trunk volumes {trunk_vols}, leaf volumes {leaf_vols}")
    for k in range(N_LEAVES):
        print(f"leaf {k}: base {leaf_base(k)}, tip {tuple(round(v, 5) for v in leaf_tip(k))}")
    gmsh.finalize()


if __name__ == "__main__":
    main()
