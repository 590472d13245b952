"""The truncated ellipsoid of Land et al. 2015 problem 2, built node for node as fiberfem's
`lv_ellipsoid` generator builds it (core/lv_ellipsoid.cpp: rings on a polar parameter
disk, prisms split into three tetrahedra by the lowest-index rule) with its quadratic
edge nodes placed as fiberfem places them (core/hyperelastic/curved_placement.cpp: on the
ellipsoid of the edge's mean transmural coordinate, base edges on the base circle), so
both codes solve on the same curved 10-node tetrahedra. Plain numpy, no dolfinx."""
import math

import numpy as np

ENDO_RS, ENDO_RL, EPI_RS, EPI_RL, BASE_Z = 7.0, 17.0, 10.0, 20.0, 5.0  # mm


def ring_size(k, K, C):
    if k == 0:
        return 1
    return min(C, max(6 * k, (C * k + K - 1) // K))


class Meridian:
    """Arc length from the apex along the meridian, tabulated by Simpson's rule."""
    INTERVALS = 1024

    def __init__(self, rs, rl, base_z):
        self.u_base = math.acos(base_z / rl)
        self.du = (math.pi - self.u_base) / self.INTERVALS
        speed = lambda u: math.hypot(rs * math.cos(u), rl * math.sin(u))
        arc = [0.0]
        for i in range(self.INTERVALS):
            u0 = math.pi - i * self.du
            arc.append(arc[-1] + self.du / 6 * (speed(u0) + 4 * speed(u0 - 0.5 * self.du) + speed(u0 - self.du)))
        self.arc = np.array(arc)

    def u_at(self, s):
        if s <= 0:
            return math.pi
        if s >= 1:
            return self.u_base
        target = s * self.arc[-1]
        i = int(np.searchsorted(self.arc, target, side="right")) - 1
        f = (target - self.arc[i]) / (self.arc[i + 1] - self.arc[i])
        return math.pi - (i + f) * self.du


def make_disk(K, C):
    first, angle, phase, tris = [0], [0.0], [0.0] * (K + 1), []
    for k in range(1, K + 1):
        n = ring_size(k, K, C)
        phase[k] = (k % 2) * 0.5
        first.append(len(angle))
        angle += [2 * math.pi * (j + phase[k]) / n for j in range(n)]
    first.append(len(angle))
    size = lambda k: first[k + 1] - first[k]
    n1 = size(1)
    tris += [(0, first[1] + (j + 1) % n1, first[1] + j) for j in range(n1)]
    for k in range(1, K):
        na, nb, a0, b0, pa, pb = size(k), size(k + 1), first[k], first[k + 1], phase[k], phase[k + 1]
        alpha = lambda i: 2 * math.pi * (i + pa) / na
        beta = lambda j: 2 * math.pi * (j + pb) / nb
        A = lambda i: a0 + i % na
        B = lambda j: b0 + j % nb
        j0 = int(math.floor(alpha(0) * nb / (2 * math.pi) - pb + 0.5))
        i, j = 0, j0
        while i < na or j < j0 + nb:
            if j == j0 + nb or (i < na and alpha(i + 1) <= beta(j + 1)):
                tris.append((A(i), A(i + 1), B(j)))
                i += 1
            else:
                tris.append((A(i), B(j + 1), B(j)))
                j += 1
    return first, angle, tris


def rs_rl(w):
    return ENDO_RS + w * (EPI_RS - ENDO_RS), ENDO_RL + w * (EPI_RL - ENDO_RL)


def corners(circumferential, longitudinal, transmural, grading=1.0):
    """Corner positions (n, 3) in mm and tetrahedra (m, 4), as make_lv_ellipsoid (ring k of K
    at the fraction (k / K)^grading of the meridian: mesh.apex_grading)."""
    K, T, L = longitudinal - 1, transmural, transmural + 1
    first, angle, tris = make_disk(K, circumferential)
    np_ = len(angle)
    x = np.zeros((np_ * L, 3))
    for t in range(L):
        rs, rl = rs_rl(t / T)
        meridian = Meridian(rs, rl, BASE_Z)
        x[t] = (0.0, 0.0, -rl)
        for k in range(1, K + 1):
            if k == K:
                c = BASE_Z / rl
                radius, z = rs * math.sqrt(1 - c * c), BASE_Z
            else:
                u = meridian.u_at((k / K) ** grading)
                radius, z = rs * math.sin(u), rl * math.cos(u)
            for p in range(first[k], first[k + 1]):
                x[p * L + t] = (radius * math.cos(angle[p]), radius * math.sin(angle[p]), z)
    tets = []
    for tri in tris:
        r = tri.index(min(tri))
        tri = tri[r:] + tri[:r]
        for t in range(T):
            v0, v1, v2 = (tri[0] * L + t, tri[1] * L + t, tri[2] * L + t)
            v3, v4, v5 = v0 + 1, v1 + 1, v2 + 1
            tets.append((v0, v3, v4, v5))
            if min(v1, v5) < min(v2, v4):
                tets += [(v0, v1, v2, v5), (v0, v1, v5, v4)]
            else:
                tets += [(v0, v1, v2, v4), (v0, v4, v2, v5)]
    return x, np.array(tets, dtype=np.int64)


def transmural_coordinate(p):
    """w of the wall ellipsoid through p (bisection; the level decreases in w)."""
    lo, hi = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        rs, rl = rs_rl(mid)
        level = (p[0] ** 2 + p[1] ** 2) / rs ** 2 + p[2] ** 2 / rl ** 2 - 1
        if level > 0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def closest_point(rs, rl, m):
    rs2, rl2 = rs * rs, rl * rl
    r2, z2 = m[0] ** 2 + m[1] ** 2, m[2] ** 2
    t = 0.0
    for _ in range(50):
        a, b = rs2 / (rs2 + t), rl2 / (rl2 + t)
        g = r2 * a * a / rs2 + z2 * b * b / rl2 - 1
        dg = -2 * (r2 * a * a / (rs2 * (rs2 + t)) + z2 * b * b / (rl2 * (rl2 + t)))
        step = g / dg
        t -= step
        if abs(step) <= 1e-16 * max(rs2, abs(t)):
            break
    return np.array([m[0] * rs2 / (rs2 + t), m[1] * rs2 / (rs2 + t), m[2] * rl2 / (rl2 + t)])


def edge_node(w, on_base, a, b, xa, xb):
    m = 0.5 * (xa + xb)
    wm = 0.5 * (w[a] + w[b])
    rs, rl = rs_rl(wm)
    if on_base[a] and on_base[b]:
        c = BASE_Z / rl
        xy = m[:2] / np.linalg.norm(m[:2]) * rs * math.sqrt(1 - c * c)
        return np.array([xy[0], xy[1], BASE_Z])
    return closest_point(rs, rl, m)


# basix's (DOLFINx's) P2 tetrahedron: vertices, then one node per edge in this order.
BASIX_TET_EDGES = ((2, 3), (1, 3), (1, 2), (0, 3), (0, 2), (0, 1))


def quadratic(circumferential, longitudinal, transmural, grading=1.0):
    """10-node tetrahedra in basix order: node positions (n, 3) mm and cells (m, 10)."""
    x, tets = corners(circumferential, longitudinal, transmural, grading)
    w = [transmural_coordinate(p) for p in x]
    on_base = x[:, 2] == BASE_Z
    nodes = list(x)
    edge_id = {}
    cells = np.zeros((len(tets), 10), dtype=np.int64)
    cells[:, :4] = tets
    for c, tet in enumerate(tets):
        for e, (i, j) in enumerate(BASIX_TET_EDGES):
            a, b = int(tet[i]), int(tet[j])
            key = (min(a, b), max(a, b))
            if key not in edge_id:
                edge_id[key] = len(nodes)
                nodes.append(edge_node(w, on_base, a, b, x[a], x[b]))
            cells[c, 4 + e] = edge_id[key]
    return np.array(nodes), cells
