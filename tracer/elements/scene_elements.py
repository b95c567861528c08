"""Elements with an inside on a scene's parts: `SceneElements` is the half of `tracer.Scene` that puts elements
onto a part's planar supports (or takes them off) and says where they lie; the scene's own module keeps the rest of what
edits it, `tracer.elements.table.Reliefs` the elements' rows.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from typing import Any

import numpy as np

from tracer.accel.store import Geometry, GeometryStore
from tracer.elements.checks import ElementError
from tracer.elements.microstructure import Microstructure
from tracer.elements.table import Reliefs
from tracer.kinds import mesh, relief


class SceneElements:
    """Provided by the class using it (`tracer.Scene`): its instance arrays, its element rows and its geometry
    library."""

    _kind: np.ndarray
    _igeom: np.ndarray
    _obox: np.ndarray
    _wfo: np.ndarray
    _reliefs: Reliefs
    _blas: GeometryStore
    add_geometry: Callable[..., str]
    _instance: Callable[[Any], int]
    _geometry: Callable[[str], Geometry]
    _touch: Callable[[int, bool], None]

    def set_element(self, i: int, element: Any, *, facing: Any = None, faces: Any = None,
                    face_ids: Any = None, mm_per_unit: float = 1000.0, table: Any = None, key: Hashable = 0) -> None:
        """Put `element` onto a planar support of mesh instance `i` as its element `key` (in place of the one it had
        there), or take that one off (None). The support: the triangles `facing` a direction of the part's frame, or
        the B-rep `faces` given each triangle's `face_ids` (`tracer.elements.support.select`); a part carries up to
        `features.PART_ROWS` elements on supports that share no triangle (`SupportTaken` otherwise). A grating
        (`tracer.elements.grating.GratingTable`) goes on the same way and scatters by its table of orders
        (`tracer.elements.diffraction`). Its instance id, transform and material stay; `mm_per_unit`: millimetres per
        object unit. With `table` (`tracer.elements.bsdf.tabulate` of the element on the part's material) the element
        is used through its tabulated BSDF: the plain support, whose hits scatter by the table, instead of its
        micro-geometry."""
        i = self._instance(i)
        if int(self._kind[i]) not in (mesh.KIND, relief.KIND):
            raise ElementError(f"instance {i} is not a part (a sensor cannot carry an element)")
        full = self._reliefs.full_of(i, self._blas.ids[int(self._igeom[i])])
        kind, rest, box = self._reliefs.put(i, element, full, self._geometry(full), self.add_geometry, key=key,
                                            facing=facing, faces=faces, face_ids=face_ids, mm_per_unit=mm_per_unit,
                                            table=table)
        self._kind[i], self._igeom[i], self._obox[i] = kind, self._geometry(rest).index, box
        self._touch(i, True)

    def elements_on(self, i: int) -> list[Hashable]:
        """The keys of the elements instance `i` carries, in the order they were put on."""
        part = self._reliefs.parts.get(self._instance(i))
        return [] if part is None else list(part.rows)

    def tabulated_elements(self) -> list[int]:
        """The instances that carry an element used through its tabulated BSDF, ascending."""
        return sorted({i for i, _, row in self._reliefs.rows() if row.table is not None})

    def exact_elements(self) -> list[int]:
        """Trace every element by its exact micro-geometry where its tabulated BSDF stood for it (what the query option
        ``physics_left_out: ["element_geometry"]`` measures against); the instances changed (commit to see them)."""
        changed = self._reliefs.untabulate()
        for i in changed:
            self._touch(i, False)
        return changed

    def gratings(self) -> list[Any]:
        """Every grating (`tracer.elements.grating.GratingTable`) the scene's parts carry, in instance order."""
        return [row.element for _, _, row in self._reliefs.rows() if not isinstance(row.element, Microstructure)]

    def element_support(self, i: int, key: Hashable = 0) -> dict[str, Any] | None:
        """What carries instance `i`'s element `key`: ``{"triangles": n, "size_mm": [lu, lv], "normal": [x, y, z],
        "outline": bool}`` (its support's triangles of the part, its extent along u and v, its outward normal in the
        part's frame, and whether it is less than its u-v box, so that only the features whose base lies wholly on
        it are placed: `tracer.elements.outline`); None where the instance carries none by that key."""
        row = self._reliefs.row(self._instance(i), key)
        if row is None:
            return None
        return {"triangles": int(len(row.support_prims)), "size_mm": [row.frame.lu, row.frame.lv],
                "normal": [float(x) for x in row.frame.n], "outline": row.frame.outline is not None}

    def element_of(self, i: int, key: Hashable = 0) -> tuple[Microstructure, np.ndarray, np.ndarray, np.ndarray] | None:
        """Instance `i`'s element `key` and where its support lies in the world: ``(model, origin, du, dv)``, a point
        at ``(u, v)`` mm of the support's frame being ``origin + u du + v dv`` (world units); None where it carries
        none by that key."""
        row = self._reliefs.row(self._instance(i), key)
        if row is None:
            return None
        fr, w = row.frame, self._wfo[i]
        return (row.element, w[:, :3] @ fr.o + w[:, 3], w[:, :3] @ fr.u / fr.mm, w[:, :3] @ fr.v / fr.mm)
