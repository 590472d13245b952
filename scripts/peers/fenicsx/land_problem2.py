"""Land et al. 2015 problem 2 in FEniCSx: the truncated ellipsoid ventricle (inner radii
7 and 17 mm, outer 10 and 20 mm, base at z = 5 mm held) of isotropic incompressible
Guccione material (C = 10 kPa, b_f = b_t = b_fs = 1), inflated by 10 kPa of follower
pressure on the endocardium; reports the deformed z of the inner apex (0, 0, -17) and
outer apex (0, 0, -20) mm. The mesh is fiberfem's lv_ellipsoid mesh node for node, with
its curved quadratic geometry (lv_ellipsoid.py; configs/scenes/land-ventricle-p2-guccione.yaml).

  python3 land_problem2.py --resolution 24 10 2 [--apex-grading 1.5] --load-steps 10 [--report out.json]
"""
import sys

import numpy as np
import ufl
from dolfinx import mesh
from mpi4py import MPI

import land_common
import lv_ellipsoid as lv


def add_mesh_arguments(ap):
    ap.add_argument("--resolution", type=int, nargs=3, required=True,
                    metavar=("CIRCUMFERENTIAL", "LONGITUDINAL", "TRANSMURAL"),
                    help="fiberfem's mesh.resolution of the lv_ellipsoid generator")
    ap.add_argument("--apex-grading", type=float, default=1.0,
                    help="fiberfem's mesh.apex_grading: ring k of K at the fraction (k/K)^G of the meridian (default 1)")


def on_endocardium(x):
    level = (x[0] ** 2 + x[1] ** 2) / lv.ENDO_RS ** 2 + x[2] ** 2 / lv.ENDO_RL ** 2 - 1
    return np.abs(level) < 1e-8


def main():
    args = land_common.arguments(__doc__.splitlines()[0], add_mesh_arguments)
    c, l, t = args.resolution

    def make_mesh():
        nodes, cells = lv.quadratic(c, l, t, args.apex_grading)
        coordinate_element = ufl.Mesh(ufl.VectorElement("Lagrange", ufl.tetrahedron, 2))
        domain = mesh.create_mesh(MPI.COMM_WORLD, cells, nodes, coordinate_element)
        fdim = domain.topology.dim - 1
        base = mesh.locate_entities_boundary(domain, fdim, lambda x: np.isclose(x[2], lv.BASE_Z, rtol=0, atol=1e-12))
        endo = mesh.locate_entities_boundary(domain, fdim, on_endocardium)
        return domain, base, endo

    law = {"C": 10.0, "b_f": 1.0, "b_t": 1.0, "b_fs": 1.0}
    return land_common.run(args, make_mesh, law, full_load=10.0,
                           probes={"apex_endo": (0.0, 0.0, -lv.ENDO_RL), "apex_epi": (0.0, 0.0, -lv.EPI_RL)},
                           mesh_description=f"lv_ellipsoid resolution {c} {l} {t}, apex grading {args.apex_grading:g}, "
                                            "curved 10-node tetrahedra")


if __name__ == "__main__":
    sys.exit(main())
