"""Ray-file light: the near field of a source (an LED, a lamp) as a list of measured or simulated rays.

LED makers ship ray files (ANSI/IES TM-25; Radiant Imaging / Zemax / LightTools binary files) of 10⁵ to 10⁷ rays,
each a start point on or near the source, a direction and a flux, in the source's own frame. This kind reads the
plain-text column form those tools export: one ray per line, ``x y z l m n flux`` (start point in `units`,
direction cosines — normalised here —, flux in lm), blank lines and lines starting with ``#`` ignored, inline
(`data`) or uploaded once (`file`); and the binary ANSI/IES TM-25 file (`tracer.optics.lights.tm25`: layout,
sources, what is kept of its photometric and spectral content), uploaded once (``POST /optical-files``) and named
by its id (`tracer.optics.files`). The Radiant/Zemax/LightTools binary formats are not read.

==========  ==============  =====  ============================================================
Field       Type            Unit   Default
==========  ==============  =====  ============================================================
position    3 floats        m      required: where the file's origin sits
data        str             —      the file's text (at most 10 MB, about 2·10⁵ rays); or `file`
file        str (64 hex)    —      an uploaded file's id (`POST /optical-files`), text or TM-25; or `data`
format      "text", "tm25"  —      what `file` holds; default: TM-25 where it begins with ``TM25``, else text
units       "mm" or "m"     —      "mm" (of a text file's start points; a TM-25 file's are mm)
direction   3 floats ≠ 0    —      [0, 0, 1]: where the file's +z axis points
c0          3 floats ≠ 0    —      [1, 0, 0]: the file's +x axis (its part across `direction`)
flux_lm     float > 0       lm     the file's: its flux column's sum (text), its header's total (TM-25)
==========  ==============  =====  ============================================================

A photon is one of the file's rays, chosen in proportion to its flux (weight factor 1), started at its point and
sent along its direction, both turned into the light's frame. Photometric content: the flux column (relative, or
lm where `flux_lm` is absent); a `spectrum` applies to every ray (a TM-25 file's own spectrum where the body gives
none, and its watts through that spectrum's efficacy: `resolve`). Not connectable: a ray file is a set of exact
rays, and a shadow ray cannot pick one (the backward estimator is refused; "auto" runs forward).

Parameter row: P_POS position, P_AXIS the file's +z, P_T its +x, P_B its +y, P_FLUX the flux (lm). The rays share
the area lights' flat tables: `tri` holds each ray's world start point and unit direction (columns 0–5) and
`tri_cdf` their cumulative flux, found through `a_off` (first ray, count).
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass

import numpy as np

from tracer.jit import njit
from tracer.optics import files
from tracer.optics.fields import BodyField, fields
from tracer.optics.frames import find_in_cdf
from tracer.optics.lights import tm25
from tracer.optics.lights.base import (
    DELTA_DIRECTION,
    DELTA_POSITION,
    FLUX_LM,
    P_AXIS,
    P_B,
    P_FLUX,
    P_POS,
    P_T,
    LightError,
    Packing,
    check_fields,
    field_value,
    vector_field,
)

NAME = "rayfile"
MAX_BYTES = 10_000_000
FIELDS = fields(
    BodyField("position", "point", "Where the file's origin sits [x, y, z], m."),
    BodyField("data", "text", "The ray file's text: one ray per line, `x y z l m n flux` (start point in `units`, "
              "direction cosines, flux in lm); `#` comments. Or `file`.", required=False, max_length=MAX_BYTES),
    BodyField("file", "text", "An uploaded ray file's id (POST /optical-files: 64 hex digits), text columns or "
              "binary ANSI/IES TM-25. Or `data`.", required=False, max_length=64),
    BodyField("format", "choice", "What `file` holds: `text` or `tm25`; default: TM-25 where the file begins "
              "with `TM25`, else text.", required=False, choices=("text", "tm25")),
    BodyField("units", "choice", "Unit of the start points: `mm` (default) or `m`.", required=False,
              choices=("mm", "m")),
    BodyField("direction", "direction", "Where the file's +z axis points (dimensionless); default +z.",
              required=False),
    BodyField("c0", "direction", "The file's +x axis (its part across `direction`); default +x.", required=False),
    FLUX_LM)
EXAMPLE = {"type": "rayfile", "name": "LED near field", "position": [0.0, 0.0, 0.01], "units": "mm",
           "data": "# x y z l m n flux\n0 0 0 0 0 1 0.5\n0.1 0 0 0.6 0 0.8 0.5\n"}
EFFECTS = ()
FLAGS = DELTA_POSITION | DELTA_DIRECTION
WHY_NOT_CONNECTABLE = "a 'rayfile' light is a set of exact rays, which a shadow ray cannot pick"


def parse_rays(text, where: str, max_chars: int = MAX_BYTES, name: str = "data") -> np.ndarray:
    """The rays of a ray file's text as an (n, 7) float64 array [x, y, z, l, m, n, flux], directions made unit;
    `LightError` naming the light, the field and the line."""
    if not isinstance(text, str) or not text.strip():
        raise LightError(f"{where}: '{name}' must be the ray file's text (one ray per line: x y z l m n flux)")
    if len(text) > max_chars:
        raise LightError(f"{where}: '{name}' is {len(text)} characters, more than {max_chars}")
    try:
        rays = np.loadtxt(io.StringIO(text), comments="#", dtype=np.float64, ndmin=2)
    except ValueError as exc:
        raise LightError(f"{where}: '{name}' is not a ray file of 7 numbers per line (x y z l m n flux): "
                         f"{str(exc)[:200]}") from None
    if rays.shape[1] != 7 or len(rays) == 0:
        raise LightError(f"{where}: '{name}' must hold 7 numbers per line (x y z l m n flux), got {rays.shape[1]}")
    if not np.all(np.isfinite(rays)):
        k = int(np.argmax(~np.all(np.isfinite(rays), axis=1)))
        raise LightError(f"{where}: '{name}' ray {k} is not finite")
    norm = np.linalg.norm(rays[:, 3:6], axis=1)
    if np.any(norm == 0):
        raise LightError(f"{where}: '{name}' ray {int(np.argmax(norm == 0))} has a zero direction")
    if np.any(rays[:, 6] < 0):
        raise LightError(f"{where}: '{name}' ray {int(np.argmax(rays[:, 6] < 0))} has a negative flux")
    if not rays[:, 6].sum() > 0:
        raise LightError(f"{where}: '{name}' carries no flux (every ray's flux is 0)")
    rays[:, 3:6] /= norm[:, None]
    return rays


def _format(body: dict, path, where: str) -> str:
    fmt = body.get("format")
    if fmt is None:
        with open(path, "rb") as fh:
            fmt = "tm25" if fh.read(4) == tm25.MAGIC else "text"
    if fmt not in ("text", "tm25"):
        raise LightError(f"{where}: 'format' must be 'text' or 'tm25', got {fmt!r}"[:200])
    return str(fmt)


def _file(body: dict, where: str) -> tuple[str, object]:
    """(format, parsed file) of the body's `file`: a `tm25.RaySet`, or the text file's rays (n, 7) in its units."""
    try:
        path = files.path_of(body.get("file"), where)
    except files.OpticalFileError as exc:
        raise LightError(str(exc)) from None
    fmt = _format(body, path, where)
    if fmt == "tm25":
        return fmt, files.cached(body["file"], "tm25", lambda: tm25.read(path, where))

    def text():
        if path.stat().st_size > 50 * MAX_BYTES:
            raise LightError(f"{where}: the text ray file is {path.stat().st_size} bytes, more than "
                             f"{50 * MAX_BYTES}: upload it as TM-25")
        rays = parse_rays(path.read_text(encoding="utf-8", errors="replace"), where, MAX_BYTES * 50, "file")
        rays.setflags(write=False)
        return rays
    return fmt, files.cached(body["file"], "text", text)


def resolve(body: dict, where: str) -> dict:
    """The body with what a TM-25 `file` says filled in where the body is silent (`dispatch.light_spec` calls it
    before reading the spectrum): its spectrum, and its radiant total as ``flux_w`` (watts become lumens through
    the spectrum's efficacy) or its luminous total as ``flux_lm``."""
    if body.get("file") is None or body.get("data") is not None:
        return body
    fmt, parsed = _file(body, where)
    if fmt != "tm25":
        return body
    assert isinstance(parsed, tm25.RaySet)
    out = dict(body)
    if out.get("spectrum") is None and parsed.spectrum is not None:
        out["spectrum"] = parsed.spectrum
    if out.get("flux_lm") is None and out.get("flux_w") is None:
        out["flux_w" if parsed.unit == "W" else "flux_lm"] = parsed.total
    return out


def _frame(body: dict, where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    z = vector_field(body, "direction", where, unit=True) if "direction" in body else np.array([0.0, 0.0, 1.0])
    c0 = vector_field(body, "c0", where, unit=True) if "c0" in body else np.array([1.0, 0.0, 0.0])
    x = c0 - z * float(c0 @ z)
    if np.linalg.norm(x) < 1e-9:
        if "c0" in body:
            raise LightError(f"{where}: 'c0' must not be parallel to 'direction'")
        x = np.array([0.0, 1.0, 0.0]) - z * z[1]
    x = x / np.linalg.norm(x)
    return z, x, np.cross(z, x)


@dataclass(frozen=True, eq=False)
class Spec:
    """position (3,) m; the file's axes in the world (z, x, y); rays (n, 7) in the file's frame, start points in
    m; flux (lm)."""

    position: np.ndarray
    z: np.ndarray
    x: np.ndarray
    y: np.ndarray
    rays: np.ndarray
    flux: float

    @classmethod
    def from_body(cls, body: dict, where: str) -> Spec:
        check_fields(body, where, NAME, FIELDS)
        position = vector_field(body, "position", where)
        z, x, y = _frame(body, where)
        units = body.get("units", "mm")
        if units not in ("mm", "m"):
            raise LightError(f"{where}: 'units' must be 'mm' or 'm', got {units!r}"[:200])
        if (body.get("data") is None) == (body.get("file") is None):
            raise LightError(f"{where}: give the rays as 'data' (the file's text) or as 'file' (an uploaded file's "
                             f"id), exactly one")
        if body.get("data") is not None:
            if body.get("format") not in (None, "text"):
                raise LightError(f"{where}: 'format' is for a 'file'; 'data' is text")
            rays = parse_rays(body.get("data"), where)
            if units == "mm":
                rays[:, :3] *= 1e-3
        else:
            fmt, parsed = _file(body, where)
            if fmt == "tm25":
                assert isinstance(parsed, tm25.RaySet)
                rays = parsed.rays                       # read-only, shared with the cache: m already
            else:
                assert isinstance(parsed, np.ndarray)
                rays = parsed * np.array([1e-3 if units == "mm" else 1.0] * 3 + [1.0] * 4)
        flux = float(rays[:, 6].sum()) if body.get("flux_lm") is None else field_value(body, FLUX_LM, where)
        if not math.isfinite(flux) or not flux > 0:
            raise LightError(f"{where}: 'flux_lm' must be > 0")
        return cls(position, z, x, y, rays, flux)


def pack(spec: Spec, j: int, out: Packing, where: str) -> float:
    """Row j and the light's rays in world space (in `tri` / `tri_cdf`); returns the flux (lm)."""
    row = out.par[j]
    row[P_POS:P_POS + 3] = spec.position
    row[P_AXIS:P_AXIS + 3], row[P_T:P_T + 3], row[P_B:P_B + 3] = spec.z, spec.x, spec.y
    row[P_FLUX] = spec.flux
    r = spec.rays
    frame = np.column_stack([spec.x, spec.y, spec.z])      # file (x, y, z) -> world
    table = np.zeros((len(r), 9))
    table[:, 0:3] = spec.position + r[:, 0:3] @ frame.T
    table[:, 3:6] = r[:, 3:6] @ frame.T
    cdf = np.cumsum(r[:, 6])
    out.a_off[j] = out.used("tri"), len(r)
    out.parts["tri"].append(table)
    out.parts["tri_n"].append(np.zeros((len(r), 3)))   # the tables stay row-aligned with `tri`
    out.parts["tri_cdf"].append(cdf / cdf[-1])
    return spec.flux


@njit(cache=True, _nrt=False)
def sample(L, j, u0, u1, u2, u3, u4):
    """A ray in proportion to its flux (u0), as it is in the file (see base)."""
    first, count = L.a_off[j, 0], L.a_off[j, 1]
    k = first + find_in_cdf(L.tri_cdf, first, count, u0)
    t = L.tri[k]
    return t[0], t[1], t[2], t[3], t[4], t[5], 1.0, False, 0.0, 0.0, 0.0


@njit(cache=True, _nrt=False)
def connect(L, j, x, y, z, nx, ny, nz, u1, u2, u3):
    """Not connectable: nothing arrives by a shadow ray."""
    return 0.0, 0.0, 0.0, 1.0, 1.0
