"""Supports of any outline (tracer.elements.outline, issue 53): on a round plate and on a washer, a feature is placed
only where its base lies wholly on the face, every feature well inside is placed, and a rectangle needs no mask."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracer.elements import prepare
from tracer.elements.outline import RESOLUTION
from tracer.scene import Scene

N = 64                 # sides of the round outline
R_OUT = 0.010          # m
THICK = 0.003
A, PITCH = 0.2, 0.5    # mm: the domes' base radius, the grid's pitch


def washer(r_out: float, r_in: float, n: int = N) -> tuple[np.ndarray, np.ndarray]:
    """A plate of thickness THICK whose faces are the n-gon of radius `r_out` (m, centred at (r_out, r_out)) less the
    n-gon of radius `r_in` (0: none); outward triangles."""
    ang = 2 * math.pi * np.arange(n) / n
    ring = np.column_stack([np.cos(ang), np.sin(ang)])
    c = np.array([r_out, r_out])
    k = np.arange(n)
    k1 = (k + 1) % n
    if r_in == 0:
        v = np.vstack([np.column_stack([c + r_out * ring, np.zeros(n)]), np.column_stack([c + r_out * ring,
                                                                                           np.full(n, THICK)]),
                       [[*c, 0.0], [*c, THICK]]])
        bottom = np.column_stack([np.full(n, 2 * n), k1, k])
        top = np.column_stack([np.full(n, 2 * n + 1), n + k, n + k1])
        side = np.vstack([np.column_stack([k, k1, n + k1]), np.column_stack([k, n + k1, n + k])])
        return v, np.vstack([bottom, top, side])
    rings = [c + r_out * ring, c + r_in * ring]
    v = np.vstack([np.column_stack([rings[0], np.zeros(n)]), np.column_stack([rings[1], np.zeros(n)]),
                   np.column_stack([rings[0], np.full(n, THICK)]), np.column_stack([rings[1], np.full(n, THICK)])])
    ob, ib, ot, it = 0, n, 2 * n, 3 * n
    bottom = np.vstack([np.column_stack([ob + k, ib + k1, ob + k1]), np.column_stack([ob + k, ib + k, ib + k1])])
    top = np.vstack([np.column_stack([ot + k, ot + k1, it + k1]), np.column_stack([ot + k, it + k1, it + k])])
    outer = np.vstack([np.column_stack([ob + k, ob + k1, ot + k1]), np.column_stack([ob + k, ot + k1, ot + k])])
    inner = np.vstack([np.column_stack([ib + k, it + k1, ib + k1]), np.column_stack([ib + k, it + k, it + k1])])
    return v, np.vstack([bottom, top, outer, inner])


def kept_sites(r_in: float) -> tuple[np.ndarray, np.ndarray]:
    """The grid's site centres (mm, from the frame's corner) and whether a ray straight down through each meets a
    feature, on the washer's bottom face."""
    s = Scene()
    v, t = washer(R_OUT, r_in)
    i = s.add_instance(s.add_geometry(v, t), np.eye(4))
    dots = prepare({"type": "microstructure", "feature": {"shape": "dome", "radius_mm": A, "height_mm": 0.1},
                    "layout": {"type": "grid", "pitch_mm": [PITCH, PITCH]}})
    s.set_element(i, dots, facing=[0, 0, -1])
    s.commit()
    n = int(2 * R_OUT * 1000 // PITCH)
    g = (np.arange(n) + 0.5) * PITCH
    cu, cv = (x.ravel() for x in np.meshgrid(g, g))
    # the bottom face's frame: u = x, v = n x u = -y, from the corner of smallest u and v: (0, 2 R, 0)
    o = np.column_stack([cu / 1000, 2 * R_OUT - cv / 1000, np.full(len(cu), THICK / 2)])
    hit = s.intersect(o, np.tile([0.0, 0.0, -1.0], (len(cu), 1)))
    return np.column_stack([cu, cv]), hit.primitive < -1


def _to_outline(p: np.ndarray, r_in: float) -> np.ndarray:
    """Distance (mm) from points inside the washer's polygon outline to it (the outer n-gon's edges, the inner's)."""
    c = R_OUT * 1000
    d = np.full(len(p), np.inf)
    for r in (R_OUT * 1000, r_in * 1000):
        if r == 0:
            continue
        ang = 2 * math.pi * np.arange(N + 1) / N
        poly = np.column_stack([c + r * np.cos(ang), c - r * np.sin(ang)])   # v = -y
        for a, b in zip(poly[:-1], poly[1:], strict=True):
            ab = b - a
            t = np.clip(((p - a) @ ab) / (ab @ ab), 0.0, 1.0)
            d = np.minimum(d, np.linalg.norm(p - (a + t[:, None] * ab), axis=1))
    return d


@pytest.mark.parametrize("r_in", [0.0, 0.004], ids=["round plate", "washer"])
def test_features_lie_wholly_on_a_face_of_any_outline_and_all_well_inside_are_placed(r_in: float) -> None:
    p, kept = kept_sites(r_in)
    centre = R_OUT * 1000
    rho = np.hypot(p[:, 0] - centre, p[:, 1] - centre)
    cos_half = math.cos(math.pi / N)
    on_face = (rho < R_OUT * 1000 * cos_half) & (rho > r_in * 1000)
    dist = np.where(on_face, _to_outline(p, r_in), -1.0)
    h = 2 * R_OUT * 1000 / RESOLUTION
    assert kept.any() and (dist[kept] >= A).all(), dist[kept].min()       # no base leaves the face
    assert kept[dist >= A + 2 * math.sqrt(2) * h].all()                    # everything well inside is placed
    assert not kept[dist < A].any()


def test_a_rectangular_face_needs_no_mask() -> None:
    from tests.tracer.elements.test_relief_geometry import dome, plate_scene

    s, i = plate_scene()
    s.set_element(i, dome(), facing=[0, 0, -1])
    s.commit()
    from tracer.elements import features as fx

    assert s.arrays().el_i[0, fx.MASK_NU] == 0
