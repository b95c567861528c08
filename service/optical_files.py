"""Optical files uploaded once and shared by every scene: ray files and measured BRDF tables, content-addressed.

A ray file (text columns or binary ANSI/IES TM-25) or a BRDF table can be hundreds of MB: it is sent once
(``POST /optical-files?format=…``, the raw bytes as the body), checked by the tracer's own reader, and kept as
``<data_dir>/optical-files/<id>``, its id the lowercase hex SHA-256 of its bytes (the same bytes, the same id:
a second upload stores nothing), with a summary beside it (``<id>.json``). A light or a material then names it:
``{"type": "rayfile", "file": "<id>", ...}``, ``{"type": "measured_brdf", "file": "<id>"}``; the tracer finds it
through `tracer.optics.files` (the directory is registered at start), so a restarted service keeps every file
and the scenes that name them. The body is streamed to a temporary file while it is hashed, never held in
memory whole; a file the reader refuses is deleted (422 naming what is wrong) and nothing is stored.

No database table: the directory is the store, written atomically (temporary name, then rename; the summary
after the file, so a summary always has its file).
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

from service.errors import Invalid, NotFound
from tracer.errors import TracerError
from tracer.optics import files

FORMATS = {"tm25": "a binary ANSI/IES TM-25 ray file", "rays": "a text ray file (x y z l m n flux per line)",
           "brdf": "a measured BRDF table: the text format of tracer.optics.surfaces.measured_brdf, or a Zemax / "
                   "Radiant BSDF Data Interchange (.bsdf) file (tracer.optics.surfaces.zemax_bsdf)"}


def _check(path: Path, fmt: str) -> dict[str, Any]:
    """Parse the file with the tracer's reader for `fmt`; its summary, or Invalid naming what is wrong."""
    where = f"optical file (format {fmt!r})"
    try:
        if fmt == "tm25":
            from tracer.optics.lights import tm25

            rs = tm25.read(path, where)
            return {"rays": int(len(rs.rays)), "flux": rs.total, "flux_unit": rs.unit, "name": rs.header.name,
                    "spectral": rs.header.spectral}
        if fmt == "rays":
            from tracer.optics.lights.rayfile import parse_rays

            rays = parse_rays(path.read_text(encoding="utf-8", errors="replace"), where, 1 << 40, "file")
            return {"rays": int(len(rays)), "flux": float(rays[:, 6].sum()), "flux_unit": "lm"}
        from tracer.optics.surfaces.measured_brdf import parse_table

        table = parse_table(path.read_text(encoding="utf-8", errors="replace"), "file", where)
        return {"shape": list(table.shape), "albedo_max": float(table.albedo().max())}
    except UnicodeError:
        raise Invalid(f"{where}: the file is not UTF-8 text") from None
    except TracerError as exc:
        raise Invalid(str(exc)) from None


class OpticalFiles:
    """The optical files under one directory, by id; registered with the tracer."""

    def __init__(self, directory: Path) -> None:
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        files.register(self.directory)

    def _meta(self, fid: str) -> Path:
        return self.directory / f"{fid}.json"

    async def upload(self, chunks: AsyncIterator[bytes], fmt: str) -> tuple[dict[str, Any], bool]:
        """Store the streamed bytes as a file of format `fmt`: (its summary, whether it is new)."""
        if fmt not in FORMATS:
            raise Invalid(f"'format' must be one of {sorted(FORMATS)}, got {fmt!r}")
        h = hashlib.sha256()
        fd, tmp_name = tempfile.mkstemp(dir=self.directory, prefix=".upload-")
        tmp = Path(tmp_name)
        size = 0
        try:
            with os.fdopen(fd, "wb") as fh:
                async for chunk in chunks:
                    h.update(chunk)
                    fh.write(chunk)
                    size += len(chunk)
            if size == 0:
                raise Invalid("the body is empty: send the file's bytes")
            fid = h.hexdigest()
            if self._meta(fid).exists():
                known = self.summary(fid)
                if known["format"] == fmt:
                    return known, False
            from starlette.concurrency import run_in_threadpool

            summary = {"id": fid, "format": fmt, "bytes": size, **await run_in_threadpool(_check, tmp, fmt)}
            os.replace(tmp, self.directory / fid)
            meta_fd, meta_tmp = tempfile.mkstemp(dir=self.directory, prefix=".meta-")
            with os.fdopen(meta_fd, "w") as fh:
                json.dump(summary, fh)
            os.replace(meta_tmp, self._meta(fid))
            return summary, True
        finally:
            tmp.unlink(missing_ok=True)

    def summary(self, fid: str) -> dict[str, Any]:
        """A stored file's summary; NotFound where none has that id."""
        if not files.is_file_id(fid) or not self._meta(fid).exists():
            raise NotFound(f"no optical file {fid} (POST /optical-files first)")
        return dict(json.loads(self._meta(fid).read_text()))

    def list(self) -> list[dict[str, Any]]:
        return [json.loads(p.read_text()) for p in sorted(self.directory.glob("*.json"))]
