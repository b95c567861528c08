"""The bottom levels of a scene's geometries, packed in one store that grows by appending.

`GeometryStore` keeps each unique mesh once (by its content hash, `tracer.geometry_id`), builds the bottom levels of
the meshes added since the last build in one compiled, parallel call (`tracer.accel.blas.build_meshes`), or loads
them from the on-disk library (`tracer.accel.cache`), and appends their rows and triangles to the store arrays
that traversal reads (`tracer.accel.traverse.SceneArrays`: ``bvh_f``, ``tri_v``, ``tri_prim``, ``prim_slot``,
``tri_n``, and the per-geometry offsets ``geom_node0``, ``geom_tri0``, ``geom_ntri``, ``geom_has_normals``).
Indices are local to one geometry; offsets are explicit, so nothing in the store is ever rewritten.
`tracer.scene.Scene` owns one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tracer.accel import cache as blas_cache
from tracer.accel.blas import build_meshes, collapse, gather_triangles, refit
from tracer.accel.rows4 import aligned_rows, leaf_order_f32, pack_wide
from tracer.errors import UnknownIdError

#: BLAS build parameters: largest leaf and the cost of a triangle test relative to a node visit
MESH_MAX_LEAF = 4
MESH_ISECT_COST = 1.0
#: below this many triangles a BLAS is rebuilt rather than cached. 1: every mesh is kept, so that a restart
#: rebuilds no bottom level (Stamp-S3: 24 of its 29 meshes have fewer than 512 triangles; a small file loads in
#: well under a millisecond, and the promise "a restart rebuilds none" is worth more than the file count)
CACHE_MIN_TRIANGLES = 1


@dataclass
class Geometry:
    """One unique mesh: its index in the store, float32 vertices (n, 3), uint32 triangles (m, 3), optional vertex
    normals, and its object box (6,) (empty when m == 0)."""

    index: int
    vertices: np.ndarray
    triangles: np.ndarray
    normals: np.ndarray | None
    box: np.ndarray


def empty_store() -> dict[str, np.ndarray]:
    """The store arrays of no geometry."""
    return {
        "bvh": np.empty((0, 16), np.float32),
        "tri_v": np.empty((0, 9), np.float32), "tri_prim": np.empty(0, np.int32), "prim_slot": np.empty(0, np.int32),
        "tri_n": np.empty((0, 9), np.float32),
    }


class GeometryStore:
    """The unique geometries of a scene and their packed bottom levels (see the module docstring).

    cache_dir : the on-disk BLAS library, or None; cache_min_triangles : smaller meshes are not cached.
    """

    def __init__(self, cache_dir=None, cache_min_triangles: int = CACHE_MIN_TRIANGLES) -> None:
        self.cache_dir = cache_dir
        self.cache_min_triangles = int(cache_min_triangles)
        self.geoms: dict[str, Geometry] = {}
        self.ids: list[str] = []
        self.n_built = 0
        self.store = empty_store()
        self.node0 = np.empty(0, np.int64)
        self.tri0 = np.empty(0, np.int64)
        self.ntri = np.empty(0, np.int64)
        self.hasn = np.empty(0, np.bool_)

    def add(self, gid: str, v: np.ndarray, f: np.ndarray, n: np.ndarray | None, box: np.ndarray) -> bool:
        """Keep mesh `gid` (canonical arrays); False where it is kept already."""
        if gid in self.geoms:
            return False
        self.geoms[gid] = Geometry(len(self.ids), v, f, n, box)
        self.ids.append(gid)
        return True

    def geometry(self, gid: str) -> Geometry:
        """The kept mesh `gid`; `UnknownIdError` otherwise."""
        if not isinstance(gid, str) or gid not in self.geoms:
            raise UnknownIdError(f"unknown geometry id {gid!r}")
        return self.geoms[gid]

    def build_pending(self) -> tuple[int, int]:
        """Build (or load from the library) the bottom levels of the meshes added since the last call and append
        them to the store: (built, loaded)."""
        pending = [self.geoms[g] for g in self.ids[self.n_built:]]
        if not pending:
            return 0, 0
        loaded: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        if self.cache_dir is not None:
            for g in pending:
                if len(g.triangles) >= self.cache_min_triangles:
                    r = blas_cache.load(self.cache_dir, self.ids[g.index], len(g.triangles))
                    if r is not None:
                        loaded[g.index] = r
        to_build = [g for g in pending if g.index not in loaded]
        parts: list[tuple[list[Geometry], dict[str, np.ndarray], np.ndarray, np.ndarray]] = []
        if to_build:
            parts.append(self._build_batch(to_build))
        for g in pending:
            if g.index in loaded:
                parts.append(self._loaded_part(g, *loaded[g.index]))
        # append to the store; geometry offsets are explicit, so order in the store is free
        G = len(self.ids)
        node0 = np.concatenate([self.node0, np.zeros(G - len(self.node0), np.int64)])
        tri0 = np.concatenate([self.tri0, np.zeros(G - len(self.tri0), np.int64)])
        ntri = np.concatenate([self.ntri, np.zeros(G - len(self.ntri), np.int64)])
        hasn = np.concatenate([self.hasn, np.zeros(G - len(self.hasn), np.bool_)])
        new = {k: [v] for k, v in self.store.items()}
        n_nodes = len(self.store["bvh"])
        n_tris = len(self.store["tri_prim"])
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
        self.store = {k: np.concatenate(v, out=outs.get(k)) if len(v) > 1 else v[0] for k, v in new.items()}
        self.node0, self.tri0, self.ntri, self.hasn = node0, tri0, ntri, hasn
        self.n_built = G
        return len(to_build), len(loaded)

    def _build_batch(self, geoms: list[Geometry]):
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
                    blas_cache.save(self.cache_dir, self.ids[g.index], order[tri_off[q]:tri_off[q + 1]],
                                    node_a[sl], node_n[sl])
        return geoms, arrs, row_cnt, g_tris

    def _loaded_part(self, g: Geometry, order: np.ndarray, node_a: np.ndarray, node_n: np.ndarray):
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

