"""Where an element sits: its support faces on a part, their frame, and the scene's table of elements in use.

An element goes onto the triangles of a part that face a direction (in the part's frame, within `FACING_DEG`) or
onto named B-rep faces. They must be planar, of any outline: u runs along the part's x axis projected onto the face
(its y axis where x is normal to it), v = n x u, from the corner of smallest u and v (docs/DESIGN.md); the layout
covers that u-v box, and where the support is not the whole box, only features whose base lies wholly on it are
placed (`tracer.elements.outline`). The part's mesh is split once per assignment into the support (its own bottom
level, so a ray that misses every feature meets the same triangles with the same test as without the element:
bit-exact) and the rest.

`Reliefs` is the scene's table: one row per element, a part's rows consecutive (up to `features.PART_ROWS` elements
on disjoint supports of one part), packed at commit into the `SceneArrays` ``el_*`` fields that
:mod:`tracer.kinds.relief` reads.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from tracer.elements import features as fx
from tracer.elements.checks import ElementError
from tracer.elements.microstructure import Microstructure
from tracer.elements.shapes.dispatch import KINDS as SHAPE_KINDS

FACING_DEG = 1.0          # a triangle faces the asked direction within this angle
PLANAR_REL = 1e-6         # support vertices within this fraction of its extent from its plane
RECTANGLE_REL = 1e-4      # the support's area within this fraction of its u-v box's


@dataclass(frozen=True)
class Frame:
    """The support's frame in object space: origin ``o`` (its corner of smallest u, v on the plane) and unit axes
    ``u, v, n`` ((3,) each); its extent ``lu, lv`` in mm; ``mm`` millimetres per object unit; ``outline`` its
    triangles (T, 3, 2) in u-v mm where it is not the whole u-v box (None where it is)."""

    o: np.ndarray
    u: np.ndarray
    v: np.ndarray
    n: np.ndarray
    lu: float
    lv: float
    mm: float
    outline: np.ndarray | None = None


def select(vertices: np.ndarray, triangles: np.ndarray, *, facing: Any = None, faces: Any = None,
           face_ids: np.ndarray | None = None) -> np.ndarray:
    """Indices of the triangles that carry the element: those facing `facing` (3 numbers, any length, the part's
    frame) or those of the B-rep faces `faces` (ints; `face_ids` gives each triangle's face). One of the two."""
    if (facing is None) == (faces is None):
        raise ElementError("give the support as 'facing' (a direction in the part's frame) or as 'faces' (its B-rep "
                           "face indices), one of the two")
    if faces is not None:
        if face_ids is None:
            raise ElementError("faces: this part's mesh carries no B-rep face indices; select by 'facing'")
        if len(face_ids) != len(triangles):
            raise ElementError(f"face_ids: {len(face_ids)} given for {len(triangles)} triangles (one per triangle)")
        if not isinstance(faces, list | tuple) or not faces or not all(
                isinstance(f, int) and not isinstance(f, bool) for f in faces):
            raise ElementError(f"faces must be a non-empty list of B-rep face indices (ints), got {faces!r}"[:300])
        present = np.unique(face_ids)
        for k, face in enumerate(faces):
            if face not in present:
                raise ElementError(f"faces[{k}] = {face}: the part's mesh has no triangle of B-rep face {face} (its "
                                   f"faces: {present.tolist()[:50]}{' ...' if len(present) > 50 else ''})")
        prims = np.flatnonzero(np.isin(face_ids, np.array(faces)))
        what = f"faces {list(faces)}"
    else:
        try:
            f = np.array(facing, dtype=np.float64)
        except (TypeError, ValueError):
            f = np.zeros(0)
        if f.shape != (3,) or not np.isfinite(f).all() or not np.linalg.norm(f) > 0:
            raise ElementError(f"facing must be a non-zero direction [x, y, z] in the part's frame, got {facing!r}"
                               [:300])
        n = _normals(vertices, triangles)
        prims = np.flatnonzero(n @ (f / np.linalg.norm(f)) >= math.cos(math.radians(FACING_DEG)))
        what = f"facing {f.tolist()}"
    if len(prims) == 0:
        raise ElementError(f"no triangle of the part is selected by {what}: check the direction (the part's own "
                           f"frame) or the face indices")
    return prims


def _normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    v = np.asarray(vertices, np.float64)[np.asarray(triangles)]
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, ln, out=np.zeros_like(n), where=ln > 0)


def frame(vertices: np.ndarray, triangles: np.ndarray, prims: np.ndarray, mm_per_unit: float) -> Frame:
    """The support's frame; `ElementError` where the selected triangles are not one plane."""
    if not (isinstance(mm_per_unit, int | float) and math.isfinite(mm_per_unit) and mm_per_unit > 0):
        raise ElementError(f"mm_per_unit must be a positive number, got {mm_per_unit!r}")
    tri = np.asarray(vertices, np.float64)[np.asarray(triangles)[prims]]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area2 = np.linalg.norm(cross, axis=1)
    if not area2.max() > 0:
        raise ElementError("the selected support has no area")
    n = cross[int(np.argmax(area2))] / area2.max()
    pts = tri.reshape(-1, 3)
    extent = float(np.ptp(pts, axis=0).max())
    off = pts @ n
    if float(np.ptp(off)) > PLANAR_REL * extent or (cross @ n < 0).any():
        raise ElementError(f"the selected support is not planar (its points lie {float(np.ptp(off)):.3g} apart along "
                           f"its normal): an element goes onto a planar face for now; select one plane")
    x = np.array([1.0, 0.0, 0.0])
    if abs(n @ x) > 0.9:
        x = np.array([0.0, 1.0, 0.0])
    u = x - (x @ n) * n
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    pu, pv = pts @ u, pts @ v
    box = float(np.ptp(pu) * np.ptp(pv))
    outline = None
    if abs(0.5 * float(area2.sum()) - box) > RECTANGLE_REL * box:   # not its whole u-v box: features within it
        outline = (np.column_stack([pu - pu.min(), pv - pv.min()]) * mm_per_unit).reshape(-1, 3, 2)
    o = pu.min() * u + pv.min() * v + float(np.mean(off)) * n
    return Frame(o, u, v, n, float(np.ptp(pu)) * mm_per_unit, float(np.ptp(pv)) * mm_per_unit, float(mm_per_unit),
                 outline)


@dataclass(frozen=True)
class Row:
    """One element on a part: the model, its frame, its support triangles (a geometry of their own) and their indices
    in the part."""

    element: Any             # a `Microstructure`, or a `tracer.elements.grating.GratingTable`
    frame: Frame
    support: str              # the support's triangles, their own geometry id
    support_prims: np.ndarray  # support triangle -> part triangle
    table: Any = None         # a `tracer.elements.bsdf.Table`: the element used through its tabulated model
    mask: tuple[np.ndarray, int, int, float] | None = None   # the outline's kept cells (`outline.mask`)


def fill_map(e: Microstructure) -> np.ndarray:
    """A density map's fill, (rows along v, columns along u), as its body gives it."""
    return np.asarray(e.body["layout"]["fill"], np.float64)


def row_params(row: Row, support_index: int) -> tuple[np.ndarray, np.ndarray]:
    """The row's ``el_f`` (NF,) and ``el_i`` (NI,) (offsets left at zero for `Reliefs.pack` to fill); a grating's
    (`tracer.elements.grating.GratingTable`, no micro-geometry) the frame and its model only."""
    e, fr = row.element, row.frame
    f = np.zeros(fx.NF)
    f[fx.O_X:fx.O_X + 3], f[fx.U_X:fx.U_X + 3], f[fx.V_X:fx.V_X + 3], f[fx.N_X:fx.N_X + 3] = fr.o, fr.u, fr.v, fr.n
    f[fx.MM], f[fx.LU], f[fx.LV] = fr.mm, fr.lu, fr.lv
    if not isinstance(e, Microstructure):
        i = np.zeros(fx.NI, np.int64)
        i[fx.GEOM_S], i[fx.MODEL], i[fx.NU], i[fx.NV] = support_index, fx.GRATING, 1, 1
        f[fx.FMAT] = fx.MAT_PART
        return f, i
    f[fx.A], f[fx.H], f[fx.RS], f[fx.SIGN] = e.a, e.h, e.rs, e.sign
    f[fx.SLOPE] = e.a / e.h
    f[fx.FMAT], f[fx.FRHO] = e.material, e.reflectance
    f[fx.CU], f[fx.CV] = e.cell
    f[fx.ORG_U], f[fx.ORG_V] = e.origin
    i = np.zeros(fx.NI, np.int64)
    i[fx.SHAPE], i[fx.LAYOUT], i[fx.GEOM_S] = e.shape, e.layout, support_index
    if row.mask is not None:   # its bits' offset is `Reliefs.pack`'s
        _, i[fx.MASK_NU], i[fx.MASK_NV], f[fx.MASK_H] = row.mask
    if row.table is not None:
        i[fx.MODEL], i[fx.TAB_MU], i[fx.TAB_PHI] = fx.BSDF, row.table.n_mu, row.table.n_phi
        i[fx.LEVELS], i[fx.TAB_SPLIT] = row.table.levels, row.table.split
        # `tracer.elements.bsdf.critical_mu`, written out: bsdf builds scenes, which hold this module (no import circle)
        f[fx.TAB_MUC] = math.sqrt(max(0.0, 1.0 - 1.0 / row.table.ior ** 2))
        if row.table.levels > 1:   # a density map's: the fill map the level is read from (`Reliefs.pack` places it)
            fill = fill_map(e)
            i[fx.FILL_NV], i[fx.FILL_NU] = fill.shape
            lay = e.body["layout"]
            f[fx.FILL_U0], f[fx.FILL_V0] = lay["origin_mm"]
            f[fx.FILL_DU], f[fx.FILL_DV] = lay["size_mm"][0] / fill.shape[1], lay["size_mm"][1] / fill.shape[0]
    if e.layout in (fx.GRID, fx.HEX):
        nu = max(1, int(fr.lu // e.cell[0]) + (1 if e.layout == fx.HEX else 0))
        nv = max(1, int(fr.lv // e.cell[1]))
        if SHAPE_KINDS[e.shape].RIDGE:   # one row of ridges across the whole support
            nv = 1
            f[fx.CV] = fr.lv
        i[fx.NU], i[fx.NV] = nu, nv
    elif e.layout == fx.TRIANGULAR:   # feature i spans cells i and i + 1 along u
        i[fx.NU], i[fx.NV] = max(0, int(fr.lu // e.cell[0]) - 1), int(fr.lv // e.cell[1])
    else:
        i[fx.NU], i[fx.NV] = e.cells
    return f, i


def box(row: Row, full_box: np.ndarray) -> np.ndarray:
    """(6,) object-space box of a part with its element: the part's, and the support raised by the feature height on
    its relief's side (a pit's stays inside the part's)."""
    fr, e = row.frame, row.element
    lift = e.sign * e.h / fr.mm * fr.n if isinstance(e, Microstructure) else 0.0 * fr.n
    corners = np.array([fr.o + a * fr.lu / fr.mm * fr.u + b * fr.lv / fr.mm * fr.v + c * lift
                        for a in (0, 1) for b in (0, 1) for c in (0, 1)])
    lo = np.minimum(full_box[:3], corners.min(axis=0))
    return np.concatenate([lo, np.maximum(full_box[3:], corners.max(axis=0))])
