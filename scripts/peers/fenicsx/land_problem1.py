"""Land et al. 2015 problem 1 in FEniCSx: the 10 x 1 x 1 mm beam of incompressible
Guccione material (C = 2 kPa, b_f = 8, b_t = 2, b_fs = 4, fibers along x), clamped at
x = 0, 4 Pa of follower pressure on the underside z = 0; reports the deformed z of the
point (10, 0.5, 1) mm. The mesh is dolfinx's box of hexahedral cells split into six
tetrahedra each, as fiberfem's box generator does (configs/scenes/land-beam-guccione.yaml).

  python3 land_problem1.py --cells 20 --load-steps 2 [--report out.json]
"""
import sys

import numpy as np
from dolfinx import mesh
from mpi4py import MPI

import land_common


def add_mesh_arguments(ap):
    ap.add_argument("--cells", type=int, required=True,
                    help="cells along the beam (x); a tenth of them (at least 1) along y and z")


def main():
    args = land_common.arguments(__doc__.splitlines()[0], add_mesh_arguments)
    n = args.cells
    m = max(1, n // 10)

    def make_mesh():
        domain = mesh.create_box(MPI.COMM_WORLD, [np.zeros(3), np.array([10.0, 1.0, 1.0])], [n, m, m],
                                 mesh.CellType.tetrahedron)
        fdim = domain.topology.dim - 1
        fixed = mesh.locate_entities_boundary(domain, fdim, lambda x: np.isclose(x[0], 0.0))
        bottom = mesh.locate_entities_boundary(domain, fdim, lambda x: np.isclose(x[2], 0.0))
        return domain, fixed, bottom

    law = {"C": 2.0, "b_f": 8.0, "b_t": 2.0, "b_fs": 4.0}
    return land_common.run(args, make_mesh, law, full_load=0.004, probes={"end": (10.0, 0.5, 1.0)},
                           mesh_description=f"box {n} x {m} x {m} cells, 6 tetrahedra each")


if __name__ == "__main__":
    sys.exit(main())
