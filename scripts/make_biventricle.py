#!/usr/bin/env python3
"""Regenerates meshes/biventricle.msh: a two-chamber heart (left and right ventricles, as in
the paper's Fig. 4) built from ellipsoids with gmsh's OpenCASCADE kernel and meshed with
linear tetrahedra.

    .venv/bin/python scripts/make_biventricle.py [--size 0.004] [--out meshes/biventricle.msh]

Geometry (metres; the long axis is z, apex down, base plane z = BASE_Z):
  LV: epicardium ellipsoid (rs 0.025, rl 0.045), endocardium (rs 0.015, rl 0.038), centred
      at the origin.
  RV: an ellipsoidal shell on the +x side, centred at (0.012, 0, 0.004): epicardium semi-axes
      (0.032, 0.026, 0.040), endocardium (0.028, 0.022, 0.036); its cavity is the RV
      endocardium outside the LV epicardium, so the septum is LV wall.
  Myocardium = (LV epi U RV epi) - LV cavity - RV cavity, cut at z = BASE_Z.
Physical groups: volumes "lv_wall" (tag 1: the LV free wall and the septum) and
"rv_free_wall" (tag 2: the tetrahedra whose centroid lies outside the LV epicardium), which
scenes select as regions by tag; surfaces "lv_endo", "rv_endo", "endo" (both), "epi", "base". fiberfem reads the groups' nodes as node sets (docs/mesh-formats.md).
The file is deterministic for a given gmsh version (pinned in scripts/requirements.txt).
"""
import argparse
import math

import gmsh
import gmsh_meshing

BASE_Z = 0.012
LV_EPI = (0.0, 0.0, 0.0, 0.025, 0.025, 0.045)
LV_ENDO = (0.0, 0.0, 0.0, 0.015, 0.015, 0.038)
RV_EPI = (0.012, 0.0, 0.004, 0.032, 0.026, 0.040)
RV_ENDO = (0.012, 0.0, 0.004, 0.028, 0.022, 0.036)


def ellipsoid(occ, e):
    cx, cy, cz, a, b, c = e
    tag = occ.addSphere(cx, cy, cz, 1.0)
    occ.dilate([(3, tag)], cx, cy, cz, a, b, c)
    return tag


def level(e, p):
    """Implicit function of an ellipsoid: 0 on it, < 0 inside."""
    cx, cy, cz, a, b, c = e
    return ((p[0] - cx) / a) ** 2 + ((p[1] - cy) / b) ** 2 + ((p[2] - cz) / c) ** 2 - 1.0


def classify(p):
    """Which named surface a boundary point lies on."""
    if abs(p[2] - BASE_Z) < 1e-6:
        return "base"
    d = {name: abs(level(e, p)) for name, e in
         (("lv_endo", LV_ENDO), ("lv_epi", LV_EPI), ("rv_endo", RV_ENDO), ("rv_epi", RV_EPI))}
    name = min(d, key=d.get)
    if name == "lv_epi":  # the septum's RV side lies on the LV epicardium, inside the RV cavity
        return "rv_endo" if level(RV_ENDO, p) < 0 else "epi"
    if name == "rv_epi":
        return "epi"
    return name


def split_rv_free_wall(volume):
    """Moves the tetrahedra whose centroid lies outside the LV epicardium (the RV free wall;
    the septum is LV wall) to a volume entity of their own, so that they carry their own
    physical tag. Element and node tags are kept and nodes are not reclassified, so the node
    numbering is the one-volume mesh's; returns the moved elements' count."""
    types, elements, nodes = gmsh.model.mesh.getElements(3, volume)
    if list(types) != [4]:
        raise SystemExit(f"expected linear tetrahedra only, got element types {list(types)}")
    node_tags, coords, _ = gmsh.model.mesh.getNodes()
    where = {int(t): coords[3 * i:3 * i + 3] for i, t in enumerate(node_tags)}
    moved, moved_nodes = [], []
    for k, tag in enumerate(elements[0]):
        corners = [int(n) for n in nodes[0][4 * k:4 * k + 4]]
        centroid = [sum(where[n][j] for n in corners) / 4 for j in range(3)]
        if level(LV_EPI, centroid) > 0:
            moved.append(int(tag))
            moved_nodes.extend(corners)
    rv_wall = gmsh.model.addDiscreteEntity(3)
    gmsh.model.mesh.removeElements(3, volume, moved)
    gmsh.model.mesh.addElementsByType(rv_wall, 4, moved, moved_nodes)
    gmsh.model.addPhysicalGroup(3, [rv_wall], 2, name="rv_free_wall")
    return len(moved)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=float, default=0.004, help="target element size, m (default 0.004)")
    ap.add_argument("--out", default="meshes/biventricle.msh")
    args = ap.parse_args()

    occ = gmsh_meshing.start("biventricle")
    lv_epi, lv_endo = ellipsoid(occ, LV_EPI), ellipsoid(occ, LV_ENDO)
    rv_epi, rv_endo = ellipsoid(occ, RV_EPI), ellipsoid(occ, RV_ENDO)
    # RV cavity: RV endocardium outside the LV epicardium (keep a copy of the LV epi).
    lv_epi_copy = occ.copy([(3, lv_epi)])
    rv_cavity, _ = occ.cut([(3, rv_endo)], lv_epi_copy)
    outer, _ = occ.fuse([(3, lv_epi)], [(3, rv_epi)])
    wall, _ = occ.cut(outer, [(3, lv_endo)] + rv_cavity)
    top = occ.addBox(-0.1, -0.1, BASE_Z, 0.2, 0.2, 0.1)
    heart, _ = occ.cut(wall, [(3, top)])
    occ.synchronize()
    vols = [t for d, t in gmsh.model.getEntities(3)]
    if len(vols) != 1:
        raise SystemExit(f"expected one volume, got {len(vols)}")

    groups = {"lv_endo": [], "rv_endo": [], "epi": [], "base": []}
    for dim, tag in gmsh.model.getBoundary([(3, vols[0])], oriented=False):
        lo, hi = gmsh.model.getParametrizationBounds(2, tag)
        p = gmsh.model.getValue(2, tag, [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2])
        groups[classify(p)].append(tag)
    for name, tags in groups.items():
        if not tags:
            raise SystemExit(f"no surface classified as {name}")
    gmsh.model.addPhysicalGroup(3, vols, 1, name="lv_wall")
    for i, name in enumerate(["lv_endo", "rv_endo", "epi", "base"]):
        gmsh.model.addPhysicalGroup(2, groups[name], 10 + i, name=name)
    gmsh.model.addPhysicalGroup(2, groups["lv_endo"] + groups["rv_endo"], 20, name="endo")

    rv_wall = []
    n_tets = gmsh_meshing.mesh_and_write(args.out, args.size, 0.5, 12,
                                         before_write=lambda: rv_wall.append(split_rv_free_wall(vols[0])))
    print(f"{args.out}: {n_tets} tetrahedra ({rv_wall[0]} in the RV free wall); surfaces: "
          + ", ".join(f"{k} {v}" for k, v in groups.items()))
    gmsh.finalize()


if __name__ == "__main__":
    main()
