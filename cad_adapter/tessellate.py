"""Tessellation of distinct parts into numpy meshes, deterministic and cached.

Settings
--------
==========  =======  ==========================================================================
name        default  meaning
==========  =======  ==========================================================================
linear      0.1 mm   chordal deflection, absolute in document units (0.1 mm converted to them);
                     with ``relative`` a fraction of each part's bounding-box diagonal (default 0.002)
angular     0.5 rad  angular deflection between adjacent facets
relative    False    linear deflection relative to each part's own size, not the document's
==========  =======  ==========================================================================

Determinism: each part is meshed as a deep copy without triangulation (``BRepBuilderAPI_Copy``), so the
result depends only on the B-rep and the settings, never on what was meshed before, and the document's
shapes are never modified (meshing adjusts edge tolerances); the same part and
settings give byte-identical arrays, hence the same geometry id. OCCT's parallel mode meshes the faces
of a part concurrently; each face's mesh does not depend on the order faces finish in.

Arrays: vertices float32 (n, 3) in the part's own frame (face locations applied), triangles uint32
(m, 3) counter-clockwise seen from outside (a reversed face's triangles are flipped), normals float32
(n, 3) from the B-rep surface (``BRepLib_ToolTriangulatedShape.ComputeNormals``), outward. Faces are
not welded together: each face keeps its own vertices, so normals stay sharp at edges; positions along a
shared edge are identical on both sides, so a closed B-rep gives a watertight mesh once positions are
merged. ``face_ids`` uint32 (m,) names each triangle's B-rep face: the face's index in the part's B-rep
(``TopExp_Explorer`` over its faces, from 0, the order the B-rep stores them in; `face_table` lists them), which
depends on the B-rep only, never on the settings, so an element assigned to "face 5" stays on the same face when
the part is meshed again at another tolerance. The face indices are part of the geometry id (docs/DESIGN.md).
"""

from __future__ import annotations

import hashlib
import io
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tracer.geometry_id import canonical_arrays, geometry_id

from .errors import TessellationError
from .tree import UNIT_METRES, Document

DEFAULT_LINEAR_MM = 0.1
DEFAULT_RELATIVE = 0.002
DEFAULT_ANGULAR = 0.5


@dataclass(frozen=True)
class Settings:
    """Tessellation settings.

    Attributes
    ----------
    linear : float
        Absolute chordal deflection in document units, or (``relative``) a fraction of each part's
        bounding-box diagonal.
    angular : float
        Angular deflection, radians, in (0, pi/2].
    relative : bool
        Whether ``linear`` is relative to each part's size.
    """

    linear: float
    angular: float = DEFAULT_ANGULAR
    relative: bool = False

    def __post_init__(self) -> None:
        for name in ("linear", "angular"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or v <= 0:
                raise TessellationError(f"{name} deflection must be a finite number > 0, got {v!r}")
        if self.angular > math.pi / 2:
            raise TessellationError(f"angular deflection must be at most pi/2 rad, got {self.angular}")
        if self.relative and self.linear >= 1:
            raise TessellationError(f"a relative linear deflection is a fraction of the part size (< 1), "
                                    f"got {self.linear}")

    @classmethod
    def default(cls, length_unit: str, linear: float | None = None, angular: float | None = None,
                relative: bool = False) -> Settings:
        """Settings with the defaults filled in for a document in ``length_unit``."""
        if linear is None:
            linear = DEFAULT_RELATIVE if relative else DEFAULT_LINEAR_MM * 1e-3 / UNIT_METRES[length_unit]
        return cls(linear=float(linear), angular=float(DEFAULT_ANGULAR if angular is None else angular),
                   relative=bool(relative))

    def as_dict(self) -> dict[str, float | bool]:
        return {"linear": self.linear, "angular": self.angular, "relative": self.relative}


@dataclass
class Mesh:
    """A part's tessellation, in the part's frame.

    Attributes
    ----------
    vertices : (n, 3) float32
    triangles : (m, 3) uint32
    normals : (n, 3) float32 or None
    geometry_id : str
        docs/DESIGN.md's content hash of the arrays (the face indices included where there are some).
    deflection : float
        The absolute linear deflection used, document units.
    face_ids : (m,) uint32 or None
        Each triangle's B-rep face index (see the module docstring).
    """

    vertices: np.ndarray
    triangles: np.ndarray
    normals: np.ndarray | None
    geometry_id: str
    deflection: float = 0.0
    face_ids: np.ndarray | None = None

    @property
    def n_triangles(self) -> int:
        return int(len(self.triangles))


@dataclass
class Tessellation:
    """Result of tessellating a document's parts.

    Attributes
    ----------
    meshes : dict of str to Mesh
        By part key; parts without faces or that failed are absent.
    empty : list of str
        Part keys whose shape has no face (nothing to mesh; not an error).
    failed : dict of str to str
        Part key -> why it failed.
    warnings : list of str
    meshed, cached, reused : int
        Parts meshed now, parts taken from the cache, parts whose scene mesh is kept (``Document.reuse``).
    seconds : float
    settings : Settings
        What the parts were meshed with.
    """

    meshes: dict[str, Mesh] = field(default_factory=dict)
    empty: list[str] = field(default_factory=list)
    failed: dict[str, str] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    meshed: int = 0
    cached: int = 0
    reused: int = 0
    seconds: float = 0.0
    settings: Settings | None = None

    @property
    def triangles(self) -> int:
        return sum(m.n_triangles for m in self.meshes.values())


def shape_digest(shape) -> str:
    """SHA-256 of a shape's B-rep (binary format, without triangulations): the cache key's content part.

    Two readings of the same file, or two builds of the same cadquery model, give the same digest, so
    the cache works across re-imports and ``watch`` cycles; any edit of the geometry changes it.
    """
    from OCP.BinTools import BinTools, BinTools_FormatVersion

    buf = io.BytesIO()
    BinTools.Write_s(shape, buf, False, False, BinTools_FormatVersion.BinTools_FormatVersion_CURRENT)
    return hashlib.sha256(buf.getvalue()).hexdigest()


def bbox_diagonal(shape) -> float:
    """Diagonal of the shape's tight bounding box (document units); 0 for an empty shape."""
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    box = Bnd_Box()
    BRepBndLib.AddOptimal_s(shape, box, False, False)
    if box.IsVoid():
        return 0.0
    x0, y0, z0, x1, y1, z1 = box.Get()
    return float(math.sqrt((x1 - x0) ** 2 + (y1 - y0) ** 2 + (z1 - z0) ** 2))


def has_faces(shape) -> bool:
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer

    return TopExp_Explorer(shape, TopAbs_FACE).More()


def _face_order(verts: list[np.ndarray], tris: list[np.ndarray]) -> list[int]:
    """Faces sorted by where they are: area-weighted centroid on a grid of 1e-6 of the part's size, then
    area and counts (concentric faces share a centroid). Independent of the order the file lists them in."""
    lo = np.min([p.min(axis=0) for p in verts], axis=0)
    hi = np.max([p.max(axis=0) for p in verts], axis=0)
    q = max(float(np.linalg.norm(hi - lo)), 1e-300) * 1e-6
    keys = []
    for p, t in zip(verts, tris, strict=True):
        a, b, c = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
        area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
        total = float(area.sum())
        centre = ((a + b + c) / 3.0 * area[:, None]).sum(axis=0) / total if total > 0 else p.mean(axis=0)
        keys.append((*np.round((centre - lo) / q).astype(np.int64).tolist(), round(total / (q * q)), len(p), len(t)))
    return sorted(range(len(verts)), key=lambda k: keys[k])


def face_table(shape) -> list[dict]:
    """The part's B-rep faces as the adapter names them: ``{"face": index, "surface": kind, "area", "centroid",
    "normal"}`` (document units; ``normal`` the outward normal at the centroid's parameters for a plane, else None),
    in B-rep order: what an element assignment's ``faces`` refers to."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.BRepGProp import BRepGProp
    from OCP.GeomAbs import GeomAbs_Plane
    from OCP.GProp import GProp_GProps
    from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    kinds = {0: "plane", 1: "cylinder", 2: "cone", 3: "sphere", 4: "torus"}
    out = []
    exp = TopExp_Explorer(shape, TopAbs_FACE)
    k = 0
    while exp.More():
        face = TopoDS.Face_s(exp.Current())
        exp.Next()
        props = GProp_GProps()
        BRepGProp.SurfaceProperties_s(face, props)
        c = props.CentreOfMass()
        surf = BRepAdaptor_Surface(face)
        normal = None
        if surf.GetType() == GeomAbs_Plane:
            d = surf.Plane().Axis().Direction()
            sign = -1.0 if face.Orientation() == TopAbs_REVERSED else 1.0
            normal = [sign * d.X(), sign * d.Y(), sign * d.Z()]
        out.append({"face": k, "surface": kinds.get(int(surf.GetType()), "other"), "area": float(props.Mass()),
                    "centroid": [c.X(), c.Y(), c.Z()], "normal": normal})
        k += 1
    return out


def _read_faces(shape) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, np.ndarray]:
    """Collect every face's triangulation: vertices float64 (n,3), triangles int64 (m,3), normals float64, the
    faces without triangles, and each triangle's B-rep face index (uint32 (m,))."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepLib import BRepLib_ToolTriangulatedShape
    from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS

    verts: list[np.ndarray] = []
    tris: list[np.ndarray] = []
    norms: list[np.ndarray] = []
    index: list[int] = []
    missing = 0
    exp = TopExp_Explorer(shape, TopAbs_FACE)
    k = -1
    while exp.More():
        face = TopoDS.Face_s(exp.Current())
        exp.Next()
        k += 1
        loc = TopLoc_Location()
        tri = BRep_Tool.Triangulation_s(face, loc)
        if tri is None or tri.NbTriangles() == 0:
            missing += 1
            continue
        n, m = tri.NbNodes(), tri.NbTriangles()
        node = tri.Node
        p = np.array([node(i).Coord() for i in range(1, n + 1)], dtype=np.float64)
        triangle = tri.Triangle
        t = np.array([triangle(i).Get() for i in range(1, m + 1)], dtype=np.int64) - 1
        if not tri.HasNormals():
            BRepLib_ToolTriangulatedShape.ComputeNormals_s(face, tri)
        normal = tri.Normal
        nn = np.array([normal(i).Coord() for i in range(1, n + 1)], dtype=np.float64)
        if face.Orientation() == TopAbs_REVERSED:
            # the triangulation and its normals follow the surface's natural orientation; the face uses
            # the surface reversed, so both the winding and the normals turn round
            t = t[:, [0, 2, 1]]
            nn = -nn
        if not loc.IsIdentity():
            trsf = loc.Transformation()
            a = np.array([[trsf.Value(r, c) for c in range(1, 4)] for r in range(1, 4)])
            b = np.array([trsf.Value(r, 4) for r in range(1, 4)])
            p = p @ a.T + b
            nn = nn @ a.T  # rotation (and uniform scale): normalised below
        verts.append(p)
        tris.append(t)
        norms.append(nn)
        index.append(k)
    if not verts:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 3)), missing, np.zeros(0, np.uint32)
    # faces in an order of their own (where they lie), not the writer's: a re-export that lists the same
    # faces in another order gives the same arrays, hence the same geometry id
    order = _face_order(verts, tris)
    verts, norms = [verts[k] for k in order], [norms[k] for k in order]
    offsets = np.cumsum([0] + [len(verts[k]) for k in range(len(verts) - 1)])
    face_ids = np.concatenate([np.full(len(tris[k]), index[k], np.uint32) for k in order])
    tris = [tris[k] + offsets[j] for j, k in enumerate(order)]
    v = np.concatenate(verts)
    nn = np.concatenate(norms)
    length = np.linalg.norm(nn, axis=1, keepdims=True)
    nn = np.where(length > 0, nn / np.where(length > 0, length, 1.0), 0.0)
    return v, np.concatenate(tris), nn, missing, face_ids


def mesh_shape(shape, deflection: float, angular: float, parallel: bool = True) -> tuple[Mesh | None, int]:
    """Mesh one shape and read its triangulation into numpy.

    Parameters
    ----------
    shape : TopoDS_Shape
    deflection : float
        Absolute linear deflection, document units.
    angular : float
        Angular deflection, radians.
    parallel : bool
        Let OCCT mesh the faces in parallel.

    Returns
    -------
    mesh : Mesh or None
        None if the shape has no face.
    missing_faces : int
        Faces OCCT produced no triangles for.

    Raises
    ------
    TessellationError
        OCCT failed, or no face could be meshed.
    """
    from OCP.BRepBuilderAPI import BRepBuilderAPI_Copy
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.BRepTools import BRepTools

    if not has_faces(shape):
        return None, 0
    # mesh a deep copy without any triangulation: meshing also adjusts edge tolerances, so meshing the
    # document's own shape would change it (and its digest, and any later meshing of it)
    shape = BRepBuilderAPI_Copy(shape, True, False).Shape()
    BRepTools.Clean_s(shape, True)
    try:
        mesher = BRepMesh_IncrementalMesh(shape, deflection, False, angular, parallel)
    except Exception as exc:  # OCCT raises Standard_Failure subclasses
        raise TessellationError(f"OCCT meshing failed: {exc}") from exc
    if not mesher.IsDone():
        raise TessellationError(f"OCCT meshing did not finish (status flags {mesher.GetStatusFlags()})")
    v, t, n, missing, face_ids = _read_faces(shape)
    if len(t) == 0:
        raise TessellationError(f"no face could be meshed ({missing} face(s) without triangles)")
    v32, t32, n32 = canonical_arrays(v, t, n.astype(np.float32))
    # triangles collapsed to a segment (two corners at the same float32 point, e.g. at the pole of a
    # revolved surface) have no normal and no area: drop them, they only confuse a ray tracer
    corners = v32[t32]
    collapsed = ((corners[:, 0] == corners[:, 1]).all(axis=1) | (corners[:, 1] == corners[:, 2]).all(axis=1)
                 | (corners[:, 2] == corners[:, 0]).all(axis=1))
    if collapsed.any():
        t32 = np.ascontiguousarray(t32[~collapsed])
        face_ids = np.ascontiguousarray(face_ids[~collapsed])
    return Mesh(v32, t32, n32, geometry_id(v32, t32, n32, face_ids), deflection, face_ids), missing


class TessellationCache:
    """Meshes by (shape content digest, settings), in memory and optionally on disk.

    Parameters
    ----------
    directory : path, optional
        Where ``<key>.npz`` files are kept between processes (a CLI re-push after an edit then meshes only
        the changed parts). None: memory only.
    """

    def __init__(self, directory: str | Path | None = None) -> None:
        self.directory = Path(directory) if directory is not None else None
        self.memory: dict[str, Mesh] = {}

    @staticmethod
    def key(digest: str, deflection: float, angular: float) -> str:
        return hashlib.sha256(f"{digest}|{deflection!r}|{angular!r}|v3".encode()).hexdigest()  # v3: face ids

    def get(self, key: str) -> Mesh | None:
        if key in self.memory:
            return self.memory[key]
        if self.directory is not None:
            path = self.directory / f"{key}.npz"
            if path.exists():
                try:
                    with np.load(path) as z:
                        normals = z["normals"] if z["normals"].size else None
                        faces = z["face_ids"] if "face_ids" in z.files else None
                        mesh = Mesh(z["vertices"], z["triangles"], normals, str(z["geometry_id"]),
                                    float(z["deflection"]), faces)
                except (OSError, ValueError, KeyError):
                    return None  # a damaged cache entry is a miss, rewritten below
                if geometry_id(mesh.vertices, mesh.triangles, mesh.normals, mesh.face_ids) == mesh.geometry_id:
                    self.memory[key] = mesh
                    return mesh
        return None

    def put(self, key: str, mesh: Mesh) -> None:
        self.memory[key] = mesh
        if self.directory is not None:
            self.directory.mkdir(parents=True, exist_ok=True)
            tmp = self.directory / f"{key}.tmp.npz"
            extra: dict[str, Any] = {"face_ids": mesh.face_ids} if mesh.face_ids is not None else {}
            np.savez(tmp, vertices=mesh.vertices, triangles=mesh.triangles,
                     normals=mesh.normals if mesh.normals is not None else np.zeros((0, 3), np.float32),
                     geometry_id=np.array(mesh.geometry_id), deflection=np.array(mesh.deflection), **extra)
            tmp.replace(self.directory / f"{key}.npz")


def tessellate(doc: Document, settings: Settings, cache: TessellationCache | None = None,
               progress: Callable[[int, int, str], None] | None = None, parallel: bool = True) -> Tessellation:
    """Tessellate every distinct part of a document (instances share one mesh).

    Parameters
    ----------
    doc : Document
    settings : Settings
    cache : TessellationCache, optional
        Parts whose B-rep and settings were meshed before are taken from it.
    progress : callable(done, total, part_name), optional
        Called after each part.
    parallel : bool
        OCCT's parallel meshing of each part's faces.

    Returns
    -------
    Tessellation
        A part that fails is listed in ``failed`` and the others go on.
    """
    if not isinstance(settings, Settings):
        raise TessellationError(f"settings must be a cad_adapter.tessellate.Settings, got {type(settings).__name__}")
    t0 = time.perf_counter()
    out = Tessellation(settings=settings)
    total = len(doc.parts)
    for done, part in enumerate(doc.parts.values(), start=1):
        label = part.name or part.key
        try:
            if part.key in doc.reuse:  # the same B-rep as the scene's mesh (identity): nothing to mesh
                out.reused += 1
                continue
            if not has_faces(part.shape):
                out.empty.append(part.key)
                continue
            if settings.relative:
                deflection = settings.linear * bbox_diagonal(part.shape)
                if not deflection > 0:
                    raise TessellationError("the part has zero size")
            else:
                deflection = settings.linear
            key = None
            if cache is not None:
                key = TessellationCache.key(shape_digest(part.shape), deflection, settings.angular)
                hit = cache.get(key)
                if hit is not None:
                    out.meshes[part.key] = hit
                    out.cached += 1
                    continue
            mesh, missing = mesh_shape(part.shape, deflection, settings.angular, parallel)
            if mesh is None:
                out.empty.append(part.key)
                continue
            if missing:
                out.warnings.append(f"part {label!r}: {missing} face(s) could not be meshed; the mesh has holes")
            out.meshes[part.key] = mesh
            out.meshed += 1
            if cache is not None and key is not None:
                cache.put(key, mesh)
        except TessellationError as exc:
            out.failed[part.key] = str(exc)
        except Exception as exc:  # OCCT's own failures must not stop the other parts
            out.failed[part.key] = f"{type(exc).__name__}: {exc}"
        finally:
            if progress is not None:
                progress(done, total, label)
    out.seconds = time.perf_counter() - t0
    return out
