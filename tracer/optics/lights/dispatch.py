"""The light kinds' registration: the one place that lists them and switches on a kind id.

A kind's id is its position in `KINDS`. Adding a kind: its module (see `base`), its entry at the end of
`KINDS` with an id constant, and a branch in `sample_emission` and in `light_connect`. `sample_emission`
is inlined into the transport kernel, with the point light's `sample`: a call per photon passes the lights'
tuple (see `tracer.optics.surfaces.dispatch`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from tracer.optics.lights import area, collimated, goniometric, point, spot
from tracer.optics.lights.base import P_FLUX, LightArrays, LightError, Packing

KINDS = (point, spot, collimated, goniometric, area)
POINT, SPOT, COLLIMATED, GONIOMETRIC, AREA = 0, 1, 2, 3, 4
KIND_OF_NAME = {module.NAME: k for k, module in enumerate(KINDS)}


def pack_lights(lights: list[dict], scene=None, sensor_ids: frozenset = frozenset()) -> LightArrays:
    """Validate light bodies and pack them.

    Parameters
    ----------
    lights : list of light bodies (world metres), each with a ``"type"`` in `KIND_OF_NAME`.
    scene : tracer.Scene, needed for area lights (their triangles are read in world space).
    sensor_ids : instance ids that are sensors (an area light cannot be one).

    Raises
    ------
    LightError
        Unknown type or field, missing or out-of-range value, zero total flux, an area light on an
        unknown instance, a goniometric file that does not parse (the parser's message).
    """
    if not isinstance(lights, list | tuple) or not lights:
        raise LightError("lights: at least one light is needed")
    n = len(lights)
    kind = np.zeros(n, np.int32)
    out = Packing(n, scene, sensor_ids)
    for j, body in enumerate(lights):
        where = f"light {j}" + (f" ({body.get('id')})" if isinstance(body, dict) and body.get("id") else "")
        if not isinstance(body, dict):
            raise LightError(f"{where}: expected a light body (dict), got {type(body).__name__}")
        t = body.get("type")
        k = KIND_OF_NAME.get(t, -1) if isinstance(t, str) else -1
        if k < 0:
            raise LightError(f"{where}: unknown light type {t!r}; known: {sorted(KIND_OF_NAME)}")
        module = KINDS[k]
        kind[j] = k
        module.pack(module.Spec.from_body(body, where), j, out, where)
    fluxes = out.par[:, P_FLUX]
    total = float(fluxes.sum())
    if not total > 0:
        raise LightError("lights: the total flux is zero: nothing to simulate")
    cdf = np.cumsum(fluxes) / total
    return LightArrays(kind, out.par, cdf, np.array([total]), out.g_off, out.g_n, out.table("g_c", (0,)),
                       out.table("g_gamma", (0,)), out.table("g_cd", (0,)), out.table("g_cell_cdf", (0,)),
                       out.table("tri", (0, 9)), out.table("tri_n", (0, 3)), out.table("tri_cdf", (0,)), out.a_off,
                       out.a_area)


def connectable(L: LightArrays) -> tuple[bool, str]:
    """Whether next-event estimation can sample every light of L, and if not why ("" if it can)."""
    for k in sorted(set(int(k) for k in L.kind)):
        if not KINDS[k].CONNECTABLE:
            return False, KINDS[k].WHY_NOT_CONNECTABLE
    return True, ""


@njit(cache=True, _nrt=False, inline="always")
def sample_emission(L, j, u0, u1, u2, u3, u4):
    """Emit one photon from light j: (ox, oy, oz, dx, dy, dz, f, on_surface, nx, ny, nz), see `base`."""
    k = L.kind[j]
    if k == POINT:
        return point.sample(L, j, u0, u1, u2, u3, u4)
    if k == SPOT:
        return spot.sample(L, j, u0, u1, u2, u3, u4)
    if k == COLLIMATED:
        return collimated.sample(L, j, u0, u1, u2, u3, u4)
    if k == GONIOMETRIC:
        return goniometric.sample(L, j, u0, u1, u2, u3, u4)
    if k == AREA:
        return area.sample(L, j, u0, u1, u2, u3, u4)
    return 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, False, 0.0, 0.0, 0.0  # an id no kind has: a photon of weight 0


@njit(cache=True, _nrt=False)
def light_connect(L, j, x, y, z, nx, ny, nz, u1, u2, u3):
    """Next-event estimation toward light j from x (m) with unit normal n: (e, sx, sy, sz, t_max), see `base`."""
    k = L.kind[j]
    if k == POINT:
        return point.connect(L, j, x, y, z, nx, ny, nz, u1, u2, u3)
    if k == SPOT:
        return spot.connect(L, j, x, y, z, nx, ny, nz, u1, u2, u3)
    if k == COLLIMATED:
        return collimated.connect(L, j, x, y, z, nx, ny, nz, u1, u2, u3)
    if k == GONIOMETRIC:
        return goniometric.connect(L, j, x, y, z, nx, ny, nz, u1, u2, u3)
    if k == AREA:
        return area.connect(L, j, x, y, z, nx, ny, nz, u1, u2, u3)
    return 0.0, 0.0, 0.0, 0.0, 0.0  # an id no kind has: nothing arrives
