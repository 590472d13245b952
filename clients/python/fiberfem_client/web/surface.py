"""The boundary surface of a run's mesh as the page draws it, and the fields coloured on it.

The page draws the boundary triangles of the topology over their own vertex list (the
nodes the triangles use, in ascending node order), so a frame carries only those
vertices: 3 floats of position and 1 of the chosen field each (docs/web.md)."""

from dataclasses import dataclass

import numpy as np

from ..client import State, Topology

# The fields a page may ask for; the renderer's names (docs/rendering.md).
FIELDS = ("activation", "fiber_strain", "displacement", "region")


class FieldUnavailable(ValueError):
    """The run's states do not carry what a field needs."""


@dataclass
class Surface:
    run_id: str
    nodes: np.ndarray           # (V,) int32: mesh node of each surface vertex
    triangles: np.ndarray       # (F, 3) uint32 into the vertices, outward
    rest: np.ndarray            # (V, 3) float32, metres
    state_rows: np.ndarray      # (V,) int: row of each vertex in a state's positions
    vertex_of: np.ndarray       # (3F,) the vertex of each triangle corner
    element_of: np.ndarray      # (3F,) the element of each triangle corner
    corners: np.ndarray         # (V,) float: triangle corners at each vertex
    region: np.ndarray          # (V,) float32: region index of each vertex
    topology: Topology

    @classmethod
    def of(cls, topo: Topology) -> "Surface":
        nodes, local = np.unique(topo.triangles, return_inverse=True)
        triangles = local.reshape(-1, 3).astype(np.uint32)
        if topo.state_nodes.size:
            row_of = np.full(topo.rest_positions.shape[0], -1, dtype=np.int64)
            row_of[topo.state_nodes] = np.arange(topo.state_nodes.size)
            rows = row_of[nodes]
            if (rows < 0).any():
                raise FieldUnavailable("the states do not carry every boundary node")
        else:
            rows = nodes.astype(np.int64)
        vertex_of = triangles.ravel().astype(np.int64)
        element_of = np.repeat(topo.triangle_elements, 3)
        corners = np.bincount(vertex_of, minlength=nodes.size).astype(np.float64)
        # A vertex's region: that of the first boundary triangle that uses it.
        _, first = np.unique(vertex_of, return_index=True)
        region = topo.element_regions[element_of[first]].astype(np.float32)
        return cls(topo.run_id, nodes.astype(np.int32), triangles, topo.rest_positions[nodes], rows,
                   vertex_of, element_of, np.maximum(corners, 1.0), region, topo)

    def positions(self, state: State) -> np.ndarray:
        """(V, 3) float32 surface positions of a state."""
        return state.positions[self.state_rows]

    def field(self, name: str, state: State) -> np.ndarray:
        """(V,) float32 values of a field: activation (active tension / peak, 1), fiber_strain
        (stretch along the rest fiber minus 1), displacement (m), region (index)."""
        if name == "activation":
            return self._element_average(state.activation)
        if name == "fiber_strain":
            return self._element_average(self._fiber_strain(state))
        if name == "displacement":
            return np.linalg.norm(self.positions(state) - self.rest, axis=1).astype(np.float32)
        if name == "region":
            return self.region
        raise FieldUnavailable(f"unknown field '{name}' (fields: {', '.join(FIELDS)})")

    def _element_average(self, per_element: np.ndarray) -> np.ndarray:
        """A per-element value at each vertex: the mean over the boundary triangles around it."""
        if per_element.size != self.topology.tets.shape[0]:
            raise FieldUnavailable("the state has no per-element values for this field")
        sums = np.bincount(self.vertex_of, weights=per_element[self.element_of], minlength=self.nodes.size)
        return (sums / self.corners).astype(np.float32)

    def _fiber_strain(self, state: State) -> np.ndarray:
        """Per element: |F f| - 1 with F = Ds Dm^-1 the deformation gradient of the linear
        tetrahedron (edge matrices of the deformed and rest shapes) and f the unit rest fiber."""
        topo = self.topology
        if state.positions.shape[0] != topo.rest_positions.shape[0]:
            raise FieldUnavailable("fiber_strain needs every node (the service runs with --surface-only)")
        if topo.fibers.shape[0] != topo.tets.shape[0]:
            raise FieldUnavailable("fiber_strain needs the fibers (the topology has none)")
        if not hasattr(self, "_rest_inverse"):
            X = topo.rest_positions.astype(np.float64)[topo.tets]
            self._rest_inverse = np.linalg.inv(np.transpose(X[:, 1:] - X[:, :1], (0, 2, 1)))
            f = topo.fibers.astype(np.float64)
            self._fiber = f / np.maximum(np.linalg.norm(f, axis=1, keepdims=True), 1e-30)
        x = state.positions.astype(np.float64)[topo.tets]
        Ds = np.transpose(x[:, 1:] - x[:, :1], (0, 2, 1))
        stretched = np.einsum("eij,ejk,ek->ei", Ds, self._rest_inverse, self._fiber)
        return (np.linalg.norm(stretched, axis=1) - 1.0).astype(np.float32)
