"""The two-level scene: geometries (bottom levels) and their instances (top level), with commits.

Python owns the objects and the bookkeeping; everything per-triangle or per-ray runs in the jitted
kernels of :mod:`tracer.accel.blas`, :mod:`tracer.accel.tlas` and :mod:`tracer.accel.traverse`. Nothing a query sees
changes until :meth:`Scene.commit`, which builds only what is dirty (Embree's commit boundary):

* a new unique geometry: its BLAS (one compiled call for all new geometries of the commit), or
  loads it from ``cache_dir``; a geometry id seen before is never built again;
* any instance added, removed, moved: the top level is rebuilt over the instance world boxes
  (only the changed instances' boxes are recomputed).

Every public method validates its input before changing anything and raises
:class:`tracer.errors.TracerError` (a ``ValueError``) naming the problem; the scene is then
unchanged. Units: metres in the world (the tracer itself is unit-free).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from tracer.accel import cache as blas_cache
from tracer.accel.blas import build_meshes, collapse, gather_triangles, refit
from tracer.accel.lanes import batch
from tracer.accel.rows4 import aligned_rows, leaf_order_f32, pack_wide
from tracer.accel.tlas import TopLevel, build_top, instance_records, refit_top, world_boxes
from tracer.accel.traverse import SceneArrays
from tracer.errors import NotCommittedError, TracerError, UnknownIdError
from tracer.geometry_id import canonical_arrays, hash_canonical, is_geometry_id
from tracer.jit import njit
from tracer.kinds import SENSOR_KINDS, disk_sensor, mesh, rect_sensor

#: BLAS build parameters: largest leaf and the cost of a triangle test relative to a node visit
MESH_MAX_LEAF = 4
MESH_ISECT_COST = 1.0
#: below this many triangles a BLAS is rebuilt rather than cached (building it takes less than
#: opening a file)
CACHE_MIN_TRIANGLES = 512
#: a top level is rebuilt after this many refitting commits (see ``Scene(tlas_refit=...)``)
MAX_REFITS = 64

SENSOR_GEOMETRY = {disk_sensor.KIND: "sensor:disk", rect_sensor.KIND: "sensor:rect"}


@dataclass(frozen=True)
class UpdateStats:
    """What a :meth:`Scene.commit` did.

    Attributes
    ----------
    blas_built : int
        Bottom levels built in this commit.
    blas_loaded : int
        Bottom levels loaded from the cache directory.
    blas_seconds : float
        Wall time of bottom-level work (build, load, cache write, packing).
    tlas_seconds : float
        Wall time of instance boxes, top-level build and packing of the query arrays.
    tlas_mode : str
        What happened to the solid top level: ``"rebuild"``, ``"refit"`` or ``"none"``.
    """

    blas_built: int
    blas_loaded: int
    blas_seconds: float
    tlas_seconds: float
    tlas_mode: str = "none"


@dataclass(frozen=True)
class Hits:
    """Closest hits of a batch of k rays.

    Attributes
    ----------
    t : (k,) float64
        Ray parameter of the hit (``inf`` on a miss), in units of ``|d|``.
    instance : (k,) int64
        Instance id (-1 on a miss).
    primitive : (k,) int64
        Triangle index in the geometry's ``triangles`` (-1 on a miss).
    u, v : (k,) float64
        Barycentrics: ``p = (1-u-v) v0 + u v1 + v v2``.
    normal : (k, 3) float64
        Unit world-space geometric normal (zeros on a miss).
    """

    t: np.ndarray
    instance: np.ndarray
    primitive: np.ndarray
    u: np.ndarray
    v: np.ndarray
    normal: np.ndarray


@dataclass
class _Geometry:
    index: int
    vertices: np.ndarray  # float32 (n, 3)
    triangles: np.ndarray  # uint32 (m, 3)
    normals: np.ndarray | None
    box: np.ndarray  # (6,) float64 object box, empty when m == 0


def _empty_store() -> dict[str, np.ndarray]:
    return {
        "bvh": np.empty((0, 16), np.float32),
        "tri_v": np.empty((0, 9), np.float32), "tri_prim": np.empty(0, np.int32), "prim_slot": np.empty(0, np.int32),
        "tri_n": np.empty((0, 9), np.float32),
    }


@njit(cache=True, error_model="numpy")
def _affine_inverse(m, ofw):
    """Check and invert the 4x4 affine ``m`` into ``ofw`` (3, 4) (compiled: the same arithmetic in
    Python floats cost ~17 µs per instance, which dominated adding 20,000 instances).

    Returns ``(code, det)``: 0 ok, 1 non-finite entries, 2 last row not ``[0, 0, 0, 1]``, 3 singular
    (``|det| <= 1e-12 scale^3``), 4 too ill-conditioned (``inv @ lin`` off the identity by > 1e-9, or a
    non-finite inverse).
    """
    for i in range(4):
        for j in range(4):
            if not np.isfinite(m[i, j]):
                return 1, 0.0
    if m[3, 0] != 0.0 or m[3, 1] != 0.0 or m[3, 2] != 0.0 or m[3, 3] != 1.0:
        return 2, 0.0
    a, b, c, tx = m[0, 0], m[0, 1], m[0, 2], m[0, 3]
    d, e, f, ty = m[1, 0], m[1, 1], m[1, 2], m[1, 3]
    g, h, k, tz = m[2, 0], m[2, 1], m[2, 2], m[2, 3]
    c00 = e * k - f * h
    c01 = f * g - d * k
    c02 = d * h - e * g
    det = a * c00 + b * c01 + c * c02
    scale = max(abs(a), abs(b), abs(c), abs(d), abs(e), abs(f), abs(g), abs(h), abs(k))
    if scale == 0.0 or not abs(det) > 1e-12 * scale**3 or not np.isfinite(det):
        return 3, det
    r = 1.0 / det
    ofw[0, 0] = c00 * r
    ofw[0, 1] = (c * h - b * k) * r
    ofw[0, 2] = (b * f - c * e) * r
    ofw[1, 0] = c01 * r
    ofw[1, 1] = (a * k - c * g) * r
    ofw[1, 2] = (c * d - a * f) * r
    ofw[2, 0] = c02 * r
    ofw[2, 1] = (b * g - a * h) * r
    ofw[2, 2] = (a * e - b * d) * r
    for i in range(3):
        for j in range(3):
            x = ofw[i, 0] * m[0, j] + ofw[i, 1] * m[1, j] + ofw[i, 2] * m[2, j]
            if not abs(x - (1.0 if i == j else 0.0)) <= 1e-9:
                return 4, det
        ofw[i, 3] = -(ofw[i, 0] * tx + ofw[i, 1] * ty + ofw[i, 2] * tz)
        for j in range(4):
            if not np.isfinite(ofw[i, j]):
                return 4, det
    return 0, det


def _check_matrix(transform: Any, what: str) -> tuple[np.ndarray, np.ndarray]:
    """Validate a 4x4 affine object-to-world matrix; return (world_from_object, object_from_world) (3,4).

    The checks and the 3x3 inverse (cofactors) run in :func:`_affine_inverse`: numpy's linalg costs
    ~50 µs per small call, which would dominate adding 20,000 instances.
    """
    try:
        m = np.array(transform, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise TracerError(f"{what}: transform must be a 4x4 array of numbers ({exc})") from None
    if m.shape != (4, 4):
        raise TracerError(f"{what}: transform must have shape (4, 4), got {m.shape}")
    ofw = np.empty((3, 4))
    code, det = _affine_inverse(m, ofw)
    if code == 1:
        raise TracerError(f"{what}: transform has non-finite entries")
    if code == 2:
        raise TracerError(f"{what}: transform is not affine (last row must be [0, 0, 0, 1], got {m[3].tolist()})")
    if code == 3:
        raise TracerError(f"{what}: transform is singular (det {det:.3g} of its 3x3 part)")
    if code == 4:
        raise TracerError(f"{what}: transform is too ill-conditioned to invert")
    return m[:3].copy(), ofw


def _vec3(x: Any, what: str) -> np.ndarray:
    try:
        a = np.array(x, dtype=np.float64)
    except (TypeError, ValueError):
        raise TracerError(f"{what} must be 3 numbers") from None
    if a.shape != (3,):
        raise TracerError(f"{what} must have shape (3,), got {a.shape}")
    if not np.isfinite(a).all():
        raise TracerError(f"{what} must be finite, got {a.tolist()}")
    return a


def _orthonormal_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing unit ``n`` to a right-handed basis (Duff et al., JCGT 2017)."""
    sign = 1.0 if n[2] >= 0.0 else -1.0
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    t1 = np.array([1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]])
    t2 = np.array([b, sign + n[1] * n[1] * a, -n[1]])
    return t1, t2


class Scene:
    """A two-level ray tracing scene (DESIGN.md, "The tracer's Python API").

    Parameters
    ----------
    cache_dir : path or None
        Directory of the on-disk BLAS library (:mod:`tracer.accel.cache`); None: no disk cache.
    cache_min_triangles : int
        Geometries with fewer triangles are not cached (rebuilding them is cheaper than a file).
    tlas_refit : bool
        When a commit only moves a few instances (at most ``max(16, n/64)``, none added or removed),
        refit the top level instead of rebuilding it; a rebuild still happens after
        :data:`MAX_REFITS` refitting commits or once the moved instances since the last build
        exceed ``n/8``, so refits cannot degrade the tree for long. False: always rebuild.
    """

    def __init__(self, cache_dir: Any = None, *, cache_min_triangles: int = CACHE_MIN_TRIANGLES,
                 tlas_refit: bool = True) -> None:
        self.cache_dir = cache_dir
        self.cache_min_triangles = int(cache_min_triangles)
        self.tlas_refit = bool(tlas_refit)
        self._geoms: dict[str, _Geometry] = {}
        self._geom_ids: list[str] = []
        self._n_built = 0
        self._store = _empty_store()
        self._g_node0 = np.empty(0, np.int64)
        self._g_tri0 = np.empty(0, np.int64)
        self._g_ntri = np.empty(0, np.int64)
        self._g_hasn = np.empty(0, np.bool_)
        cap = 16
        self._n_ids = 0
        self._kind = np.full(cap, -1, np.int32)
        self._igeom = np.full(cap, -1, np.int32)
        self._wfo = np.zeros((cap, 3, 4))
        self._ofw = np.zeros((cap, 3, 4))
        self._obox = np.zeros((cap, 6))
        self._wbox = np.zeros((cap, 6))
        self._dirty_ids: set[int] = set()
        # per top level ("top": solids, "sen": sensors): moved ids, structure changed, refit history
        self._moved: dict[str, set[int]] = {"top": set(), "sen": set()}
        self._struct = {"top": True, "sen": True}
        self._refits = {"top": (0, 0), "sen": (0, 0)}  # (refit commits, instances moved) since build
        self._levels = {"top": build_top(np.empty(0, np.int64), self._wbox),
                        "sen": build_top(np.empty(0, np.int64), self._wbox, wide=False)}
        self._top_rec = np.zeros(0, np.int64)   # instance_records of the solid top level's items
        self._inst_changed = True
        self._arrays: SceneArrays | None = None
        self._changed = True

    # ---------------------------------------------------------------- geometries
    def add_geometry(self, vertices: Any, triangles: Any, normals: Any = None, *, known_id: str | None = None) -> str:
        """Add a triangle mesh; its BLAS is built at the next commit unless its id is known.

        Parameters
        ----------
        vertices : (n, 3) float
            Object-space positions (stored as float32, as hashed).
        triangles : (m, 3) int
            Vertex indices.
        normals : (n, 3) float or None
            Vertex normals for shading (need not be unit).
        known_id : str, optional
            The arrays' geometry id where the caller has already computed it (the service checked it when the
            mesh was uploaded): taken as given, not hashed again, so it must be the arrays' own id.

        Returns
        -------
        str
            The geometry id (:func:`tracer.geometry_id`): the same content gives the same id.
        """
        try:
            v, f, n = canonical_arrays(vertices, triangles, normals)
        except ValueError as exc:
            raise TracerError(f"add_geometry: {exc}") from None
        if known_id is not None and not is_geometry_id(known_id):
            raise TracerError(f"add_geometry: known_id must be a geometry id (64 lowercase hex), got {known_id!r}")
        gid = hash_canonical(v, f, n) if known_id is None else known_id
        if gid in self._geoms:
            return gid
        box = mesh.object_bounds_of(v) if len(f) else np.array([np.inf] * 3 + [-np.inf] * 3)
        self._geoms[gid] = _Geometry(len(self._geom_ids), v, f, n, box)
        self._geom_ids.append(gid)
        self._changed = True
        return gid

    def geometry_arrays(self, gid: str) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """``(vertices float32 (n,3), triangles uint32 (m,3), normals float32 (n,3) or None)`` of ``gid``."""
        g = self._geometry(gid)
        return g.vertices, g.triangles, g.normals

    def geometries(self) -> list[str]:
        """Ids of all geometries added (built or pending)."""
        return list(self._geom_ids)

    def _geometry(self, gid: str) -> _Geometry:
        if not isinstance(gid, str) or gid not in self._geoms:
            raise UnknownIdError(f"unknown geometry id {gid!r}")
        return self._geoms[gid]

    # ---------------------------------------------------------------- instances
    def _grow(self) -> None:
        cap = len(self._kind)
        if self._n_ids < cap:
            return
        new = 2 * cap
        self._kind = np.concatenate([self._kind, np.full(new - cap, -1, np.int32)])
        self._igeom = np.concatenate([self._igeom, np.full(new - cap, -1, np.int32)])
        for name in ("_wfo", "_ofw"):
            setattr(self, name, np.concatenate([getattr(self, name), np.zeros((new - cap, 3, 4))]))
        for name in ("_obox", "_wbox"):
            setattr(self, name, np.concatenate([getattr(self, name), np.zeros((new - cap, 6))]))

    def _new_instance(self, kind: int, geom: int, wfo: np.ndarray, ofw: np.ndarray, obox: np.ndarray) -> int:
        self._grow()
        i = self._n_ids
        self._n_ids += 1
        self._kind[i] = kind
        self._igeom[i] = geom
        self._wfo[i] = wfo
        self._ofw[i] = ofw
        self._obox[i] = obox
        self._touch(i, structural=True)
        return i

    def _touch(self, i: int, structural: bool) -> None:
        self._dirty_ids.add(i)
        level = "sen" if self._kind[i] in SENSOR_KINDS else "top"
        if structural:
            self._struct[level] = True
        else:
            self._moved[level].add(i)
        self._inst_changed = True
        self._changed = True

    def add_instance(self, gid: str, transform: Any) -> int:
        """Place geometry ``gid`` with the 4x4 affine ``transform`` (world_from_object); returns the id.

        Ids are ints, never reused within one scene.
        """
        g = self._geometry(gid)
        wfo, ofw = _check_matrix(transform, f"instance of {gid[:12]}")
        return self._new_instance(mesh.KIND, g.index, wfo, ofw, g.box)

    def _instance(self, i: Any) -> int:
        if isinstance(i, bool) or not isinstance(i, (int, np.integer)) or not 0 <= int(i) < self._n_ids \
                or self._kind[int(i)] < 0:
            raise UnknownIdError(f"unknown instance id {i!r}")
        return int(i)

    def set_transform(self, i: int, transform: Any) -> None:
        """Move/rotate/scale instance ``i`` (4x4 affine world_from_object). Sensors too."""
        i = self._instance(i)
        wfo, ofw = _check_matrix(transform, f"instance {i}")
        self._wfo[i] = wfo
        self._ofw[i] = ofw
        self._touch(i, structural=False)

    def remove_instance(self, i: int) -> None:
        """Remove instance ``i`` (its geometry stays in the scene's library)."""
        i = self._instance(i)
        self._touch(i, structural=True)
        self._kind[i] = -1

    def instances(self) -> list[int]:
        """Ids of the live instances (meshes and sensors), ascending."""
        return [int(i) for i in np.flatnonzero(self._kind[: self._n_ids] >= 0)]

    def instance_geometry(self, i: int) -> str:
        """Geometry id of instance ``i`` (``"sensor:disk"`` / ``"sensor:rect"`` for sensors)."""
        i = self._instance(i)
        k = int(self._kind[i])
        if k in SENSOR_GEOMETRY:
            return SENSOR_GEOMETRY[k]
        return self._geom_ids[int(self._igeom[i])]

    def instance_transform(self, i: int) -> np.ndarray:
        """4x4 world_from_object of instance ``i`` (a copy)."""
        i = self._instance(i)
        m = np.eye(4)
        m[:3] = self._wfo[i]
        return m

    def instance_bounds(self, i: int) -> np.ndarray:
        """(2, 3) world-space box ``[lo, hi]`` the top level holds for instance ``i`` as last committed.

        It encloses every surface of the instance: for a mesh, the box of its transformed vertices (or,
        above :data:`tracer.accel.tlas.EXACT_MAX_TRIANGLES`, of its BVH's transformed second-level boxes), so
        a rotated part's box is not the loose box of its rotated object box. ``lo > hi`` for an empty mesh.
        """
        i = self._instance(i)
        if i in self._dirty_ids or self._arrays is None:
            raise NotCommittedError(f"instance {i} changed since the last commit: call commit() first")
        return self._wbox[i].reshape(2, 3).copy()

    def is_sensor(self, i: int) -> bool:
        """True when instance ``i`` is a sensor."""
        return int(self._kind[self._instance(i)]) in SENSOR_KINDS

    # ---------------------------------------------------------------- sensors
    def add_disk_sensor(self, center: Any, normal: Any, radius: float) -> int:
        """A disk sensor (front side: ``normal``); returns its instance id.

        Crossings report ``(u, v)`` in the unit disk along an orthonormal basis of the disk plane.
        """
        c = _vec3(center, "disk sensor center")
        n = _vec3(normal, "disk sensor normal")
        ln = float(np.linalg.norm(n))
        if not ln > 0.0:
            raise TracerError("disk sensor normal must be non-zero")
        try:
            r = float(radius)
        except (TypeError, ValueError):
            raise TracerError(f"disk sensor radius must be a number, got {radius!r}") from None
        if not (np.isfinite(r) and r > 0.0):
            raise TracerError(f"disk sensor radius must be positive and finite, got {radius!r}")
        n = n / ln
        t1, t2 = _orthonormal_basis(n)
        m = np.eye(4)
        m[:3, 0] = r * t1
        m[:3, 1] = r * t2
        m[:3, 2] = n
        m[:3, 3] = c
        wfo, ofw = _check_matrix(m, "disk sensor")
        return self._new_instance(disk_sensor.KIND, -1, wfo, ofw, disk_sensor.OBJECT_BOUNDS)

    def add_rect_sensor(self, origin: Any, u: Any, v: Any) -> int:
        """A parallelogram sensor ``origin + a u + b v``, ``a, b`` in [0, 1]; front side ``u x v``."""
        o = _vec3(origin, "rect sensor origin")
        uu = _vec3(u, "rect sensor u")
        vv = _vec3(v, "rect sensor v")
        n = np.cross(uu, vv)
        ln = float(np.linalg.norm(n))
        if not ln > 1e-12 * float(np.linalg.norm(uu) * np.linalg.norm(vv)) or ln == 0.0:
            raise TracerError("rect sensor u and v must be non-zero and not parallel")
        m = np.eye(4)
        m[:3, 0] = uu
        m[:3, 1] = vv
        m[:3, 2] = n / ln
        m[:3, 3] = o
        wfo, ofw = _check_matrix(m, "rect sensor")
        return self._new_instance(rect_sensor.KIND, -1, wfo, ofw, rect_sensor.OBJECT_BOUNDS)

    # ---------------------------------------------------------------- commit
    def commit(self) -> UpdateStats:
        """Build what is dirty (new BLAS, then the top levels) and publish it to queries."""
        t0 = time.perf_counter()
        built, loaded = self._build_pending()
        t1 = time.perf_counter()
        if self._dirty_ids:
            ids = np.fromiter(self._dirty_ids, np.int64, len(self._dirty_ids))
            rows = self._store["bvh"]
            world_boxes(ids, self._wfo, self._obox, self._kind, mesh.KIND, self._igeom, self._g_node0, self._g_tri0,
                        self._g_ntri, rows.ravel(), rows.view(np.int32).ravel(), rows.view(np.uint8).ravel(),
                        self._store["tri_v"].ravel(), self._wbox)
            self._dirty_ids = set()
        n = self._n_ids
        kind = self._kind[:n]
        modes = {"top": "none", "sen": "none"}
        for level in ("top", "sen"):
            moved = self._moved[level]
            if not (self._struct[level] or moved):
                continue
            n_level = len(self._levels[level].items)
            commits, count = self._refits[level]
            if (not self._struct[level] and self.tlas_refit and len(moved) <= max(16, n_level // 64)
                    and commits < MAX_REFITS and count + len(moved) <= max(16, n_level // 8)):
                self._levels[level] = refit_top(self._levels[level], np.fromiter(moved, np.int64, len(moved)),
                                                self._wbox)
                self._refits[level] = (commits + 1, count + len(moved))
                modes[level] = "refit"
            else:
                if level == "top":
                    keep = (kind >= 0) & ~np.isin(kind, list(SENSOR_KINDS)) & (self._wbox[:n, 0] <= self._wbox[:n, 3])
                else:
                    keep = np.isin(kind, list(SENSOR_KINDS))
                self._levels[level] = build_top(np.flatnonzero(keep), self._wbox, wide=level == "top")
                if level == "top":
                    self._top_rec = instance_records(self._levels[level].items, self._kind, self._igeom,
                                                     self._g_node0, self._g_tri0, self._g_ntri, mesh.KIND)
                self._refits[level] = (0, 0)
                modes[level] = "rebuild"
            self._struct[level] = False
            self._moved[level] = set()
        s = self._store
        old = self._arrays
        if self._inst_changed or old is None:
            inst = (kind.copy(), self._igeom[:n].copy(), self._wfo[:n].copy(), self._ofw[:n].copy())
        else:
            inst = (old.inst_kind, old.inst_geom, old.world_from_object, old.object_from_world)
        self._arrays = SceneArrays(
            s["bvh"].ravel(), s["bvh"].view(np.int32).ravel(), s["tri_v"].ravel(),
            s["tri_prim"], s["prim_slot"], s["tri_n"],
            self._g_node0, self._g_tri0, self._g_ntri, self._g_hasn,
            *inst, *_flat(self._levels["top"]), self._top_rec, *_flat(self._levels["sen"]))
        self._inst_changed = False
        self._changed = False
        t2 = time.perf_counter()
        return UpdateStats(built, loaded, t1 - t0, t2 - t1, modes["top"])

    def _build_pending(self) -> tuple[int, int]:
        pending = [self._geoms[g] for g in self._geom_ids[self._n_built:]]
        if not pending:
            return 0, 0
        loaded: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        if self.cache_dir is not None:
            for g in pending:
                if len(g.triangles) >= self.cache_min_triangles:
                    r = blas_cache.load(self.cache_dir, self._geom_ids[g.index], len(g.triangles))
                    if r is not None:
                        loaded[g.index] = r
        to_build = [g for g in pending if g.index not in loaded]
        parts: list[tuple[list[_Geometry], dict[str, np.ndarray], np.ndarray, np.ndarray]] = []
        if to_build:
            parts.append(self._build_batch(to_build))
        for g in pending:
            if g.index in loaded:
                parts.append(self._loaded_part(g, *loaded[g.index]))
        # append to the store; geometry offsets are explicit, so order in the store is free
        G = len(self._geom_ids)
        node0 = np.concatenate([self._g_node0, np.zeros(G - len(self._g_node0), np.int64)])
        tri0 = np.concatenate([self._g_tri0, np.zeros(G - len(self._g_tri0), np.int64)])
        ntri = np.concatenate([self._g_ntri, np.zeros(G - len(self._g_ntri), np.int64)])
        hasn = np.concatenate([self._g_hasn, np.zeros(G - len(self._g_hasn), np.bool_)])
        new = {k: [v] for k, v in self._store.items()}
        n_nodes = len(self._store["bvh"])
        n_tris = len(self._store["tri_prim"])
        for geoms, arrs, g_nodes, g_tris in parts:
            idx = np.array([g.index for g in geoms], np.int64)
            node0[idx] = n_nodes + np.concatenate([[0], np.cumsum(g_nodes)[:-1]])
            tri0[idx] = n_tris + np.concatenate([[0], np.cumsum(g_tris)[:-1]])
            ntri[idx] = g_tris
            hasn[idx] = [g.normals is not None for g in geoms]
            n_nodes += int(g_nodes.sum())
            n_tris += int(g_tris.sum())
            for k, v in arrs.items():
                new[k].append(v)
        # the BLAS rows are joined straight into a 64-byte aligned buffer (one cache line per row)
        outs = {"bvh": aligned_rows(sum(len(r) for r in new["bvh"]))}
        self._store = {k: np.concatenate(v, out=outs.get(k)) if len(v) > 1 else v[0] for k, v in new.items()}
        self._g_node0, self._g_tri0, self._g_ntri, self._g_hasn = node0, tri0, ntri, hasn
        self._n_built = G
        return len(to_build), len(loaded)

    def _build_batch(self, geoms: list[_Geometry]):
        """One compiled call for all geometries to build; write cache files for the large ones."""
        g_tris = np.array([len(g.triangles) for g in geoms], np.int64)
        g_verts = np.array([len(g.vertices) for g in geoms], np.int64)
        tri_off = np.concatenate([[0], np.cumsum(g_tris)])
        vert_off = np.concatenate([[0], np.cumsum(g_verts)])
        verts = np.concatenate([g.vertices for g in geoms]).astype(np.float64) if len(geoms) else np.empty((0, 3))
        tris = np.concatenate([g.triangles for g in geoms]).astype(np.int64)
        m = int(tri_off[-1])
        tri_v = np.empty((m, 9))
        gather_triangles(verts, tris, tri_off, vert_off, tri_v)
        order, node_box, node_a, node_n, node_cnt = build_meshes(tri_v, tri_off, MESH_MAX_LEAF, MESH_ISECT_COST)
        # geometry g's nodes are rows 2*tri_off[g] .. + node_cnt[g] of the build arrays
        node_off = 2 * tri_off[:-1]
        rows, row_cnt = pack_wide(*collapse(node_box, node_a, node_n, node_off, node_cnt))
        base = np.repeat(tri_off[:-1], g_tris)
        leaf_rows = base + order  # batch row of the original triangle at each leaf position
        prim_slot = np.empty(m, np.int32)
        prim_slot[leaf_rows] = (np.arange(m) - base).astype(np.int32)
        tri_n = np.zeros((m, 9), np.float32)
        if any(g.normals is not None for g in geoms):
            nrm = np.concatenate([g.normals if g.normals is not None else np.zeros_like(g.vertices) for g in geoms])
            tri_n[:] = nrm[tris + np.repeat(vert_off[:-1], g_tris)[:, None]].reshape(m, 9)
            tri_n = tri_n[leaf_rows]
        arrs = {"bvh": rows, "tri_v": leaf_order_f32(tri_v, leaf_rows).reshape(m, 9),
                "tri_prim": order.astype(np.int32), "prim_slot": prim_slot, "tri_n": tri_n}
        if self.cache_dir is not None:
            for q, g in enumerate(geoms):
                if g_tris[q] >= self.cache_min_triangles:
                    sl = slice(int(node_off[q]), int(node_off[q] + node_cnt[q]))
                    blas_cache.save(self.cache_dir, self._geom_ids[g.index], order[tri_off[q]:tri_off[q + 1]],
                                    node_a[sl], node_n[sl])
        return geoms, arrs, row_cnt, g_tris

    def _loaded_part(self, g: _Geometry, order: np.ndarray, node_a: np.ndarray, node_n: np.ndarray):
        """Store arrays of a BLAS whose topology came from the cache; boxes are refitted, never read."""
        m = len(g.triangles)
        v = g.vertices.astype(np.float64)
        tri_v = v[g.triangles.astype(np.int64)].reshape(m, 9)[order]
        node_box = np.empty((len(node_a), 6))
        refit(node_a, node_n, tri_v, node_box)
        prim_slot = np.empty(m, np.int32)
        prim_slot[order] = np.arange(m, dtype=np.int32)
        if g.normals is not None:
            tri_n = g.normals[g.triangles.astype(np.int64)].reshape(m, 9)[order].astype(np.float32)
        else:
            tri_n = np.zeros((m, 9), np.float32)
        rows, row_cnt = pack_wide(*collapse(node_box, node_a, node_n, np.zeros(1, np.int64),
                                            np.array([len(node_a)], np.int64)))
        arrs = {"bvh": rows, "tri_v": tri_v.astype(np.float32),
                "tri_prim": order.astype(np.int32), "prim_slot": prim_slot, "tri_n": tri_n}
        return [g], arrs, row_cnt, np.array([m], np.int64)

    # ---------------------------------------------------------------- queries
    def arrays(self) -> SceneArrays:
        """The committed scene as a :class:`tracer.accel.traverse.SceneArrays` for jitted code."""
        if self._arrays is None:
            raise NotCommittedError("the scene was never committed: call commit() before querying")
        if self._changed:
            raise NotCommittedError("the scene has changes that are not committed: call commit() before querying")
        return self._arrays

    @property
    def dirty(self) -> bool:
        """True when there are changes that :meth:`commit` has not yet published."""
        return self._changed

    def intersect(self, origins: Any, directions: Any, t_max: Any = np.inf, *, threads: int | None = None) -> Hits:
        """Closest hits of rays ``origins[i] + t directions[i]``, ``0 < t < t_max`` (sensors ignored).

        Parameters
        ----------
        origins, directions : (k, 3) float
            World space; directions need not be unit (``t`` is in units of ``|d|``).
        t_max : float or (k,) float
        threads : int or None
            Number of threads (None: numba's current setting); 1 for per-core measurements.
        """
        return self._trace(origins, directions, t_max, threads, any_hit=False)

    def occluded(self, origins: Any, directions: Any, t_max: Any = np.inf, *, threads: int | None = None) -> np.ndarray:
        """(k,) bool: does any solid lie on ``origins[i] + t directions[i]``, ``0 < t < t_max``?"""
        return self._trace(origins, directions, t_max, threads, any_hit=True).instance >= 0

    def _trace(self, origins: Any, directions: Any, t_max: Any, threads: int | None, any_hit: bool) -> Hits:
        sa = self.arrays()
        o, d, tm = _check_rays(origins, directions, t_max)
        k = len(o)
        h = Hits(np.empty(k), np.empty(k, np.int64), np.empty(k, np.int64), np.empty(k), np.empty(k), np.empty((k, 3)))
        _run_threads(threads, lambda: batch(sa, o, d, tm, any_hit, h.t, h.instance, h.primitive, h.u, h.v, h.normal))
        return h


def _flat(level: TopLevel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rows = level.binary if level.rows8 is None else level.rows8
    return rows.ravel(), rows.view(np.int32).ravel(), level.items


def _run_threads(threads: int | None, fn: Callable[[], None]) -> None:
    if threads is None:
        fn()
        return
    if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) \
            or not 1 <= threads <= numba.config.NUMBA_NUM_THREADS:
        raise TracerError(f"threads must be an int in [1, {numba.config.NUMBA_NUM_THREADS}], got {threads!r}")
    old = numba.get_num_threads()
    numba.set_num_threads(int(threads))
    try:
        fn()
    finally:
        numba.set_num_threads(old)


def _check_rays(origins: Any, directions: Any, t_max: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validate a ray batch; return contiguous float64 (k,3), (k,3), (k,)."""
    arrs = []
    for name, a in (("origins", origins), ("directions", directions)):
        x = np.asarray(a)
        if x.ndim != 2 or x.shape[1] != 3:
            raise TracerError(f"{name} must have shape (k, 3), got {x.shape}")
        if not (np.issubdtype(x.dtype, np.floating) or np.issubdtype(x.dtype, np.integer)):
            raise TracerError(f"{name} must be real numbers, got dtype {x.dtype}")
        arrs.append(np.ascontiguousarray(x, dtype=np.float64))
    o, d = arrs
    if len(o) != len(d):
        raise TracerError(f"origins and directions differ in length: {len(o)} vs {len(d)}")
    try:
        tm = np.asarray(t_max, dtype=np.float64)
    except (TypeError, ValueError):
        raise TracerError(f"t_max must be a number or (k,) numbers, got {t_max!r}") from None
    if tm.ndim == 0:
        tm = np.full(len(o), float(tm))
    elif tm.shape != (len(o),):
        raise TracerError(f"t_max must be a scalar or have shape ({len(o)},), got {tm.shape}")
    tm = np.ascontiguousarray(tm)
    i, what = _first_bad_ray(o, d, tm)
    if what == 1:
        raise TracerError(f"ray {i}: origin is not finite: {o[i].tolist()}")
    if what == 2:
        raise TracerError(f"ray {i}: direction is not finite: {d[i].tolist()}")
    if what == 3:
        raise TracerError(f"ray {i}: direction is zero")
    if what == 4:
        raise TracerError(f"ray {i}: t_max must be >= 0 (inf allowed), got {tm[i]}")
    return o, d, tm


@njit(cache=True, error_model="numpy")
def _first_bad_ray(o, d, tm):
    """``(i, what)`` of the first bad ray (what: 1 origin not finite, 2 direction not finite, 3 zero
    direction, 4 t_max NaN or negative), ``(-1, 0)`` when all are good: one pass, where the numpy
    masks took four and cost as much as tracing a simple scene."""
    for i in range(o.shape[0]):
        if not (math.isfinite(o[i, 0]) and math.isfinite(o[i, 1]) and math.isfinite(o[i, 2])):
            return i, 1
        if not (math.isfinite(d[i, 0]) and math.isfinite(d[i, 1]) and math.isfinite(d[i, 2])):
            return i, 2
        if d[i, 0] == 0.0 and d[i, 1] == 0.0 and d[i, 2] == 0.0:
            return i, 3
        if not (tm[i] >= 0.0):
            return i, 4
    return -1, 0
