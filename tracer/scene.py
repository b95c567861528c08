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

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from tracer.accel.queries import Hits, SceneQueries  # noqa: F401 - Hits is tracer.scene.Hits too (docs/DESIGN.md)
from tracer.accel.store import CACHE_MIN_TRIANGLES, Geometry, GeometryStore
from tracer.accel.tlas import TopLevel, world_boxes
from tracer.accel.top_levels import TopLevels
from tracer.accel.traverse import SceneArrays
from tracer.elements.scene_elements import SceneElements
from tracer.elements.table import Reliefs
from tracer.errors import NotCommittedError, TracerError, UnknownIdError
from tracer.geometry_id import canonical_arrays, canonical_faces, hash_canonical, is_geometry_id
from tracer.jit import njit
from tracer.kinds import REGISTRY, SENSOR_KINDS, mesh

#: the kinds that have a placement of their own (sensor shapes), by name, for `Scene.add_shape`
SHAPES = {m.__name__.rsplit(".", 1)[-1]: m for m in REGISTRY.values() if hasattr(m, "placement")}


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


#: whether this process has compiled (or loaded) the scene builders (`_builders_ready`)
_BUILDERS_READY = False


def _builders_ready() -> None:
    """Before this process's first scene: compile (or load) the builders of the bottom and top levels by building
    two boxes, under their machine-wide compile lock (`tracer.compile_locks.compiling`), so that processes that meet
    their first scene at once (test workers, a service and its warm-up child, Dask workers) compile them once, about
    30 s of a core cold, and the others load them from numba's cache (0.3 s) instead of compiling them as well.
    Geometry ids are given, not hashed: nobody's count of hashes changes."""
    global _BUILDERS_READY
    if _BUILDERS_READY:
        return
    _BUILDERS_READY = True
    from tracer.compile_locks import compiling

    corners = np.array([[x, y, z] for z in (0.0, 1.0) for y in (0.0, 1.0) for x in (0.0, 1.0)])
    faces = np.array([[0, 3, 1], [0, 2, 3], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4],
                      [1, 3, 7], [1, 7, 5], [3, 2, 6], [3, 6, 7], [2, 0, 4], [2, 4, 6]])
    with compiling("scene"):
        boxes = Scene()
        for k, shift in enumerate((0.0, 2.0)):
            gid = boxes.add_geometry(corners + shift, faces, known_id=f"{k:064x}")
            boxes.add_instance(gid, np.eye(4))
        boxes.commit()


class Scene(SceneElements, SceneQueries):
    """A two-level ray tracing scene (docs/DESIGN.md, "The tracer's Python API").

    Parameters
    ----------
    cache_dir : path or None
        Directory of the on-disk BLAS library (:mod:`tracer.accel.cache`); None: no disk cache.
    cache_min_triangles : int
        Geometries with fewer triangles are not cached (default 1: every mesh is kept, a restart rebuilds none).
    tlas_refit : bool
        A commit that only moves a few instances refits a top level instead of rebuilding it
        (`tracer.accel.top_levels`: at most ``max(16, n/64)`` moved, none added or removed). False: always rebuild.
    """

    def __init__(self, cache_dir: Any = None, *, cache_min_triangles: int = CACHE_MIN_TRIANGLES,
                 tlas_refit: bool = True) -> None:
        _builders_ready()
        self.cache_dir = cache_dir
        self.cache_min_triangles = int(cache_min_triangles)
        self.tlas_refit = bool(tlas_refit)
        self._blas = GeometryStore(cache_dir, self.cache_min_triangles)   # the bottom levels
        cap = 16
        self._n_ids = 0
        self._kind = np.full(cap, -1, np.int32)
        self._igeom = np.full(cap, -1, np.int32)
        self._wfo = np.zeros((cap, 3, 4))
        self._ofw = np.zeros((cap, 3, 4))
        self._obox = np.zeros((cap, 6))
        self._wbox = np.zeros((cap, 6))
        self._dirty_ids: set[int] = set()
        self._top = TopLevels(self._wbox, self.tlas_refit)   # the solid and the sensor top level
        self._reliefs = Reliefs()   # the instances that carry an element with an inside
        self._face_ids: dict[str, np.ndarray] = {}   # geometry id -> each triangle's B-rep face index
        self._inst_changed = True
        self._arrays: SceneArrays | None = None
        self._changed = True

    # ---------------------------------------------------------------- geometries
    def add_geometry(self, vertices: Any, triangles: Any, normals: Any = None, *, known_id: str | None = None,
                     face_ids: Any = None) -> str:
        """Add a triangle mesh; its BLAS is built at the next commit unless its id is known. Returns its geometry id
        (:func:`tracer.geometry_id`: the same content gives the same id).

        vertices : (n, 3) float — object-space positions (stored as float32, as hashed); triangles : (m, 3) int —
        vertex indices; normals : (n, 3) float or None — vertex normals for shading (need not be unit).
        known_id : str, optional — the arrays' geometry id where the caller has already computed it (the service
        checked it when the mesh was uploaded): taken as given, not hashed again, so it must be the arrays' own id.
        face_ids : (m,) int or None — each triangle's B-rep face index (`tracer.geometry_id.canonical_faces`), hashed
        with the mesh and kept for what selects faces by index (an area light's `faces`).
        """
        try:
            v, f, n = canonical_arrays(vertices, triangles, normals)
            faces = canonical_faces(face_ids, len(f))
        except ValueError as exc:
            raise TracerError(f"add_geometry: {exc}") from None
        if known_id is not None and not is_geometry_id(known_id):
            raise TracerError(f"add_geometry: known_id must be a geometry id (64 lowercase hex), got {known_id!r}")
        gid = hash_canonical(v, f, n, faces) if known_id is None else known_id
        if gid in self._blas.geoms:
            return gid
        if faces is not None:
            self._face_ids[gid] = faces
        box = mesh.object_bounds_of(v) if len(f) else np.array([np.inf] * 3 + [-np.inf] * 3)
        self._blas.add(gid, v, f, n, box)
        self._changed = True
        return gid

    def geometry_arrays(self, gid: str) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """``(vertices float32 (n,3), triangles uint32 (m,3), normals float32 (n,3) or None)`` of ``gid``."""
        g = self._geometry(gid)
        return g.vertices, g.triangles, g.normals

    def face_ids(self, gid: str) -> np.ndarray | None:
        """Each triangle's B-rep face index, uint32 (m,), as `add_geometry` was given it; None where it was not."""
        self._geometry(gid)
        return self._face_ids.get(gid)

    def geometries(self) -> list[str]:
        """Ids of all geometries added (built or pending)."""
        return list(self._blas.ids)

    def _geometry(self, gid: str) -> Geometry:
        return self._blas.geometry(gid)

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
        self._top.touch(i, int(self._kind[i]), structural)
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
        self._reliefs.drop(i)

    def instances(self) -> list[int]:
        """Ids of the live instances (meshes and sensors), ascending."""
        return [int(i) for i in np.flatnonzero(self._kind[: self._n_ids] >= 0)]

    def instance_geometry(self, i: int) -> str:
        """Geometry id of instance ``i`` (``"sensor:disk"`` / ``"sensor:rect"`` for sensors)."""
        i = self._instance(i)
        return REGISTRY[int(self._kind[i])].GEOMETRY or self._reliefs.full_of(i, self._blas.ids[int(self._igeom[i])])

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

    # ---------------------------------------------------------------- shapes (sensors)
    def add_shape(self, kind: str, *placement: Any) -> int:
        """An instance of a kind with a placement of its own (`SHAPES`: a sensor shape), placed by the kind's
        ``placement(*placement)``, which checks its arguments; returns its instance id."""
        if kind not in SHAPES:
            raise TracerError(f"add_shape: unknown shape kind {kind!r}; known: {sorted(SHAPES)}")
        m = SHAPES[kind]
        wfo, ofw = _check_matrix(m.placement(*placement), kind.replace("_", " "))
        return self._new_instance(m.KIND, -1, wfo, ofw, m.OBJECT_BOUNDS)

    def add_disk_sensor(self, center: Any, normal: Any, radius: float) -> int:
        """A disk sensor (front side: ``normal``); crossings report ``(u, v)`` in the unit disk."""
        return self.add_shape("disk_sensor", center, normal, radius)

    def add_rect_sensor(self, origin: Any, u: Any, v: Any) -> int:
        """A parallelogram sensor ``origin + a u + b v``, ``a, b`` in [0, 1]; front side ``u x v``."""
        return self.add_shape("rect_sensor", origin, u, v)

    # ---------------------------------------------------------------- commit
    def commit(self) -> UpdateStats:
        """Build what is dirty (new BLAS, then the top levels) and publish it to queries."""
        t0 = time.perf_counter()
        built, loaded = self._blas.build_pending()
        t1 = time.perf_counter()
        if self._dirty_ids:
            ids = np.fromiter(self._dirty_ids, np.int64, len(self._dirty_ids))
            rows = self._blas.store["bvh"]
            blas = self._blas
            world_boxes(ids, self._wfo, self._obox, self._kind, mesh.KIND, self._igeom, blas.node0, blas.tri0,
                        blas.ntri, rows.ravel(), rows.view(np.int32).ravel(), rows.view(np.uint8).ravel(),
                        self._blas.store["tri_v"].ravel(), self._wbox)
            self._dirty_ids = set()
        n = self._n_ids
        kind = self._kind[:n]
        modes = self._top.update(kind, self._kind, self._igeom, self._wbox, self._blas)
        s = self._blas.store
        old = self._arrays
        if self._inst_changed or old is None:
            inst = (kind.copy(), self._igeom[:n].copy(), self._wfo[:n].copy(), self._ofw[:n].copy())
        else:
            inst = (old.inst_kind, old.inst_geom, old.world_from_object, old.object_from_world)
        self._arrays = SceneArrays(
            s["bvh"].ravel(), s["bvh"].view(np.int32).ravel(), s["tri_v"].ravel(),
            s["tri_prim"], s["prim_slot"], s["tri_n"],
            self._blas.node0, self._blas.tri0, self._blas.ntri, self._blas.hasn,
            *inst, *_flat(self._top.levels["top"]), self._top.top_rec, *_flat(self._top.levels["sen"]),
            *self._reliefs.pack(n, lambda gid: self._geometry(gid).index))
        self._inst_changed = False
        self._changed = False
        t2 = time.perf_counter()
        return UpdateStats(built, loaded, t1 - t0, t2 - t1, modes["top"])

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


def _flat(level: TopLevel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rows = level.binary if level.rows8 is None else level.rows8
    return rows.ravel(), rows.view(np.int32).ravel(), level.items
