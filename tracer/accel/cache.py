"""On-disk library of prepared bottom levels (the paper's "library of prepared objects").

One file per geometry, ``<cache_dir>/<geometry id>.blas.npz`` (uncompressed ``.npz``), holding the
BVH *topology* only: leaf order and node links, plus the builder version, the geometry id and a
SHA-256 digest of all of it. Node boxes are not stored: they are refitted from the geometry on load,
so a file can at worst slow traversal, never make it wrong. A file is used only if it opens, its
version and id match, its digest matches and the topology passes :func:`tracer.accel.blas.check_topology`;
anything else (truncated, corrupt, foreign, older builder) is ignored and rebuilt. Writes go to a
temporary file in the same directory and are renamed into place, so readers in other processes see
either nothing or a whole file.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path

import numpy as np

from tracer.accel.blas import BUILDER_VERSION, check_topology


def cache_path(cache_dir: str | os.PathLike, gid: str) -> Path:
    """Path of the cache file of geometry ``gid``."""
    return Path(cache_dir) / f"{gid}.blas.npz"


def _digest(gid: str, order: np.ndarray, node_a: np.ndarray, node_n: np.ndarray) -> str:
    h = hashlib.sha256(BUILDER_VERSION.encode() + b"\0" + gid.encode() + b"\0")
    for a in (order, node_a, node_n):
        h.update(str(a.shape).encode())
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def save(cache_dir: str | os.PathLike, gid: str, order: np.ndarray, node_a: np.ndarray, node_n: np.ndarray) -> None:
    """Write the topology of one BLAS atomically (temp file + rename). I/O errors propagate."""
    order = np.ascontiguousarray(order, dtype="<i4")
    node_a = np.ascontiguousarray(node_a, dtype="<i4")
    node_n = np.ascontiguousarray(node_n, dtype="<i4")
    path = cache_path(cache_dir, gid)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{gid[:16]}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez(fh, version=np.array(BUILDER_VERSION), gid=np.array(gid), order=order, node_a=node_a,
                     node_n=node_n, digest=np.array(_digest(gid, order, node_a, node_n)))
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def load(cache_dir: str | os.PathLike, gid: str, n_triangles: int) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The cached ``(order, node_a, node_n)`` of geometry ``gid`` with ``n_triangles``, or None.

    None for a missing file and for any file that fails a check (see module docstring).
    """
    path = cache_path(cache_dir, gid)
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            if str(z["version"]) != BUILDER_VERSION or str(z["gid"]) != gid:
                return None
            order = z["order"]
            node_a = z["node_a"]
            node_n = z["node_n"]
            digest = str(z["digest"])
    except Exception:  # noqa: BLE001 - any unreadable file is simply rebuilt
        return None
    for a in (order, node_a, node_n):
        if a.dtype != np.dtype("<i4") or a.ndim != 1:
            return None
    if digest != _digest(gid, order, node_a, node_n):
        return None
    if order.shape[0] != n_triangles:
        return None
    seen = np.zeros(n_triangles, bool)
    if n_triangles and (order.min() < 0 or order.max() >= n_triangles):
        return None
    seen[order] = True
    if not seen.all():
        return None
    if not check_topology(node_a, node_n, n_triangles):
        return None
    return order.astype(np.int64), node_a.astype(np.int32), node_n.astype(np.int32)
