"""The scene's elements in use: one `Row` per instance that carries one, packed into `SceneArrays` at commit.

Python owns the rows; :mod:`tracer.kinds.relief` reads the packed ``el_*`` arrays. A model used by several instances
(the same element on many parts, in one scene) is packed once: its bits, points, cells and face planes are shared by
id.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np

from tracer.accel.store import Geometry
from tracer.elements import diffraction, outline, support
from tracer.elements import features as fx
from tracer.elements.microstructure import Microstructure
from tracer.elements.support import Row
from tracer.kinds import mesh, relief


class Reliefs:
    """Rows by instance id. Their packed arrays are kept until a row changes: a commit after a move (the hot path of
    a CAD edit) packs nothing again, and copies no element's points."""

    def __init__(self) -> None:
        self.rows: dict[int, Row] = {}
        self._packed: tuple[np.ndarray, ...] | None = None   # el_f ... el_item of `rows` as they are

    def drop(self, i: int) -> None:
        """Forget instance `i`'s row (it was removed, or its element taken off)."""
        if self.rows.pop(i, None) is not None:
            self._packed = None

    def untabulate(self) -> list[int]:
        """Use every element through its exact micro-geometry where a tabulated BSDF stood for it; the instances
        whose row changed."""
        changed = [i for i, row in self.rows.items() if row.table is not None]
        for i in changed:
            self.rows[i] = dataclasses.replace(self.rows[i], table=None)
        if changed:
            self._packed = None
        return changed

    def full_of(self, i: int, own: str) -> str:
        """The part's own geometry id of instance `i`: its row's where it carries an element, else `own`."""
        return self.rows[i].full if i in self.rows else own

    def put(self, i: int, element: Any, full: str, g: Geometry, add_geometry: Callable, *,
            facing: Any, faces: Any, face_ids: Any, mm_per_unit: float, table: Any = None
            ) -> tuple[int, str, np.ndarray]:
        """Put `element` (a `Microstructure` or a `tracer.elements.grating.GratingTable`) onto part `g` (geometry id
        `full`) of instance `i`, or take it off (None); answers what the instance becomes: ``(kind, geometry id,
        object box)``. A support that cannot carry it raises `ElementError` with nothing changed."""
        if element is None:
            self.drop(i)
            return mesh.KIND, full, g.box
        ids = None if face_ids is None else np.asarray(face_ids)
        prims = support.select(g.vertices, g.triangles, facing=facing, faces=faces, face_ids=ids)
        row = self.make_row(add_geometry, element, full, g.vertices, g.triangles, g.normals, prims, mm_per_unit)
        if table is not None:
            row = dataclasses.replace(row, table=table)
        self.rows[i] = row
        self._packed = None
        return relief.KIND, row.rest, support.box(row, g.box)

    def make_row(self, add_geometry: Callable, element: Any, full: str, vertices: np.ndarray,
                 triangles: np.ndarray, normals: np.ndarray | None, prims: np.ndarray, mm_per_unit: float) -> Row:
        """A row for `element` on the triangles `prims` of geometry `full` (checked: planar; where they are not their
        u-v box, the features that lie wholly on them: `outline.mask`), its mesh split by `add_geometry`
        (`tracer.Scene.add_geometry`) into the rest and the support. Changes no row."""
        fr = support.frame(vertices, triangles, prims, mm_per_unit)
        kept = None
        if fr.outline is not None and isinstance(element, Microstructure):
            kept = outline.mask(fr.outline, fr.lu, fr.lv, element.a)
        on = np.zeros(len(triangles), bool)
        on[prims] = True
        rest_prims = np.flatnonzero(~on).astype(np.int32)
        support_prims = np.flatnonzero(on).astype(np.int32)
        rest = add_geometry(vertices, triangles[rest_prims], normals)
        sup = add_geometry(vertices, triangles[support_prims], normals)
        return Row(element, fr, full, rest, sup, rest_prims, support_prims, mask=kept)

    def pack(self, n_ids: int, index_of: Callable[[str], int]) -> tuple[np.ndarray, ...]:
        """``(inst_aux, el_f, el_i, el_prim, el_bits, el_uv, el_bin, el_item, el_tab, el_face)`` for `n_ids`
        instance ids; `index_of` gives a geometry's index in the store."""
        aux = np.full(n_ids, -1, np.int32)
        for r, i in enumerate(sorted(self.rows)):
            aux[i] = r
        if self._packed is None:
            self._packed = self._pack(index_of)
        return (aux, *self._packed)

    def _pack(self, index_of: Callable[[str], int]) -> tuple[np.ndarray, ...]:
        """``(el_f, el_i, el_prim, el_bits, el_uv, el_bin, el_item, el_tab, el_face)`` of the rows, in instance
        order."""
        ef = np.zeros((len(self.rows), fx.NF))
        ei = np.zeros((len(self.rows), fx.NI), np.int64)
        prim: list[np.ndarray] = []
        bits: list[np.ndarray] = []
        uv: list[np.ndarray] = []
        bins: list[np.ndarray] = []
        items: list[np.ndarray] = []
        tabs: list[np.ndarray] = []
        faces: list[np.ndarray] = []
        n_tab = 0
        shared: dict[str, tuple[int, int, int, int, int]] = {}
        gratings: dict[str, int] = {}   # a grating's first row in el_tab
        fills: list[tuple[int, np.ndarray]] = []   # (row, a density map's fill) of the tables read by fill level
        sizes = [0, 0, 0, 0, 0, 0]   # el_prim, el_bits, el_uv, el_bin, el_item, el_face so far
        for r, (_, row) in enumerate(sorted(self.rows.items())):
            ef[r], ei[r] = support.row_params(row, index_of(row.support))
            inverse = np.empty(len(row.rest_prims) + len(row.support_prims), np.int32)
            inverse[row.rest_prims] = np.arange(len(row.rest_prims))
            inverse[row.support_prims] = -1 - np.arange(len(row.support_prims))
            ei[r, fx.MAP_A] = sizes[0]
            ei[r, fx.MAP_S] = sizes[0] + len(row.rest_prims)
            ei[r, fx.MAP_INV] = sizes[0] + len(row.rest_prims) + len(row.support_prims)
            prim += [row.rest_prims, row.support_prims, inverse]
            sizes[0] += 2 * len(inverse)
            e = row.element
            if not isinstance(e, Microstructure):   # a grating: its table of orders, once per element
                if e.id not in gratings:
                    gratings[e.id] = n_tab
                    tabs.append(diffraction.pack(e))
                    n_tab += len(tabs[-1])
                ei[r, fx.TAB] = gratings[e.id]
                continue
            if e.id not in shared:
                shared[e.id] = (sizes[1], sizes[2], sizes[3], sizes[4], sizes[5])
                bits.append(e.bits)
                uv.append(e.uv)
                bins.append(e.bins)
                items.append(e.items)
                faces.append(e.faces)
                for k, a in enumerate((e.bits, e.uv, e.bins, e.items, e.faces)):
                    sizes[1 + k] += len(a)
            ei[r, fx.BITS], ei[r, fx.UV], ei[r, fx.BINS], ei[r, fx.ITEMS], ei[r, fx.FACE] = shared[e.id]
            ei[r, fx.NFACE] = len(e.faces)
            if row.mask is not None:   # the row's own outline (the same element may lie on other outlines)
                ei[r, fx.MASK] = sizes[1]
                bits.append(row.mask[0])
                sizes[1] += len(row.mask[0])
            if row.table is not None:
                ei[r, fx.TAB] = n_tab
                tabs.append(row.table.cdf)
                n_tab += len(row.table.cdf)
                if row.table.levels > 1:   # its fill map, row-major, in rows of el_tab's width (known below)
                    fills.append((r, support.fill_map(e).ravel()))
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


def _cat(parts: list[np.ndarray], dtype: type, empty: tuple[int, ...] = (0,)) -> np.ndarray:
    return np.concatenate(parts).astype(dtype, copy=False) if parts else np.zeros(empty, dtype)
