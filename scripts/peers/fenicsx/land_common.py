"""What the two Land et al. 2015 problems share in FEniCSx (dolfinx 0.5.2): the mixed
Taylor-Hood space (P2 displacement, P1 pressure), the incompressible Guccione law written
in the isochoric Green strain Ebar = (J^(-2/3) C - I)/2 (the form fiberfem's laws use;
with the plain strain E, Newton stalls on problem 2 on fine meshes), the follower pressure
traction -p J F^-T N, Newton with a direct LU (MUMPS) and load stepping with halving, the
probes read at mesh nodes, and the timing and JSON report. Units: mm and kPa."""
import argparse
import json
import time

import numpy as np
import ufl
from dolfinx import fem, log
from dolfinx.fem.petsc import NonlinearProblem
from dolfinx.nls.petsc import NewtonSolver
from mpi4py import MPI
from petsc4py import PETSc


def arguments(description, add_mesh_arguments):
    ap = argparse.ArgumentParser(description=description)
    add_mesh_arguments(ap)
    ap.add_argument("--quadrature-degree", type=int, default=2,
                    help="degree of the cell and facet quadrature (default 2: 4 points per tetrahedron, "
                         "fiberfem's default rule for quadratic tetrahedra)")
    ap.add_argument("--facet-quadrature-degree", type=int, default=4,
                    help="degree of the quadrature on the loaded faces (default 4: 6 points per triangle, "
                         "fiberfem's rule for the faces of quadratic tetrahedra)")
    ap.add_argument("--load-steps", type=int, required=True, help="equal load increments (halved on failure)")
    ap.add_argument("--rtol", type=float, default=1e-9, help="Newton: residual norm relative to the first of "
                                                             "each increment (default 1e-9)")
    ap.add_argument("--strain", choices=("isochoric", "plain"), default="isochoric",
                    help="the Green strain the law is written in: isochoric (J^(-2/3) C - I)/2, as fiberfem, "
                         "or plain (C - I)/2 (default isochoric)")
    ap.add_argument("--report", help="write the results as JSON here")
    ap.add_argument("--verbose", action="store_true", help="print dolfinx's Newton log")
    return ap.parse_args()


def guccione(F, strain, C, b_f, b_t, b_fs):
    """W = C/2 (exp(Q) - 1) in the isochoric (or plain) Green strain, fibers along x, sheets
    along y (fiber frame = the Cartesian axes)."""
    scale = ufl.det(F) ** (-2.0 / 3.0) if strain == "isochoric" else 1.0
    E = 0.5 * (scale * F.T * F - ufl.Identity(3))
    Q = (b_f * E[0, 0] ** 2
         + b_t * (E[1, 1] ** 2 + E[2, 2] ** 2 + E[1, 2] ** 2 + E[2, 1] ** 2)
         + b_fs * (E[0, 1] ** 2 + E[1, 0] ** 2 + E[0, 2] ** 2 + E[2, 0] ** 2))
    return 0.5 * C * (ufl.exp(Q) - 1)


class Timer:
    def __init__(self):
        self.phases = {}

    def measure(self, name, fn, *args, **kwargs):
        t0 = time.perf_counter()
        out = fn(*args, **kwargs)
        self.phases[name] = self.phases.get(name, 0.0) + time.perf_counter() - t0
        return out


class LandProblem:
    """The mixed problem on `domain`: law parameters, Dirichlet facets (every displacement
    component held) and the facets carrying the follower pressure."""

    def __init__(self, domain, law, strain, fixed_facets, pressure_facets, quadrature_degree, facet_quadrature_degree):
        self.domain = domain
        cell = domain.ufl_cell()
        P2 = ufl.VectorElement("Lagrange", cell, 2)
        P1 = ufl.FiniteElement("Lagrange", cell, 1)
        self.W = fem.FunctionSpace(domain, ufl.MixedElement([P2, P1]))
        self.V, _ = self.W.sub(0).collapse()
        self.w = fem.Function(self.W)
        u, p = ufl.split(self.w)
        v, q = ufl.TestFunctions(self.W)

        fdim = domain.topology.dim - 1
        zero = fem.Function(self.V)
        dofs = fem.locate_dofs_topological((self.W.sub(0), self.V), fdim, fixed_facets)
        self.bcs = [fem.dirichletbc(zero, dofs, self.W.sub(0))]
        from dolfinx.mesh import meshtags
        order = np.argsort(pressure_facets)
        tags = meshtags(domain, fdim, pressure_facets[order], np.ones(len(order), dtype=np.int32))
        dx = ufl.Measure("dx", domain=domain, metadata={"quadrature_degree": quadrature_degree})
        ds = ufl.Measure("ds", domain=domain, subdomain_data=tags,
                         metadata={"quadrature_degree": facet_quadrature_degree})

        F = ufl.Identity(3) + ufl.grad(u)
        J = ufl.det(F)
        self.load = fem.Constant(domain, PETSc.ScalarType(0.0))
        energy = guccione(F, strain, **law) * dx - p * (J - 1) * dx
        N = ufl.FacetNormal(domain)
        residual = ufl.derivative(energy, self.w, ufl.TestFunction(self.W)) \
            + self.load * J * ufl.inner(ufl.inv(F).T * N, v) * ds(1)
        del q
        jacobian = ufl.derivative(residual, self.w, ufl.TrialFunction(self.W))
        # UFL caches a form's signature (the JIT cache key) at its first use. Compiling the
        # residual changes the signature the Jacobian would get afterwards, so without this
        # the Jacobian is compiled again by the second run (dolfinx 0.5.2, UFL 2022.2).
        residual.signature(), jacobian.signature()
        self.problem = NonlinearProblem(residual, self.w, self.bcs, jacobian)

    def solver(self, rtol):
        s = NewtonSolver(MPI.COMM_WORLD, self.problem)
        s.convergence_criterion = "residual"
        s.rtol, s.atol, s.max_it = rtol, 1e-14, 30
        s.report = True
        ksp = s.krylov_solver
        opts = PETSc.Options()
        prefix = ksp.getOptionsPrefix()
        opts[f"{prefix}ksp_type"] = "preonly"
        opts[f"{prefix}pc_type"] = "lu"
        opts[f"{prefix}pc_factor_mat_solver_type"] = "mumps"
        ksp.setFromOptions()
        s.set_update(self._update)
        return s

    @staticmethod
    def _update(solver, dx, x):
        """dolfinx's own update (x -= dx), but a non-finite Newton step ends the solve at
        once instead of iterating on NaN until max_it."""
        if not np.isfinite(dx.norm()):
            raise FloatingPointError("non-finite Newton step")
        x.axpy(-1.0, dx)

    def solve(self, full_load, load_steps, rtol):
        """Load stepping from 0 to full_load in increments of 1/load_steps; an increment
        that fails is halved (at most 10 times in the solve) and the increment doubles back
        after a success, up to 1/load_steps. A failed Newton solve leaves the LU factor of
        a NaN matrix behind, so the solver is rebuilt after each failure.
        Returns (converged, load factor reached, increments, Newton iterations, cut-backs);
        on failure the state is the last converged one."""
        solver = self.solver(rtol)
        largest = 1.0 / load_steps
        reached, step, increments, iterations, cutbacks = 0.0, largest, 0, 0, 0
        saved = self.w.x.array.copy()
        while reached < 1.0 - 1e-12:
            target = min(1.0, reached + step)
            self.load.value = target * full_load
            try:
                n, ok = solver.solve(self.w)
            except (RuntimeError, FloatingPointError):
                n, ok = 0, False
            iterations += n
            ok = ok and np.all(np.isfinite(self.w.x.array))
            if ok:
                reached, increments = target, increments + 1
                saved[:] = self.w.x.array
                step = min(largest, 2 * step)
            else:
                cutbacks += 1
                self.w.x.array[:] = saved
                self.w.x.scatter_forward()
                if cutbacks > 10:
                    return False, reached, increments, iterations, cutbacks
                step *= 0.5
                solver = self.solver(rtol)
        return True, reached, increments, iterations, cutbacks

    def unknowns(self):
        """(all unknowns, those not held by the Dirichlet condition)."""
        total = self.W.dofmap.index_map.size_global * self.W.dofmap.index_map_bs
        return total, total - self.bcs[0].dof_indices()[1]

    def node_z(self, point):
        """Deformed z at the displacement node at `point` (mm); the probes are mesh nodes."""
        coords = self.V.tabulate_dof_coordinates()
        i = int(np.argmin(np.linalg.norm(coords - np.asarray(point), axis=1)))
        if np.linalg.norm(coords[i] - point) > 1e-8:
            raise ValueError(f"no mesh node at {point} (nearest {coords[i]})")
        u = self.w.sub(0).collapse()
        return float(point[2] + u.x.array.reshape(-1, 3)[i, 2])


def run(args, make_mesh, law, full_load, probes, mesh_description):
    """Builds, solves and reports; times every phase after the imports."""
    if args.verbose:
        log.set_log_level(log.LogLevel.INFO)
    timer = Timer()
    t0 = time.perf_counter()
    domain, fixed, pressure = timer.measure("mesh_s", make_mesh)
    lp = timer.measure("setup_s", LandProblem, domain, law, args.strain, fixed, pressure, args.quadrature_degree,
                       args.facet_quadrature_degree)
    converged, load_factor, increments, iterations, cutbacks = timer.measure(
        "solve_s", lp.solve, full_load, args.load_steps, args.rtol)
    values = {name: lp.node_z(point) for name, point in probes.items()}
    wall = time.perf_counter() - t0
    report = {"code": "FEniCSx (dolfinx) " + __import__("dolfinx").__version__,
              "mesh": mesh_description, "unknowns": lp.unknowns()[0], "free_unknowns": lp.unknowns()[1],
              "strain": args.strain, "quadrature_degree": args.quadrature_degree, "facet_quadrature_degree": args.facet_quadrature_degree, "converged": converged, "load_factor": load_factor,
              "load_steps": increments, "newton_iterations": iterations, "cutbacks": cutbacks,
              "probes_z_mm": values, "timing": {"wall_s": wall, **timer.phases}}
    print(json.dumps(report, indent=1))
    if args.report:
        with open(args.report, "w") as f:
            json.dump(report, f, indent=1)
    return 0 if converged else 1
