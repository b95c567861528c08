"""The scene's two top levels, brought up to date at a commit: rebuilt, or refitted where only a few instances moved.

"top" holds the solid instances (8-wide float32 rows, `tracer.accel.rows8`, and a record per item,
`tracer.accel.tlas.instance_records`); "sen" the sensor instances (binary rows, walked for crossings only). A commit
that only moved a few instances refits a level instead of rebuilding it (`Scene(tlas_refit=...)`); a rebuild still
happens after `MAX_REFITS` refitting commits or once the instances moved since the last build exceed a level's
n/8, so refits cannot degrade the tree for long.
"""

from __future__ import annotations

import numpy as np

from tracer.accel.tlas import TopLevel, build_top, instance_records, refit_top
from tracer.kinds import SENSOR_KINDS, mesh

#: a top level is rebuilt after this many refitting commits (see ``Scene(tlas_refit=...)``)
MAX_REFITS = 64
LEVELS = ("top", "sen")


class TopLevels:
    """The solid ("top") and sensor ("sen") top levels of a scene, and what changed in each since the last commit.

    wbox : (capacity, 6) world boxes of the instances (read at a build); refit : whether a commit that moves a few
    instances may refit instead of rebuilding.
    """

    def __init__(self, wbox: np.ndarray, refit: bool) -> None:
        self.refit = refit
        self.moved: dict[str, set[int]] = {"top": set(), "sen": set()}
        self.struct = {"top": True, "sen": True}
        self.refits = {"top": (0, 0), "sen": (0, 0)}  # (refit commits, instances moved) since build
        self.levels: dict[str, TopLevel] = {"top": build_top(np.empty(0, np.int64), wbox),
                                            "sen": build_top(np.empty(0, np.int64), wbox, wide=False)}
        self.top_rec = np.zeros(0, np.int64)   # instance_records of the solid top level's items

    def touch(self, i: int, kind: int, structural: bool) -> None:
        """Instance `i` (of bottom-level `kind`) was added or removed (`structural`), or moved."""
        level = "sen" if kind in SENSOR_KINDS else "top"
        if structural:
            self.struct[level] = True
        else:
            self.moved[level].add(i)

    def update(self, kind: np.ndarray, all_kinds: np.ndarray, igeom: np.ndarray, wbox: np.ndarray, blas) -> dict:
        """Rebuild or refit each level that changed; ``{"top": mode, "sen": mode}``, mode "none", "refit" or
        "rebuild". `kind` (n,): the live instances' kinds; `all_kinds`, `igeom`, `wbox`: the instance arrays;
        `blas`: the scene's `tracer.accel.store.GeometryStore` (offsets for the solid items' records)."""
        n = len(kind)
        modes = {"top": "none", "sen": "none"}
        for level in LEVELS:
            moved = self.moved[level]
            if not (self.struct[level] or moved):
                continue
            n_level = len(self.levels[level].items)
            commits, count = self.refits[level]
            if (not self.struct[level] and self.refit and len(moved) <= max(16, n_level // 64)
                    and commits < MAX_REFITS and count + len(moved) <= max(16, n_level // 8)):
                self.levels[level] = refit_top(self.levels[level], np.fromiter(moved, np.int64, len(moved)), wbox)
                self.refits[level] = (commits + 1, count + len(moved))
                modes[level] = "refit"
            else:
                if level == "top":
                    keep = (kind >= 0) & ~np.isin(kind, list(SENSOR_KINDS)) & (wbox[:n, 0] <= wbox[:n, 3])
                else:
                    keep = np.isin(kind, list(SENSOR_KINDS))
                self.levels[level] = build_top(np.flatnonzero(keep), wbox, wide=level == "top")
                if level == "top":
                    self.top_rec = instance_records(self.levels[level].items, all_kinds, igeom, blas.node0,
                                                    blas.tri0, blas.ntri, mesh.KIND)
                self.refits[level] = (0, 0)
                modes[level] = "rebuild"
            self.struct[level] = False
            self.moved[level] = set()
        return modes
