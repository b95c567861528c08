"""Area light: Lambertian emission from the front side of every triangle of some instances, or of those facing one way.

The front side is the geometric normal's (e1 × e2 in world space; a mirrored instance keeps its
outward side). Radiance M/π, Φ = M × area. `node` is the service's; the transport reads `instances`.
With `facing`, only the triangles whose front normal, in their part's own frame, lies within `FACING_DEG` of it emit
(an LED package's lens face, not its sides and back: issue 53); the flux is M × their area. With `faces`, only the
triangles of those B-rep faces emit (each part's mesh gives each triangle's face: `Scene.add_geometry`'s `face_ids`,
which the CAD adapter sends): a face that no direction singles out, a curved lens or one of two parallel faces.

==============  ==================  =====  ====================================
Field           Type                Unit   Default
==============  ==================  =====  ====================================
instances       non-empty int list  —      required (instance ids, not sensors)
exitance_lm_m2  float ≥ 0           lm/m²  required
facing          [x, y, z], not 0    —      every triangle (a direction in each part's own frame)
faces           non-empty int list  —      every triangle (B-rep face indices; not with `facing`)
node            any                 —      ignored (the service's: its FIELDS value "node" gives `instances`)
==============  ==================  =====  ====================================

Parameter row: P_I0 exitance M (lm/m²), P_FLUX flux (lm). Tables: tri, tri_n, tri_cdf, found through
a_off; a_area the total area (m²) (see `LightArrays`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tracer.geometry_id import MAX_FACE_INDEX
from tracer.jit import njit
from tracer.optics.fields import BodyField, fields
from tracer.optics.frames import find_in_cdf, sample_cosine
from tracer.optics.lights.base import (
    AREA_EMITTER,
    P_FLUX,
    P_I0,
    SHADOW_SHORTEN,
    LightError,
    Packing,
    check_fields,
    field_value,
)
from tracer.optics.polarization import unit_axis

NAME = "area"
FACING_DEG = 1.0   # a triangle faces `facing` within this angle (as an element's support: tracer.elements.support)
FIELDS = fields(
    BodyField("node", "node", "The node (UUID or path) whose surfaces, with its descendants', emit."),
    BodyField("exitance_lm_m2", "number", "Luminous exitance of the surfaces, lm/m².", lo=0.0, hi=1e15),
    BodyField("facing", "part_dir", "Only the triangles facing this way emit: a direction in each part's own frame "
                                    f"(as an element's `facing`), within {FACING_DEG:g}°; default every triangle.",
              required=False),
    BodyField("faces", "faces", "Only the triangles of these B-rep faces emit: face indices of each emitting part's "
                                "mesh, as the CAD adapter numbers them (as an element's `faces`); default every "
                                "triangle. Not with `facing`.", required=False))
EXAMPLE = {"type": "area", "name": "ceiling panel", "node": "room/ceiling_panel", "exitance_lm_m2": 2000.0}
EFFECTS = ()
FLAGS = AREA_EMITTER


@dataclass(frozen=True)
class Spec:
    """exitance_lm_m2 (lm/m²); instances: the ids as given (checked against the scene by `pack`); facing: a unit
    direction in each part's own frame, or None; faces: B-rep face indices, or None (neither: every triangle emits)."""

    exitance_lm_m2: float
    instances: tuple
    facing: tuple | None = None
    faces: tuple | None = None

    @classmethod
    def from_body(cls, body: dict, where: str) -> Spec:
        check_fields(body, where, NAME, FIELDS)
        m_exit = field_value(body, FIELDS["exitance_lm_m2"], where)
        ids = body.get("instances")
        if not isinstance(ids, list | tuple) or not ids:
            raise LightError(f"{where}: an area light needs 'instances', a non-empty list of instance ids")
        facing = body.get("facing")
        if facing is not None:
            unit = unit_axis(facing)
            if unit is None:
                raise LightError(f"{where}: 'facing' must be 3 finite numbers, not all zero (a direction in each "
                                 f"emitting part's own frame), got {facing!r}"[:300])
            facing = tuple(unit)
        faces = body.get("faces")
        if faces is not None:
            if facing is not None:
                raise LightError(f"{where}: give 'facing' or 'faces', not both (a direction, or B-rep face indices)")
            if not isinstance(faces, list | tuple) or not faces or not all(
                    isinstance(f, int | np.integer) and not isinstance(f, bool) and 0 <= f <= MAX_FACE_INDEX
                    for f in faces):
                raise LightError(f"{where}: 'faces' must be a non-empty list of B-rep face indices (ints 0 to "
                                 f"{MAX_FACE_INDEX}), got {faces!r}"[:300])
            faces = tuple(sorted({int(f) for f in faces}))
        return cls(m_exit, tuple(ids), facing, faces)


def pack(spec: Spec, j: int, out: Packing, where: str) -> float:
    """Fill row j and append the light's triangles (world space, from `out.scene`); returns Φ (lm)."""
    scene = out.scene
    if scene is None:
        raise LightError(f"{where}: an area light needs the scene to read its triangles")
    known = set(scene.instances())
    world = []
    for i in spec.instances:
        if isinstance(i, bool) or not isinstance(i, int | np.integer) or int(i) not in known:
            raise LightError(f"{where}: instance {i!r} is not in the scene")
        if int(i) in out.sensor_ids:
            raise LightError(f"{where}: instance {i} is a sensor and cannot emit")
        world.append(_world_triangles(scene, int(i), spec, where))
    tri = np.concatenate(world)
    e1, e2 = tri[:, 3:6], tri[:, 6:9]
    cr = np.cross(e1, e2)
    area2 = np.linalg.norm(cr, axis=1)
    keep = area2 > 0
    tri, cr, area2 = tri[keep], cr[keep], area2[keep]
    sign = np.concatenate([np.full(len(w), 1.0) for w in world])[keep]
    if len(tri) == 0 and spec.facing is not None:
        raise LightError(f"{where}: no triangle of the instances faces {list(spec.facing)} (within {FACING_DEG:g}°, "
                         f"in each part's own frame): check 'facing'")
    if spec.faces is not None:
        _check_faces(scene, spec, where)
    if len(tri) == 0:
        raise LightError(f"{where}: the instances have no triangle of non-zero area")
    area = 0.5 * area2
    normals = cr / area2[:, None] * sign[:, None]
    a_total = float(area.sum())
    row = out.par[j]
    row[P_I0] = spec.exitance_lm_m2
    row[P_FLUX] = spec.exitance_lm_m2 * a_total
    out.a_off[j] = out.used("tri"), len(tri)
    out.a_area[j] = a_total
    cdf = np.cumsum(area)
    out.parts["tri"].append(tri)
    out.parts["tri_n"].append(normals)
    out.parts["tri_cdf"].append(cdf / cdf[-1])
    return row[P_FLUX]


def facing_triangles(v: np.ndarray, tri: np.ndarray, facing: tuple) -> np.ndarray:
    """(m,) bool: which triangles (indices into vertices `v`, object space) face `facing` (any length) within
    `FACING_DEG`."""
    n = np.cross(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]])
    f = np.asarray(facing, np.float64)
    return n @ (f / np.linalg.norm(f)) >= math.cos(math.radians(FACING_DEG)) * np.linalg.norm(n, axis=1)


def emitting_triangles(scene, inst: int, facing: tuple | None, faces: tuple | None = None,
                       where: str = "area light") -> np.ndarray | None:
    """(m,) bool over instance `inst`'s triangles (its part's own, in order): which emit (those facing `facing`, or
    those of the B-rep faces `faces`); None where all do. A LightError where `faces` is given and the part's mesh
    carries no face indices."""
    gid = scene.instance_geometry(inst)
    if faces is not None:
        ids = scene.face_ids(gid)
        if ids is None:
            raise LightError(f"{where}: instance {inst}'s mesh carries no B-rep face indices (push it from CAD with "
                             f"them, or select by 'facing')")
        return np.isin(ids, np.asarray(faces, np.int64))
    if facing is None:
        return None
    v, tri = scene.geometry_arrays(gid)[:2]
    return facing_triangles(np.asarray(v, np.float64), np.asarray(tri, np.int64), facing)


def _check_faces(scene, spec: Spec, where: str) -> None:
    """A LightError naming each of `spec.faces` that no emitting part's mesh has a triangle of."""
    present: set[int] = set()
    for i in spec.instances:
        present.update(np.unique(scene.face_ids(scene.instance_geometry(int(i)))).tolist())
    for k, face in enumerate(spec.faces or ()):
        if face not in present:
            listed = sorted(present)
            raise LightError(f"{where}: faces[{k}] = {face}: no triangle of the emitting parts lies on B-rep face "
                             f"{face} (their faces: {listed[:50]}{' ...' if len(listed) > 50 else ''})")


def _world_triangles(scene, inst: int, spec: Spec | None = None, where: str = "area light") -> np.ndarray:
    """(m, 9) world-space triangles (v0, e1, e2) of one instance, those `spec` chooses (`emitting_triangles`) where
    it is given; edges of a mirrored instance are swapped so that e1 × e2 keeps pointing to the instance's outward
    side."""
    gid = scene.instance_geometry(inst)
    arrays = scene.geometry_arrays(gid)
    v, tri = np.asarray(arrays[0], np.float64), np.asarray(arrays[1], np.int64)
    if spec is not None:
        chosen = emitting_triangles(scene, inst, spec.facing, spec.faces, where)
        if chosen is not None:
            tri = tri[chosen]
    m = np.asarray(scene.instance_transform(inst), np.float64)
    w = v @ m[:3, :3].T + m[:3, 3]
    p0, p1, p2 = w[tri[:, 0]], w[tri[:, 1]], w[tri[:, 2]]
    if np.linalg.det(m[:3, :3]) < 0:
        p1, p2 = p2, p1
    return np.concatenate([p0, p1 - p0, p2 - p0], axis=1)


@njit(cache=True, _nrt=False)
def sample_point(L, j, u0, u1, u2):
    """A point on area light j, uniform over its area: (x, y, z, nx, ny, nz) with the front normal."""
    first, count = L.a_off[j, 0], L.a_off[j, 1]
    k = first + find_in_cdf(L.tri_cdf, first, count, u0)
    su = math.sqrt(u1)
    b1 = 1.0 - su
    b2 = u2 * su
    t = L.tri[k]
    x = t[0] + b1 * t[3] + b2 * t[6]
    y = t[1] + b1 * t[4] + b2 * t[7]
    z = t[2] + b1 * t[5] + b2 * t[8]
    return x, y, z, L.tri_n[k, 0], L.tri_n[k, 1], L.tri_n[k, 2]


@njit(cache=True, _nrt=False)
def sample(L, j, u0, u1, u2, u3, u4):
    """A uniform point (u0, u1, u2), a cosine-distributed direction about its normal (u3, u4); f = 1, on a
    surface (see base)."""
    x, y, z, nx, ny, nz = sample_point(L, j, u0, u1, u2)
    dx, dy, dz = sample_cosine(nx, ny, nz, u3, u4)
    return x, y, z, dx, dy, dz, 1.0, True, nx, ny, nz


@njit(cache=True, _nrt=False)
def connect(L, j, x, y, z, nx, ny, nz, u1, u2, u3):
    """One uniform point y of the emitter (u1, u2, u3): E = M/π cosθy cosθx / d² × A at x (lx); the shadow
    ray stops `SHADOW_SHORTEN` short of y (see base)."""
    lx, ly, lz, lnx, lny, lnz = sample_point(L, j, u1, u2, u3)
    dx, dy, dz = lx - x, ly - y, lz - z
    t_max = 1.0 - SHADOW_SHORTEN
    d2 = dx * dx + dy * dy + dz * dz
    if not (d2 > 0.0):
        return 0.0, dx, dy, dz, t_max
    dist = math.sqrt(d2)
    cos_x = (dx * nx + dy * ny + dz * nz) / dist
    cos_l = -(dx * lnx + dy * lny + dz * lnz) / dist
    if cos_x <= 0.0 or cos_l <= 0.0:
        return 0.0, dx, dy, dz, t_max
    return L.par[j, P_I0] / math.pi * cos_l * cos_x / d2 * L.a_area[j], dx, dy, dz, t_max
