"""Optical files by content id: where the tracer finds a file that a body names by ``"file": "<id>"``.

Ray files (`tracer.optics.lights.rayfile`) and measured BRDF tables (`tracer.optics.surfaces.measured_brdf`) can be
tens or hundreds of MB: they are uploaded once (the service's ``POST /optical-files``) and named by their id, the
lowercase hex SHA-256 of the file's bytes, in any number of lights, materials and scenes. Whoever stores such files
(the service, at start) registers the directory that holds them as ``<dir>/<id>``; the kinds resolve an id to a path
here and read the file from disk (streamed, never as one Python ``bytes``). Because an id is the hash of the bytes,
any registered directory that holds a file of that name holds the right one.

Parsed files are kept in a small cache (by id and reader), read-only: a light validated on its way in and packed
for a query reads its file once.
"""

from __future__ import annotations

import hashlib
import re
import threading
from collections import OrderedDict
from collections.abc import Callable
from pathlib import Path
from typing import Any

from tracer.errors import TracerError

FILE_ID = re.compile(r"^[0-9a-f]{64}$")
CACHED = 4                 # parsed files kept in memory (the largest ray files are 10⁷ rays, 0.5 GB as float64)

_dirs: list[Path] = []
_cache: OrderedDict[tuple[str, str], Any] = OrderedDict()
_lock = threading.Lock()


class OpticalFileError(TracerError):
    """A file id that is malformed or that no registered directory holds."""


def file_id(data: bytes) -> str:
    """The id of a file's bytes: lowercase hex SHA-256."""
    return hashlib.sha256(data).hexdigest()


def register(directory: str | Path) -> None:
    """Look for files in `directory` too (``<directory>/<id>``); registering it again changes nothing."""
    d = Path(directory)
    with _lock:
        if d not in _dirs:
            _dirs.append(d)


def is_file_id(v: Any) -> bool:
    return isinstance(v, str) and FILE_ID.match(v) is not None


def path_of(fid: Any, where: str, name: str = "file") -> Path:
    """The path of file `fid`; `OpticalFileError` naming `where` and the field where it is no id or not stored."""
    if not is_file_id(fid):
        raise OpticalFileError(f"{where}: {name!r} must be an optical file's id (64 lowercase hex digits, the "
                               f"SHA-256 that POST /optical-files answered), got {str(fid)[:80]!r}")
    with _lock:
        dirs = list(_dirs)
    for d in dirs:
        p = d / fid
        if p.is_file():
            return p
    raise OpticalFileError(f"{where}: {name!r} names no stored optical file ({fid}): upload it first "
                           f"(POST /optical-files)")


def cached(fid: str, reader: str, parse: Callable[[], Any]) -> Any:
    """`parse()`'s result for file `fid` read by `reader`, parsed once while it stays among the `CACHED` last."""
    key = (fid, reader)
    with _lock:
        if key in _cache:
            _cache.move_to_end(key)
            return _cache[key]
    value = parse()
    with _lock:
        _cache[key] = value
        while len(_cache) > CACHED:
            _cache.popitem(last=False)
    return value
