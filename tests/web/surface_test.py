"""The fields `fiberfem web` colours the surface with (clients/python/fiberfem_client/web/
surface.py), against closed-form deformations of a two-tetrahedron mesh:

- a stretch by s along the fiber gives fiber_strain s - 1 everywhere (and 0 for a stretch
  across it, and for a rigid rotation);
- displacement is the distance from the rest position;
- activation at a vertex is the mean of the elements of the boundary triangles around it;
- a frame encodes to 48 + 16 V bytes whose header and arrays read back.

    surface_test.py   (exit 0 when every check holds)"""

import struct
import sys

import numpy as np

from fiberfem_client.client import State, Topology
from fiberfem_client.web.protocol import FRAME_HEADER, encode_frame
from fiberfem_client.web.surface import FieldUnavailable, Surface


def two_tets(fiber) -> Topology:
    rest = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], dtype=np.float32) * 0.01
    tets = np.array([[0, 1, 2, 3], [1, 2, 3, 4]], dtype=np.int32)
    # The boundary: the 6 faces not shared (face 1-2-3 is interior), as the service lists them.
    triangles = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 4], [1, 4, 3], [2, 3, 4]], dtype=np.int32)
    tri_elements = np.array([0, 0, 0, 1, 1, 1], dtype=np.int32)
    fibers = np.tile(np.asarray(fiber, dtype=np.float32), (2, 1))
    return Topology("r", "two", "h", False, rest, tets, triangles, tri_elements, np.array([0, 1], dtype=np.int16),
                    ["a", "b"], fibers, np.zeros(0, dtype=np.int32), np.zeros(0, dtype=np.int32))


def state(positions, activation=(0.0, 0.0)) -> State:
    return State("r", 7, 0.5, 3, np.asarray(positions, dtype=np.float32), np.asarray(activation, dtype=np.float32))


def main() -> int:
    fiber = np.array([1.0, 2.0, 2.0]) / 3.0
    topo = two_tets(fiber)
    surf = Surface.of(topo)
    X = topo.rest_positions.astype(np.float64)
    assert surf.nodes.tolist() == [0, 1, 2, 3, 4] and surf.triangles.shape == (6, 3)

    # Stretch by 1.1 along the fiber: x = X + 0.1 (f . X) f.
    stretched = X + 0.1 * np.outer(X @ fiber, fiber)
    strain = surf.field("fiber_strain", state(stretched))
    assert np.allclose(strain, 0.1, atol=1e-5), strain
    # Across the fiber (a direction orthogonal to it) the fiber keeps its length.
    across = np.cross(fiber, [0.0, 0.0, 1.0])
    across /= np.linalg.norm(across)
    assert np.allclose(surf.field("fiber_strain", state(X + 0.2 * np.outer(X @ across, across))), 0.0, atol=1e-5)
    # A rigid rotation (90 degrees about z) strains nothing.
    rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    assert np.allclose(surf.field("fiber_strain", state(X @ rot.T)), 0.0, atol=1e-5)

    moved = X + np.array([0.003, -0.004, 0.0])
    assert np.allclose(surf.field("displacement", state(moved)), 0.005, atol=1e-7)

    # Vertex 0 touches only element 0's triangles, vertex 4 only element 1's, vertices 1-3
    # two triangles of each.
    act = surf.field("activation", state(X, (0.2, 0.8)))
    assert np.allclose(act, [0.2, 0.5, 0.5, 0.5, 0.8]), act
    # A vertex's region is its first boundary triangle's: only vertex 4 is first met in element 1.
    assert surf.field("region", state(X)).tolist() == [0, 0, 0, 0, 1]

    # Surface-only states cannot give the strain of interior elements.
    topo_s = two_tets(fiber)
    topo_s.state_nodes = np.array([0, 1, 2, 3, 4], dtype=np.int32)[::-1].copy()
    s_only = Surface.of(topo_s)
    reversed_positions = X[::-1]
    assert np.allclose(s_only.positions(state(reversed_positions)), X), "state rows mapped wrongly"
    try:
        s_only.field("fiber_strain", state(reversed_positions[:4]))
        raise AssertionError("fiber_strain of a partial state")
    except FieldUnavailable as e:
        print(f"partial state: {e}")

    data = encode_frame(7, 0.5, 1.5e12, 1.5e12 + 3, 3, "activation", surf.positions(state(moved)), act)
    assert len(data) == 48 + 16 * 5
    magic, v, frame, t, src, br, version, field = FRAME_HEADER.unpack_from(data)
    assert (magic, v, frame, t, src, br, version, field) == (b"FFW1", 5, 7.0, 0.5, 1.5e12, 1.5e12 + 3, 3, 0)
    assert np.allclose(np.frombuffer(data, "<f4", 15, 48).reshape(5, 3), moved, atol=1e-8)
    assert np.allclose(np.frombuffer(data, "<f4", 5, 48 + 60), act)
    assert struct.calcsize("<4sIdddd II") == 48
    print("fields and frame encoding: passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
