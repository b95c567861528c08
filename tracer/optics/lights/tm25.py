"""ANSI/IES TM-25 ray files (TM-25-13; TM-25-20 keeps its layout): read, streamed, into the ray light's table.

TM-25 is the IES's vendor-neutral binary format for the near field of a light source, which LED makers publish
(ams OSRAM, Lumileds, Nichia…) next to their own formats. The standard text is sold by the IES; the layout below
is the one the public-domain reference implementation by J. Muschaweck reads and writes (github.com/
JuliusMuschaweck/TM25RaySetTools, ``TM25Library/TM25_impl.h``: ``ReadHeader``, ``WriteHeader``; its field names
carry the standard's section numbers), cross-checked against real ams OSRAM files by holg/tm25ray
(``docs/format.md``). Little-endian throughout; every ray value is a float32.

======  =============  ================================================================================
offset  type           field (TM-25-13 section)
======  =============  ================================================================================
0       4 × char       ``TM25`` (4.7.1.1)
4       int32          version: 2013 (4.7.1.2); 2020 is read the same
8       int32          creation method, 0 simulation / 1 measurement (4.7.1.3; not used)
12      float32        total luminous flux Φv, lm; NaN or 0 where unknown (4.7.1.4)
16      float32        total radiant flux Φe, W; NaN or 0 where unknown (4.7.1.5)
20      uint64         number of rays (4.7.1.6)
28      28 × char      creation date (4.7.1.7); then int32 ray start position (4.7.1.8)
60      int32          spectral data: 0 none, 1 one wavelength, 2 a wavelength per ray, 3 one spectral table,
                       4 a table index per ray (4.7.1.9)
64      3 × float32    the single wavelength, the smallest and the largest wavelength, nm (4.7.1.10–12)
76      3 × int32      number of spectral tables, of additional ray items, size of the additional text (bytes)
88      168 bytes      reserved
256     8 × int32      known-data flags, each 0 or 1: position, direction (both 1), radiant flux, wavelength,
                       luminous flux, Stokes, tristimulus, spectrum index (4.7.2)
288     9 × 4000       description texts, UTF-32 (4.7.3: source, manufacturer, …)
36288   tables         per spectral table: int32 count n, n × (float32 nm, float32 weight); the tables'
                       bytes padded with zeros to a multiple of 32 (4.7.4)
…       512 × items    names of the additional ray items, UTF-32 (4.7.5); then the additional text (4.7.6)
…       rays           n × k float32: x y z (mm), kx ky kz, then in this order those the flags name:
                       radiant flux (W), wavelength (nm), luminous flux (lm), S1 S2 S3 and the polarization
                       ellipse's axis (3), tristimulus X Z, spectrum index (1-based), the additional items
======  =============  ================================================================================

What the ray light takes (`tracer.optics.lights.rayfile`): start points (mm → m), directions (made unit), and as
each ray's flux the luminous column where the file has one, else the radiant one. Flux is normalised as the file
says: the header's total (Φv in lm where given and > 0, else Φe in W) is the light's, the rays share it in
proportion to their column; a header without a total takes the column's sum. A radiant file's watts become lumens
through its spectrum's efficacy (lm = W × K(S), as ``flux_w`` does). The spectrum: a single wavelength is a
monochromatic light; one table is the light's spectrum; per-ray wavelengths and per-ray table indices become the
flux-weighted mixture on the tracer's grid (1 nm bins, 360–830 nm; radiant flux outside it is left out and
counted). A photon then draws its wavelength from that spectrum, not from its own ray: where colour varies over
the beam (a phosphor LED's yellow rim) the spectrum is right in total but not ray by ray. In a scene that is not
spectral only the lumens count. Stokes, tristimulus and additional items are read past, not used.

Large files are streamed: the header is read, the file's size checked against it, and the rays copied from a
memory map in chunks of `CHUNK` straight into the (n, 7) float64 table the light keeps; the file is never held as
bytes. `write` writes a file (for tests and for converting a text ray file).
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tracer.optics import spectra
from tracer.optics.lights.base import LightError

MAGIC = b"TM25"
VERSIONS = (2013, 2020)
HEADER_BYTES = 256
TEXT_BYTES = 9 * 4000
FIXED = HEADER_BYTES + 32 + TEXT_BYTES          # 36288: where the spectral tables begin
NAME_BYTES = 512                                # one additional item's name
CHUNK = 1 << 20                                 # rays copied per step
MAX_TABLE = 100_000                             # samples in one spectral table
FLAGS = ("position", "direction", "radiant flux", "wavelength", "luminous flux", "Stokes", "tristimulus",
         "spectrum index")


@dataclass(frozen=True)
class Header:
    """What the ray light needs from a TM-25 header."""

    version: int
    phi_v: float                   # lm, NaN where unknown
    phi_e: float                   # W, NaN where unknown
    n_rays: int
    spectral: int                  # 0..4 (module docstring)
    single_nm: float
    flags: tuple[int, ...]         # FLAGS
    tables: tuple[tuple[np.ndarray, np.ndarray], ...]   # (nm, weight) each
    n_items: int                   # float32 per ray
    ray_offset: int                # bytes
    name: str

    def column(self, flag: str) -> int:
        """The ray column of an item a flag names (−1 where absent)."""
        cols = {"radiant flux": 1, "wavelength": 1, "luminous flux": 1, "Stokes": 6, "tristimulus": 2,
                "spectrum index": 1}
        k = 6
        for f in FLAGS[2:]:
            if f == flag:
                return k if self.flags[FLAGS.index(f)] else -1
            k += cols[f] * self.flags[FLAGS.index(f)]
        raise KeyError(flag)


def _utf32(raw: bytes) -> str:
    text = raw.decode("utf-32-le", errors="replace")
    return text.split("\0", 1)[0]


def read_header(path: Path, where: str) -> Header:
    """The header of the TM-25 file at `path`; `LightError` naming `where` and what is wrong."""
    size = path.stat().st_size
    with open(path, "rb") as fh:
        head = fh.read(FIXED)
        if len(head) < 4 or head[:4] != MAGIC:
            raise LightError(f"{where}: not a TM-25 ray file: it must begin with 'TM25', it begins with "
                             f"{head[:4]!r}")
        if len(head) < FIXED:
            raise LightError(f"{where}: the TM-25 file is truncated: its header is {FIXED} bytes, the file has "
                             f"{size}")
        version, _method, phi_v, phi_e, n_rays = struct.unpack_from("<iiffQ", head, 4)
        if version not in VERSIONS:
            raise LightError(f"{where}: TM-25 version {version} is not one this reader knows ({VERSIONS})")
        (spectral, single_nm, _lo, _hi, n_tables, n_addtl, text_bytes) = struct.unpack_from("<ifffiii", head, 60)
        flags = struct.unpack_from("<8i", head, HEADER_BYTES)
        for f, v in zip(FLAGS, flags, strict=True):
            if v not in (0, 1):
                raise LightError(f"{where}: the TM-25 {f} flag must be 0 or 1, it is {v}")
        if not (flags[0] and flags[1]):
            raise LightError(f"{where}: a TM-25 file's position and direction flags must be 1, they are "
                             f"{flags[0]} and {flags[1]}")
        if not (flags[2] or flags[4]):
            raise LightError(f"{where}: the TM-25 file has neither a radiant nor a luminous flux column (flags)")
        if spectral not in range(5):
            raise LightError(f"{where}: the TM-25 spectral data identifier must be 0 to 4, it is {spectral}")
        if spectral == 1 and not single_nm > 0:
            raise LightError(f"{where}: the TM-25 file says one wavelength (identifier 1) but gives {single_nm} nm")
        if spectral == 2 and not flags[3]:
            raise LightError(f"{where}: the TM-25 file says a wavelength per ray (identifier 2) but has no "
                             f"wavelength column")
        if (spectral == 4) != bool(flags[7]):
            raise LightError(f"{where}: the TM-25 spectrum index flag ({flags[7]}) must be set exactly when the "
                             f"spectral identifier is 4 (it is {spectral})")
        if spectral in (3, 4) and n_tables <= 0:
            raise LightError(f"{where}: the TM-25 spectral identifier {spectral} needs spectral tables, the "
                             f"header counts {n_tables}")
        if n_tables < 0 or n_addtl < 0 or text_bytes < 0 or n_tables > 10_000 or n_addtl > 10_000:
            raise LightError(f"{where}: the TM-25 header's counts are wrong: {n_tables} spectral tables, "
                             f"{n_addtl} additional items, {text_bytes} bytes of text")
        tables = []
        nbytes = 0
        for t in range(n_tables):
            raw = fh.read(4)
            if len(raw) < 4:
                raise LightError(f"{where}: the TM-25 file is truncated in spectral table {t + 1}")
            (m,) = struct.unpack("<i", raw)
            if not 0 < m <= MAX_TABLE:
                raise LightError(f"{where}: TM-25 spectral table {t + 1} counts {m} samples (1 to {MAX_TABLE})")
            pairs = np.frombuffer(fh.read(8 * m), dtype="<f4")
            if len(pairs) < 2 * m:
                raise LightError(f"{where}: the TM-25 file is truncated in spectral table {t + 1}")
            nm, w = pairs[0::2].astype(np.float64), pairs[1::2].astype(np.float64)
            if not (np.all(nm > 0) and np.all(np.diff(nm) > 0) and np.all(w >= 0)):
                raise LightError(f"{where}: TM-25 spectral table {t + 1} needs increasing wavelengths > 0 and "
                                 f"weights ≥ 0")
            tables.append((nm, w))
            nbytes += 4 + 8 * m
        offset = FIXED + nbytes + (-nbytes) % 32 + NAME_BYTES * n_addtl + text_bytes
    n_items = 6 + flags[2] + flags[3] + flags[4] + 6 * flags[5] + 2 * flags[6] + flags[7] + n_addtl
    if n_rays <= 0:
        raise LightError(f"{where}: the TM-25 file holds no rays (its header counts {n_rays})")
    expected = offset + n_rays * n_items * 4
    if size != expected:
        raise LightError(f"{where}: the TM-25 file's size does not match its header: {n_rays} rays of "
                         f"{n_items} values after a {offset}-byte header make {expected} bytes, the file has "
                         f"{size}" + (" (truncated)" if size < expected else ""))
    name = _utf32(head[HEADER_BYTES + 32:HEADER_BYTES + 32 + 4000])
    return Header(version, phi_v, phi_e, n_rays, spectral, single_nm, tuple(flags), tuple(tables), n_items,
                  offset, name)


@dataclass(frozen=True)
class RaySet:
    """A TM-25 file read for the ray light: rays (n, 7) float64 [x y z (m), unit direction, flux (relative)]
    (read-only), the light's total flux and its unit ("lm" or "W"), and its spectrum body (None: none given)."""

    rays: np.ndarray
    total: float
    unit: str
    spectrum: dict | None
    outside_nm: float           # fraction of the radiant flux at wavelengths outside the tracer's grid
    header: Header


def _grid_histogram(nm: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Flux-weighted histogram of wavelengths on the tracer's grid (bin i: [λ_i − ½, λ_i + ½) nm)."""
    k = np.floor(nm - spectra.LAMBDA_MIN + 0.5).astype(np.int64)
    inside = (k >= 0) & (k < spectra.GRID_N)
    return np.bincount(k[inside], weights=w[inside], minlength=spectra.GRID_N)


def _table_on_grid(nm: np.ndarray, w: np.ndarray) -> np.ndarray:
    return np.interp(spectra.GRID_NM, nm, w, left=0.0, right=0.0)


def read(path: Path, where: str) -> RaySet:
    """The rays, flux and spectrum of the TM-25 file at `path` (module docstring); `LightError` naming `where`,
    what is wrong and, for a bad ray, its index."""
    h = read_header(path, where)
    c_flux = h.column("luminous flux") if h.flags[4] else h.column("radiant flux")
    c_rad = h.column("radiant flux")
    c_lam = h.column("wavelength") if h.spectral == 2 else -1
    c_idx = h.column("spectrum index") if h.spectral == 4 else -1
    n = h.n_rays
    mm = np.memmap(path, dtype="<f4", mode="r", offset=h.ray_offset, shape=(n, h.n_items))
    rays = np.empty((n, 7))
    power = np.zeros(spectra.GRID_N)
    table_w = np.zeros(len(h.tables))
    rad_total = rad_outside = 0.0
    for s in range(0, n, CHUNK):
        c = np.asarray(mm[s:s + CHUNK], dtype=np.float64)
        e = s + len(c)
        block = rays[s:e]
        block[:, :6] = c[:, :6]
        block[:, 6] = c[:, c_flux]
        bad = ~np.all(np.isfinite(block), axis=1)
        if bad.any():
            raise LightError(f"{where}: TM-25 ray {s + int(np.argmax(bad))} is not finite")
        norm = np.linalg.norm(block[:, 3:6], axis=1)
        if np.any(norm == 0):
            raise LightError(f"{where}: TM-25 ray {s + int(np.argmax(norm == 0))} has a zero direction")
        if np.any(block[:, 6] < 0):
            raise LightError(f"{where}: TM-25 ray {s + int(np.argmax(block[:, 6] < 0))} has a negative flux")
        block[:, 3:6] /= norm[:, None]
        block[:, :3] *= 1e-3
        if c_lam >= 0:
            lam, w = c[:, c_lam], c[:, c_rad]
            if not np.all(np.isfinite(lam)):
                raise LightError(f"{where}: TM-25 ray {s + int(np.argmax(~np.isfinite(lam)))}'s wavelength is "
                                 f"not finite")
            hist = _grid_histogram(lam, w)
            power += hist
            rad_total += float(w.sum())
            rad_outside += float(w.sum() - hist.sum())
        if c_idx >= 0:
            idx = np.rint(c[:, c_idx]).astype(np.int64)
            if np.any((idx < 1) | (idx > len(h.tables))):
                k = int(np.argmax((idx < 1) | (idx > len(h.tables))))
                raise LightError(f"{where}: TM-25 ray {s + k}'s spectrum index {c[k, c_idx]:g} names no table "
                                 f"(1 to {len(h.tables)})")
            table_w += np.bincount(idx - 1, weights=c[:, c_rad], minlength=len(h.tables))
    del mm
    column_sum = float(rays[:, 6].sum())
    if not column_sum > 0:
        raise LightError(f"{where}: the TM-25 file carries no flux (every ray's flux is 0)")
    spectrum: dict | None = None
    if h.spectral == 1:
        spectrum = {"type": "monochromatic", "nm": float(h.single_nm)}
    elif h.spectral in (2, 3, 4):
        if h.spectral == 3:
            power = _table_on_grid(*h.tables[0])
        elif h.spectral == 4:
            for (nm, w), tw in zip(h.tables, table_w, strict=True):
                g = _table_on_grid(nm, w)
                if tw > 0 and g.sum() > 0:
                    power += tw * g / np.trapezoid(w, nm)
        if not power.sum() > 0:
            raise LightError(f"{where}: the TM-25 file's spectrum has no power in {spectra.LAMBDA_MIN:g}–"
                             f"{spectra.LAMBDA_MAX:g} nm, the range the tracer simulates")
        spectrum = {"type": "table", "nm": spectra.GRID_NM.tolist(), "values": (power / power.max()).tolist()}
    if h.flags[4]:
        unit, total = "lm", (float(h.phi_v) if math.isfinite(h.phi_v) and h.phi_v > 0 else column_sum)
    else:
        unit, total = "W", (float(h.phi_e) if math.isfinite(h.phi_e) and h.phi_e > 0 else column_sum)
    outside = rad_outside / rad_total if rad_total > 0 else 0.0
    if unit == "W" and outside > 0:
        total *= 1.0 - outside        # the watts the tracer can carry
    rays.setflags(write=False)
    return RaySet(rays, total, unit, spectrum, outside, h)


def write(path, rays, *, flux: str = "luminous", total: float | None = None, wavelength_nm=None,
          single_nm: float | None = None, table=None, name: str = "LumenLink test emitter") -> None:
    """Write a TM-25-13 file (for tests and conversions).

    rays : (n, 7) [x y z (mm), kx ky kz, flux] (flux in lm for ``flux="luminous"``, W for ``"radiant"``).
    total : the header's total flux (default: the column's sum); NaN writes "unknown".
    wavelength_nm : (n,) per-ray wavelengths (identifier 2; needs ``flux="radiant"``).
    single_nm : one wavelength (identifier 1). table : (nm, weights), one spectral table (identifier 3).
    """
    rays = np.asarray(rays, dtype=np.float64)
    n = len(rays)
    lum = flux == "luminous"
    spectral = 2 if wavelength_nm is not None else 1 if single_nm is not None else 3 if table is not None else 0
    tot = float(rays[:, 6].sum()) if total is None else float(total)
    head = bytearray(HEADER_BYTES)
    head[:4] = MAGIC
    struct.pack_into("<iiffQ", head, 4, 2013, 0, tot if lum else math.nan, math.nan if lum else tot, n)
    head[28:28 + 19] = b"2026-11-27 00:00:00"
    lo, hi = (float(np.min(wavelength_nm)), float(np.max(wavelength_nm))) if wavelength_nm is not None else (
        (float(table[0][0]), float(table[0][-1])) if table is not None else (math.nan, math.nan))
    struct.pack_into("<iifffiii", head, 56, 0, spectral, single_nm if single_nm is not None else math.nan, lo, hi,
                     1 if table is not None else 0, 0, 0)
    flags = [1, 1, 0 if lum else 1, 1 if spectral == 2 else 0, 1 if lum else 0, 0, 0, 0]
    text = bytearray(TEXT_BYTES)
    enc = name.encode("utf-32-le")[:4000]
    text[:len(enc)] = enc
    tables = b""
    if table is not None:
        nm, w = (np.asarray(x, dtype="<f4") for x in table)
        tables = struct.pack("<i", len(nm)) + np.column_stack([nm, w]).astype("<f4").tobytes()
        tables += bytes((-len(tables)) % 32)
    cols = [rays[:, :6], rays[:, 6:7]]
    if spectral == 2:
        cols.append(np.asarray(wavelength_nm, dtype=np.float64)[:, None])
    with open(path, "wb") as fh:
        fh.write(bytes(head) + struct.pack("<8i", *flags) + bytes(text) + tables)
        fh.write(np.hstack(cols).astype("<f4").tobytes())
