"""The scene's elements in use: one `Part` per instance that carries any, one `Row` per element on it, packed into
`SceneArrays` at commit.

Python owns the rows; :mod:`tracer.kinds.relief` reads the packed ``el_*`` arrays: a part's rows are consecutive from
its ``inst_aux`` entry, in the order its elements were put on. A model used by several rows (the same element on many
parts, in one scene) is packed once: its bits, points, cells and face planes are shared by id.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Hashable
from typing import Any

import numpy as np

from tracer.accel.store import Geometry
from tracer.elements import diffraction, outline, support
from tracer.elements import features as fx
from tracer.elements.checks import ElementError, SupportTaken
from tracer.elements.microstructure import Microstructure
from tracer.elements.support import Row
from tracer.kinds import mesh, relief


@dataclasses.dataclass(frozen=True)
class Part:
    """A part that carries elements: its own geometry id, the rest (the part without any support: its own geometry id
    and rest triangle -> part triangle) and its rows by key, in the order they were put on."""

    full: str
    rest: str
    rest_prims: np.ndarray
    rows: dict[Hashable, Row]


class Reliefs:
    """Parts by instance id. Their packed arrays are kept until a row changes: a commit after a move (the hot path of
    a CAD edit) packs nothing again, and copies no element's points."""

    def __init__(self) -> None:
        self.parts: dict[int, Part] = {}
        self._packed: tuple[np.ndarray, ...] | None = None   # el_f ... el_face of `parts` as they are

    def rows(self) -> list[tuple[int, Hashable, Row]]:
        """Every row as ``(instance, key, row)``, in packed order (by instance, then as put on)."""
        return [(i, key, row) for i, part in sorted(self.parts.items()) for key, row in part.rows.items()]

    def row(self, i: int, key: Hashable) -> Row | None:
        part = self.parts.get(i)
        return None if part is None else part.rows.get(key)

    def drop(self, i: int) -> None:
        """Forget instance `i`'s elements (it was removed)."""
        if self.parts.pop(i, None) is not None:
            self._packed = None

    def untabulate(self) -> list[int]:
        """Use every element through its exact micro-geometry where a tabulated BSDF stood for it; the instances
        whose rows changed."""
        changed = sorted({i for i, _, row in self.rows() if row.table is not None})
        for i in changed:
            part = self.parts[i]
            rows = {k: dataclasses.replace(r, table=None) for k, r in part.rows.items()}
            self.parts[i] = dataclasses.replace(part, rows=rows)
        if changed:
            self._packed = None
        return changed

    def full_of(self, i: int, own: str) -> str:
        """The part's own geometry id of instance `i`: its part's where it carries an element, else `own`."""
        return self.parts[i].full if i in self.parts else own

    def put(self, i: int, element: Any, full: str, g: Geometry, add_geometry: Callable, *, key: Hashable = 0,
            facing: Any = None, faces: Any = None, face_ids: Any = None, mm_per_unit: float = 1000.0,
            table: Any = None) -> tuple[int, str, np.ndarray]:
        """Put `element` (a `Microstructure` or a `tracer.elements.grating.GratingTable`) onto part `g` (geometry id
        `full`) of instance `i` as its element `key` (in place of the one it had there), or take that one off
        (None); answers what the instance becomes: ``(kind, geometry id, object box)``. A support that cannot carry
        it, or that shares a triangle with another of the part's elements, raises `ElementError` with nothing
        changed."""
        part = self.parts.get(i)
        rows = dict(part.rows) if part is not None else {}
        if element is None:
            rows.pop(key, None)
        else:
            ids = None if face_ids is None else np.asarray(face_ids)
            prims = support.select(g.vertices, g.triangles, facing=facing, faces=faces, face_ids=ids)
            for other, row in rows.items():
                shared = np.intersect1d(prims, row.support_prims)
                if other != key and len(shared):
                    raise SupportTaken(f"the support shares {len(shared)} of its {len(prims)} triangles with the "
                                       f"part's element {other!r}: one element a face; select other faces or take "
                                       f"that one off first", other)
            if key not in rows and len(rows) >= fx.PART_ROWS:
                raise ElementError(f"a part carries at most {fx.PART_ROWS} elements; it carries {len(rows)}")
            row = self.make_row(add_geometry, element, g.vertices, g.triangles, g.normals, prims, mm_per_unit)
            rows[key] = row if table is None else dataclasses.replace(row, table=table)
        self._packed = None
        if not rows:
            self.parts.pop(i, None)
            return mesh.KIND, full, g.box
        on = np.zeros(len(g.triangles), bool)
        for row in rows.values():
            on[row.support_prims] = True
        rest_prims = np.flatnonzero(~on).astype(np.int32)
        rest = add_geometry(g.vertices, g.triangles[rest_prims], g.normals)
        self.parts[i] = Part(full, rest, rest_prims, rows)
        boxes = np.array([support.box(row, g.box) for row in rows.values()])
        return relief.KIND, rest, np.concatenate([boxes[:, :3].min(axis=0), boxes[:, 3:].max(axis=0)])

    def make_row(self, add_geometry: Callable, element: Any, vertices: np.ndarray, triangles: np.ndarray,
                 normals: np.ndarray | None, prims: np.ndarray, mm_per_unit: float) -> Row:
        """A row for `element` on the triangles `prims` of a part (checked: planar; where they are not their u-v box,
        the features that lie wholly on them: `outline.mask`), its support a geometry of its own added by
        `add_geometry` (`tracer.Scene.add_geometry`). Changes no row."""
        fr = support.frame(vertices, triangles, prims, mm_per_unit)
        kept = None
        if fr.outline is not None and isinstance(element, Microstructure):
            kept = outline.mask(fr.outline, fr.lu, fr.lv, element.a)
        support_prims = np.sort(np.asarray(prims)).astype(np.int32)
        sup = add_geometry(vertices, triangles[support_prims], normals)
        return Row(element, fr, sup, support_prims, mask=kept)

    def pack(self, n_ids: int, index_of: Callable[[str], int]) -> tuple[np.ndarray, ...]:
        """``(inst_aux, el_f, el_i, el_prim, el_bits, el_uv, el_bin, el_item, el_tab, el_face)`` for `n_ids`
        instance ids (``inst_aux``: each instance's first row, -1 where it carries none); `index_of` gives a
        geometry's index in the store."""
        aux = np.full(n_ids, -1, np.int32)
        r = 0
        for i, part in sorted(self.parts.items()):
            aux[i] = r
            r += len(part.rows)
        if self._packed is None:
            self._packed = self._pack(index_of)
        return (aux, *self._packed)

    def _pack(self, index_of: Callable[[str], int]) -> tuple[np.ndarray, ...]:
        """``(el_f, el_i, el_prim, el_bits, el_uv, el_bin, el_item, el_tab, el_face)`` of the rows, in instance
        order."""
        all_rows = self.rows()
        ef = np.zeros((len(all_rows), fx.NF))
        ei = np.zeros((len(all_rows), fx.NI), np.int64)
        bits: list[np.ndarray] = []
        uv: list[np.ndarray] = []
        bins: list[np.ndarray] = []
        items: list[np.ndarray] = []
        tabs: list[np.ndarray] = []
        faces: list[np.ndarray] = []
        n_tab = 0
        shared: dict[str, tuple[int, ...]] = {}
        gratings: dict[str, int] = {}   # a grating's first row in el_tab
        fills: list[tuple[int, np.ndarray]] = []   # (row, a density map's fill) of the tables read by fill level
        sizes = [0, 0, 0, 0, 0]   # el_bits, el_uv, el_bin, el_item, el_face so far
        for r, (_, _, row) in enumerate(all_rows):
            ef[r], ei[r] = support.row_params(row, index_of(row.support))
            e = row.element
            if not isinstance(e, Microstructure):   # a grating: its table of orders, once per element
                if e.id not in gratings:
                    gratings[e.id] = n_tab
                    tabs.append(diffraction.pack(e))
                    n_tab += len(tabs[-1])
                ei[r, fx.TAB] = gratings[e.id]
                continue
            if e.id not in shared:
                shared[e.id] = tuple(sizes)
                bits.append(e.bits)
                uv.append(e.uv)
                bins.append(e.bins)
                items.append(e.items)
                faces.append(e.faces)
                for k, a in enumerate((e.bits, e.uv, e.bins, e.items, e.faces)):
                    sizes[k] += len(a)
            ei[r, fx.BITS], ei[r, fx.UV], ei[r, fx.BINS], ei[r, fx.ITEMS], ei[r, fx.FACE] = shared[e.id]
            ei[r, fx.NFACE] = len(e.faces)
            if row.mask is not None:   # the row's own outline (the same element may lie on other outlines)
                ei[r, fx.MASK] = sizes[0]
                bits.append(row.mask[0])
                sizes[0] += len(row.mask[0])
            if row.table is not None:
                ei[r, fx.TAB] = n_tab
                tabs.append(row.table.cdf)
                n_tab += len(row.table.cdf)
                if row.table.levels > 1:   # its fill map, row-major, in rows of el_tab's width (known below)
                    fills.append((r, support.fill_map(e).ravel()))
        prim = _part_maps(self.parts, ei)
        width = max((len(t[0]) for t in tabs), default=0)
        for r, fill in fills:
            ei[r, fx.FILL] = n_tab * width
            rows = -(-len(fill) // width)
            tabs.append(np.pad(fill, (0, rows * width - len(fill))).reshape(rows, width))
            n_tab += rows
        tab = np.zeros((n_tab, width))
        k = 0
        for t in tabs:
            tab[k:k + len(t), :t.shape[1]] = t
            k += len(t)
        return (ef, ei, _cat(prim, np.int32), _cat(bits, np.uint8), _cat(uv, np.float32, (0, 2)),
                _cat(bins, np.int32), _cat(items, np.int32), tab, _cat(faces, np.float64, (0, 4)))


def _part_maps(parts: dict[int, Part], ei: np.ndarray) -> list[np.ndarray]:
    """The parts' ``el_prim`` entries, in instance order, their offsets and each row's place written into `ei`."""
    prim: list[np.ndarray] = []
    first = at = 0
    for _, part in sorted(parts.items()):
        maps = _prim_maps(part, at)
        prim += maps[0]
        at += sum(len(a) for a in maps[0])
        for k in range(len(part.rows)):
            ei[first + k, fx.MAP_A], ei[first + k, fx.MAP_INV] = maps[1], maps[2]
            ei[first + k, fx.MAP_S], ei[first + k, fx.S_START] = maps[3][k], maps[4][k]
            ei[first + k, fx.PART_N], ei[first + k, fx.PART_K] = len(part.rows), k
        first += len(part.rows)
    return prim


def _prim_maps(part: Part, at: int) -> tuple[list[np.ndarray], int, int, list[int], list[int]]:
    """A part's ``el_prim`` entries (from offset `at`): rest -> part, each row's support -> part, and part -> either
    (>= 0: a rest triangle; ``-1 - j``: the j-th of the supports taken in row order); with the offsets of the first
    (``MAP_A``), the last (``MAP_INV``) and each row's support map (``MAP_S``), and each row's first j (``S_START``)."""
    supports = [row.support_prims for row in part.rows.values()]
    inverse = np.empty(len(part.rest_prims) + sum(len(p) for p in supports), np.int32)
    inverse[part.rest_prims] = np.arange(len(part.rest_prims))
    starts = np.cumsum([0] + [len(p) for p in supports])
    map_s = []
    for k, p in enumerate(supports):
        inverse[p] = -1 - (starts[k] + np.arange(len(p)))
        map_s.append(at + len(part.rest_prims) + int(starts[k]))
    return ([part.rest_prims, *supports, inverse], at, at + len(part.rest_prims) + int(starts[-1]), map_s,
            [int(x) for x in starts[:-1]])


def _cat(parts: list[np.ndarray], dtype: type, empty: tuple[int, ...] = (0,)) -> np.ndarray:
    return np.concatenate(parts).astype(dtype, copy=False) if parts else np.zeros(empty, dtype)
