"""A plate whose bottom face carries an n x n grid of domes, meshed explicitly as one closed solid: the reference
the element's inner model is checked against (issue 36: "a small dot array, meshed explicitly and pushed as
geometry, against the same as an element")."""

from __future__ import annotations

import math

import numpy as np


def domed_plate(n: int, pitch: float, radius: float, height: float, thickness: float, segments: int = 48,
                rings: int = 8):
    """(vertices, triangles) of the plate [0, n pitch]^2 x [0, thickness] (m) with a dome (base `radius`, `height`,
    m) centred in each pitch cell of its bottom face, raised downwards (outward). Outward normals. `segments` (a
    multiple of 8, so that each cell's square has its corners) around each dome, `rings` from its rim to its apex.
    """
    assert segments % 8 == 0
    rs = (radius * radius + height * height) / (2.0 * height)
    phi_max = math.asin(radius / rs)
    theta = 2.0 * math.pi * np.arange(segments) / segments
    cos_t, sin_t = np.cos(theta), np.sin(theta)
    # the square's boundary at the same angles (the ray from the centre at theta meets it at distance s)
    s = 0.5 * pitch / np.maximum(np.abs(cos_t), np.abs(sin_t))
    verts: list[np.ndarray] = []
    tris: list[np.ndarray] = []
    count = 0

    def add(v, t):
        nonlocal count
        verts.append(np.asarray(v, float))
        tris.append(np.asarray(t, np.int64) + count)
        count += len(v)

    k = np.arange(segments)
    k1 = (k + 1) % segments
    for i in range(n):
        for j in range(n):
            cx, cy = (i + 0.5) * pitch, (j + 0.5) * pitch
            square = np.column_stack([cx + s * cos_t, cy + s * sin_t, np.zeros(segments)])
            circle = np.column_stack([cx + radius * cos_t, cy + radius * sin_t, np.zeros(segments)])
            # bottom annulus (normal -z, so wound clockwise seen from +z)
            v = np.vstack([square, circle])
            t = np.vstack([np.column_stack([k, k + segments, k1 + segments]), np.column_stack([k, k1 + segments, k1])])
            add(v, t)
            # the cap, ring 0 at the rim, the last ring the apex
            ring_v = [circle]
            for r in range(1, rings):
                phi = phi_max * (rings - r) / rings
                rr, z = rs * math.sin(phi), -((height - rs) + rs * math.cos(phi))
                ring_v.append(np.column_stack([cx + rr * cos_t, cy + rr * sin_t, np.full(segments, z)]))
            apex = np.array([[cx, cy, -height]])
            v = np.vstack([*ring_v, apex])
            t = []
            for r in range(rings - 1):
                a0, b0 = r * segments, (r + 1) * segments
                t.append(np.column_stack([a0 + k, b0 + k1, a0 + k1]))
                t.append(np.column_stack([a0 + k, b0 + k, b0 + k1]))
            last = (rings - 1) * segments
            t.append(np.column_stack([last + k, np.full(segments, rings * segments), last + k1]))
            add(v, np.vstack(t))
    size = n * pitch
    top = np.array([[0, 0, thickness], [size, 0, thickness], [size, size, thickness], [0, size, thickness]])
    add(top, [[0, 1, 2], [0, 2, 3]])
    # the four sides, each a fan from its top edge over the bottom boundary points of the cells along it
    edge = np.sort(np.unique(np.concatenate([(i + 0.5) * pitch + s * cos_t for i in range(n)]).round(15)))
    edge = edge[(edge >= -1e-15) & (edge <= size + 1e-15)]
    for axis, at, outward in ((1, 0.0, -1), (1, size, 1), (0, 0.0, -1), (0, size, 1)):
        pts = np.zeros((len(edge) + 2, 3))
        pts[:len(edge), 1 - axis] = edge
        pts[:len(edge), axis] = at
        pts[-2] = pts[0] + [0, 0, thickness]
        pts[-1] = pts[len(edge) - 1] + [0, 0, thickness]
        m = len(edge)
        t = [[m, q, q + 1] for q in range(m - 1)] + [[m, m - 1, m + 1]]
        t = np.array(t)
        normal = np.cross(pts[t[0, 1]] - pts[t[0, 0]], pts[t[0, 2]] - pts[t[0, 0]])
        if np.sign(normal[axis]) != outward:
            t = t[:, [0, 2, 1]]
        add(pts, t)
    return np.vstack(verts), np.vstack(tris)
