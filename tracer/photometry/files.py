"""Goniometric photometry: IES LM-63 and EULUMDAT (LDT) files → a type-C candela table.

Conventions (type C photometry, as both formats define it):

- γ (vertical angle) is measured from the nadir: γ = 0 points down, γ = 90° is horizontal, γ = 180°
  points up;
- C (horizontal angle) turns about the vertical axis: C = 0 along the luminaire's +x axis, C = 90°
  along +y.

A light placed in a scene keeps this frame in world coordinates (γ = 0 along world −z, C = 0
along world +x), see `tracer.optics.lights.goniometric`.

Whatever symmetry the file declares, `Photometry` holds the expanded table over C ∈ [0, 360]
(first and last column equal) and γ ∈ [0, 180] (rows beyond the measured range are zero), in
candelas, and the intensity between the samples is bilinear in (C, γ). `total_flux` integrates that
bilinear model exactly (∫∫ I sinγ dγ dC), so it is the flux the sampled source emits.

Scaling: IES candelas are multiplied by the candela multiplier and the ballast factor. EULUMDAT
values are cd per 1000 lm of lamp flux; they are multiplied by the first lamp set's flux / 1000 and
by the intensity conversion factor. Luminous-opening sizes are read but not used: every goniometric
source is a point source.

What a file states about its flux (`stated_lumens`): IES relative photometry states lamp lumens
(number of lamps × lumens per lamp); the luminaire emits that times its efficiency. Absolute IES
photometry (lumens per lamp = −1) states nothing in the numeric header; the `[_ABSOLUTELUMENS]`
keyword, where present, is used. EULUMDAT states lamp flux and the light output ratio LORL; the
luminaire flux is their product.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from tracer.errors import TracerError

__all__ = ["Photometry", "PhotometryError", "parse_photometry", "parse_ies", "parse_ldt"]

_GAP_DEG = 1e-6  # width of the step from the last measured γ to zero (a step, not a ramp)


class PhotometryError(TracerError):
    """A photometry file that cannot be read; the message says where and why."""


@dataclass(frozen=True)
class Photometry:
    """A type-C luminous intensity distribution.

    Attributes
    ----------
    c_deg : (nc,) float64
        Horizontal angles, increasing, from 0 to 360 inclusive.
    gamma_deg : (ng,) float64
        Vertical angles, increasing, from 0 to 180 inclusive.
    candela : (nc, ng) float64
        Intensity in cd at each (C, γ); row 0 equals row nc−1.
    stated_lumens : float or None
        The luminaire flux the file states (see the module docstring), lm.
    lamp_lumens : float or None
        The lamp flux the file states, lm, where it states one.
    fmt : str
        "ies" or "ldt".
    meta : dict
        Header values kept for reports (manufacturer, catalogue number, symmetry).
    """

    c_deg: np.ndarray
    gamma_deg: np.ndarray
    candela: np.ndarray
    stated_lumens: float | None
    lamp_lumens: float | None
    fmt: str
    meta: dict = field(default_factory=dict)

    def intensity(self, c_deg, gamma_deg) -> np.ndarray:
        """Bilinear intensity in cd at horizontal angles `c_deg` and vertical angles `gamma_deg` (broadcast).

        C is taken modulo 360; γ is clipped to [0, 180].
        """
        c = np.mod(np.asarray(c_deg, dtype=np.float64), 360.0)
        g = np.clip(np.asarray(gamma_deg, dtype=np.float64), 0.0, 180.0)
        c, g = np.broadcast_arrays(c, g)
        ic = np.clip(np.searchsorted(self.c_deg, c, side="right") - 1, 0, len(self.c_deg) - 2)
        ig = np.clip(np.searchsorted(self.gamma_deg, g, side="right") - 1, 0, len(self.gamma_deg) - 2)
        c0, c1 = self.c_deg[ic], self.c_deg[ic + 1]
        g0, g1 = self.gamma_deg[ig], self.gamma_deg[ig + 1]
        tc = np.where(c1 > c0, (c - c0) / np.where(c1 > c0, c1 - c0, 1.0), 0.0)
        tg = np.where(g1 > g0, (g - g0) / np.where(g1 > g0, g1 - g0, 1.0), 0.0)
        t = self.candela
        return ((1 - tc) * (1 - tg) * t[ic, ig] + tc * (1 - tg) * t[ic + 1, ig]
                + (1 - tc) * tg * t[ic, ig + 1] + tc * tg * t[ic + 1, ig + 1])

    def cell_flux(self) -> np.ndarray:
        """Flux in lm of each (C, γ) cell of the bilinear model, shape (nc−1, ng−1); sums to `total_flux`."""
        g = np.radians(self.gamma_deg)
        g0, g1 = g[:-1], g[1:]
        dg = g1 - g0
        cos_int = np.cos(g0) - np.cos(g1)                      # ∫ sinγ dγ over the interval
        x_int = (np.sin(g1) - g1 * np.cos(g1)) - (np.sin(g0) - g0 * np.cos(g0))   # ∫ γ sinγ dγ
        w1 = np.where(dg > 0, (x_int - g0 * cos_int) / np.where(dg > 0, dg, 1.0), 0.0)  # ∫ t sinγ, t = (γ-γ0)/Δγ
        w0 = cos_int - w1
        # average over C of a column pair is exact for a function linear in C
        col = 0.5 * (self.candela[:-1] + self.candela[1:])          # (nc-1, ng)
        dc = np.radians(np.diff(self.c_deg))[:, None]
        return dc * (col[:, :-1] * w0[None, :] + col[:, 1:] * w1[None, :])

    def total_flux(self) -> float:
        """Total luminous flux of the distribution in lm (exact integral of the bilinear model)."""
        return float(self.cell_flux().sum())

    def max_candela(self) -> float:
        """The largest intensity in the table, cd."""
        return float(self.candela.max())


# ---------------------------------------------------------------------------------------------------------------------
# shared helpers


def _full_c(c_list: np.ndarray, table: np.ndarray, symmetry: str, where: str) -> tuple[np.ndarray, np.ndarray]:
    """Columns over C ∈ [0, 360] from the measured ones and a symmetry; returns (c (nc,), table (nc, ng))."""
    cols: dict[float, np.ndarray] = {}

    def put(c: float, row: np.ndarray) -> None:
        c = round(c % 360.0, 9)
        cols.setdefault(c, row)

    if symmetry == "axial":
        cols = {0.0: table[0], 360.0: table[0]}
    elif symmetry == "none":
        for c, row in zip(c_list, table, strict=True):
            put(float(c), row)
    elif symmetry == "bilateral_0_180":      # I(C) = I(360 − C)
        for c, row in zip(c_list, table, strict=True):
            put(float(c), row)
            put(360.0 - float(c), row)
    elif symmetry == "bilateral_90_270":     # I(C) = I(180 − C)
        for c, row in zip(c_list, table, strict=True):
            put(float(c), row)
            put(180.0 - float(c), row)
    elif symmetry == "quadrant":             # both planes
        for c, row in zip(c_list, table, strict=True):
            for cc in (float(c), 180.0 - float(c), 180.0 + float(c), 360.0 - float(c)):
                put(cc, row)
    else:  # pragma: no cover - internal
        raise AssertionError(symmetry)
    if 0.0 not in cols:
        raise PhotometryError(f"{where}: the horizontal angles do not cover C = 0 (got {list(c_list)})")
    cols[360.0] = cols[0.0]
    cs = np.array(sorted(cols), dtype=np.float64)
    return cs, np.array([cols[c] for c in cs], dtype=np.float64)


def _full_gamma(gamma: np.ndarray, table: np.ndarray, where: str) -> tuple[np.ndarray, np.ndarray]:
    """Rows over γ ∈ [0, 180]: zero outside the measured range, with a step of `_GAP_DEG` at its ends."""
    g = [float(x) for x in gamma]
    t = [table[:, i] for i in range(table.shape[1])]
    zero = np.zeros(table.shape[0])
    if g[0] > 0.0:
        g = [0.0, max(g[0] - _GAP_DEG, 0.0)] + g
        t = [zero, zero] + t
    if g[-1] < 180.0:
        g = g + [min(g[-1] + _GAP_DEG, 180.0), 180.0]
        t = t + [zero, zero]
    return np.array(g), np.stack(t, axis=1)


def _check_angles(values: np.ndarray, name: str, lo: float, hi: float, where: str) -> None:
    if not np.all(np.isfinite(values)):
        raise PhotometryError(f"{where}: {name} angles must be finite numbers")
    if len(values) > 1 and not np.all(np.diff(values) > 0):
        raise PhotometryError(f"{where}: {name} angles must be strictly increasing, got {values.tolist()}")
    if values.size and (values[0] < lo - 1e-9 or values[-1] > hi + 1e-9):
        raise PhotometryError(f"{where}: {name} angles must lie in [{lo:g}, {hi:g}] degrees, "
                              f"got {values[0]:g} .. {values[-1]:g}")


def _check_candela(table: np.ndarray, where: str) -> None:
    if not np.all(np.isfinite(table)):
        raise PhotometryError(f"{where}: candela values must be finite numbers")
    if np.any(table < 0):
        raise PhotometryError(f"{where}: negative candela value {table.min():g}")
    if not np.any(table > 0):
        raise PhotometryError(f"{where}: every candela value is zero: the luminaire emits nothing")


# ---------------------------------------------------------------------------------------------------------------------
# IES LM-63


_NUM = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?$")


@dataclass(frozen=True)
class _IesHeader:
    """The numeric header after ``TILT=NONE``, as the file states it (counts checked to be integers)."""

    n_lamps: float
    lumens_per_lamp: float          # lm per lamp, or −1 for absolute photometry
    multiplier: float               # candela multiplier
    n_vert: int
    n_horiz: int
    ptype: float                    # photometric type: 1 = C, 2 = B, 3 = A
    units: float                    # 1 = feet, 2 = metres
    opening: tuple[float, float, float]   # luminous opening width, length, height, in `units`
    ballast: float
    input_watts: float


class _IesTokens:
    """The values after the TILT line, taken one at a time so that an error names the line of the value."""

    def __init__(self, lines: list[str], start: int) -> None:
        self._tokens = [(tok, j + 1) for j in range(start, len(lines)) for tok in lines[j].replace(",", " ").split()]
        self._pos = 0

    def take(self, name: str) -> float:
        """The next value as a number; `name` says in the error what was expected."""
        if self._pos >= len(self._tokens):
            raise PhotometryError(f"IES: the file ends before {name}")
        tok, line_no = self._tokens[self._pos]
        self._pos += 1
        if not _NUM.match(tok):
            raise PhotometryError(f"IES line {line_no}: {name} must be a number, got {tok!r}")
        return float(tok)

    def left_over(self) -> tuple[str, int] | None:
        """The first value not taken and its 1-based line, or None when every value was taken."""
        return self._tokens[self._pos] if self._pos != len(self._tokens) else None


def _ies_tilt_and_keywords(lines: list[str]) -> tuple[int, dict[str, str]]:
    """The 0-based index of the ``TILT=NONE`` line and the ``[KEYWORD] value`` pairs above it (first one wins)."""
    tilt_at = None
    keywords: dict[str, str] = {}
    for i, line in enumerate(lines):
        s = line.strip()
        if s.upper().startswith("TILT"):
            tilt_at = i
            break
        m = re.match(r"\[([^\]]+)\]\s*(.*)", s)
        if m:
            keywords.setdefault(m.group(1).strip().upper(), m.group(2).strip())
    if tilt_at is None:
        raise PhotometryError("IES: no 'TILT=' line: not an IES LM-63 file")
    tilt = lines[tilt_at].strip().split("=", 1)
    tilt_value = tilt[1].strip().upper() if len(tilt) == 2 else ""
    if tilt_value != "NONE":
        raise PhotometryError(f"IES line {tilt_at + 1}: TILT={tilt_value or '?'} is not supported (only TILT=NONE)")
    return tilt_at, keywords


def _ies_read_header(tokens: _IesTokens) -> _IesHeader:
    """The thirteen numbers of the header, read in file order, then checked (type C photometry only)."""
    n_lamps = tokens.take("the number of lamps")
    lumens_per_lamp = tokens.take("the lumens per lamp")
    multiplier = tokens.take("the candela multiplier")
    n_vert = tokens.take("the number of vertical angles")
    n_horiz = tokens.take("the number of horizontal angles")
    ptype = tokens.take("the photometric type")
    units = tokens.take("the units type")
    width, length, height = tokens.take("the width"), tokens.take("the length"), tokens.take("the height")
    ballast = tokens.take("the ballast factor")
    tokens.take("the ballast-lamp factor / future use")
    input_watts = tokens.take("the input watts")
    for name, v in (("number of vertical angles", n_vert), ("number of horizontal angles", n_horiz)):
        if v != int(v) or v < 1 or v > 100000:
            raise PhotometryError(f"IES: the {name} must be a positive integer, got {v:g}")
    header = _IesHeader(n_lamps, lumens_per_lamp, multiplier, int(n_vert), int(n_horiz), ptype, units,
                        (width, length, height), ballast, input_watts)
    _ies_check_header(header)
    return header


def _ies_check_header(h: _IesHeader) -> None:
    """Reject what the parser does not support or what cannot scale the table: not type C, unknown units,
    non-positive multiplier, ballast factor, lamp count or lumens."""
    if int(h.ptype) != 1:
        kind = {2: "B", 3: "A"}.get(int(h.ptype), str(h.ptype))
        raise PhotometryError(f"IES: photometric type {kind} is not supported (only type C, photometric type 1)")
    if h.units not in (1, 2):
        raise PhotometryError(f"IES: units type must be 1 (feet) or 2 (metres), got {h.units:g}")
    if not (h.multiplier > 0 and math.isfinite(h.multiplier)):
        raise PhotometryError(f"IES: the candela multiplier must be > 0, got {h.multiplier:g}")
    if not (h.ballast > 0 and math.isfinite(h.ballast)):
        raise PhotometryError(f"IES: the ballast factor must be > 0, got {h.ballast:g}")
    if h.n_lamps <= 0:
        raise PhotometryError(f"IES: the number of lamps must be > 0, got {h.n_lamps:g}")
    if not (h.lumens_per_lamp == -1 or h.lumens_per_lamp > 0):
        raise PhotometryError(f"IES: the lumens per lamp must be > 0 or -1 (absolute photometry), "
                              f"got {h.lumens_per_lamp:g}")


def _ies_read_tables(tokens: _IesTokens, n_vert: int, n_horiz: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The angle lists and the candela table as stored: vertical (n_vert,) and horizontal (n_horiz,) angles in
    degrees, candelas (n_horiz, n_vert) before the multiplier; nothing may follow the table."""
    vert = np.array([tokens.take(f"vertical angle {k + 1}") for k in range(n_vert)])
    horiz = np.array([tokens.take(f"horizontal angle {k + 1}") for k in range(n_horiz)])
    cd = np.array([[tokens.take(f"candela value {k + 1} of horizontal angle {h + 1}") for k in range(n_vert)]
                   for h in range(n_horiz)])
    extra = tokens.left_over()
    if extra is not None:
        tok, line_no = extra
        raise PhotometryError(f"IES line {line_no}: unexpected value {tok!r} after the candela table "
                              f"({n_horiz}×{n_vert} values expected)")
    return vert, horiz, cd


def _ies_check_angles(vert: np.ndarray, horiz: np.ndarray) -> None:
    """Angles in degrees, increasing and in range, with the vertical span type C allows (0 or 90 to 90 or 180)."""
    _check_angles(vert, "vertical", 0.0, 180.0, "IES")
    _check_angles(horiz, "horizontal", 0.0, 360.0, "IES")
    if not (vert[0] in (0.0, 90.0) and vert[-1] in (90.0, 180.0)):
        raise PhotometryError(f"IES: type C vertical angles must start at 0 or 90 and end at 90 or 180, "
                              f"got {vert[0]:g} .. {vert[-1]:g}")


def _ies_symmetry(horiz: np.ndarray) -> str:
    """The symmetry (a `_full_c` name) that the span of the horizontal angles (degrees) declares."""
    first, last = horiz[0], horiz[-1]
    if len(horiz) == 1:
        if first != 0.0:
            raise PhotometryError(f"IES: a single horizontal angle must be 0, got {first:g}")
        return "axial"
    if first == 0.0 and last == 90.0:
        return "quadrant"
    if first == 0.0 and last == 180.0:
        return "bilateral_0_180"
    if first == 90.0 and last == 270.0:
        return "bilateral_90_270"
    if first == 0.0 and 180.0 < last <= 360.0:
        return "none"
    raise PhotometryError(f"IES: type C horizontal angles must run 0..0, 0..90, 0..180, 90..270 or 0..360, "
                          f"got {first:g} .. {last:g}")


def _ies_lumens(h: _IesHeader, keywords: dict[str, str]) -> tuple[float | None, float | None]:
    """(lamp lumens, stated lumens) in lm: lamps × lumens per lamp, or for absolute photometry no lamp flux and
    the ``[_ABSOLUTELUMENS]`` keyword's number where it has one."""
    lamp_lumens = h.n_lamps * h.lumens_per_lamp if h.lumens_per_lamp > 0 else None
    stated = lamp_lumens
    if stated is None and "_ABSOLUTELUMENS" in keywords:
        try:
            stated = float(keywords["_ABSOLUTELUMENS"].split()[0])
        except (ValueError, IndexError):
            stated = None
    return lamp_lumens, stated


def parse_ies(text: str) -> Photometry:
    """Parse an IES LM-63 file (1986, 1991, 1995, 2002 or 2019 revision), type C photometry only.

    Parameters
    ----------
    text : str
        The whole file.

    Raises
    ------
    PhotometryError
        (a ValueError) naming the line or field that is wrong: no ``TILT=`` line, ``TILT=<file>``
        or ``TILT=INCLUDE`` (tilt data is not supported), a non-numeric or missing value, type A or
        B photometry, angles out of range or not increasing, negative or all-zero candelas.
    """
    if not isinstance(text, str):
        raise PhotometryError(f"IES: expected the file text as str, got {type(text).__name__}")
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    tilt_at, keywords = _ies_tilt_and_keywords(lines)
    tokens = _IesTokens(lines, tilt_at + 1)
    header = _ies_read_header(tokens)
    vert, horiz, cd = _ies_read_tables(tokens, header.n_vert, header.n_horiz)
    where = "IES"
    _ies_check_angles(vert, horiz)
    cd = cd * header.multiplier * header.ballast
    _check_candela(cd, where)
    sym = _ies_symmetry(horiz)
    if sym == "none" and horiz[-1] == 360.0:
        horiz, cd = horiz[:-1], cd[:-1]   # C = 360 is C = 0 again; the expansion closes the circle
    c_full, t = _full_c(horiz, cd, sym, where)
    g_full, t = _full_gamma(vert, t, where)
    lamp_lumens, stated = _ies_lumens(header, keywords)
    metres = 0.3048 if header.units == 1 else 1.0
    meta = {"symmetry": sym, "manufacturer": keywords.get("MANUFAC"), "catalogue": keywords.get("LUMCAT"),
            "absolute": header.lumens_per_lamp == -1, "input_watts": header.input_watts,
            "opening_m": [x * metres for x in header.opening]}
    return Photometry(c_full, g_full, t, stated, lamp_lumens, "ies", meta)


# ---------------------------------------------------------------------------------------------------------------------
# EULUMDAT


def _ldt_line(lines: list[str], k: int, name: str) -> str:
    """Line `k` (1-based, as the format numbers its fields), stripped; `name` says in the error what was expected."""
    if k > len(lines):
        raise PhotometryError(f"LDT line {k}: the file ends before {name}")
    return lines[k - 1].strip()


def _ldt_num(lines: list[str], k: int, name: str) -> float:
    """Line `k` as a number (a decimal comma is read as a point)."""
    s = _ldt_line(lines, k, name).replace(",", ".")
    if not _NUM.match(s):
        raise PhotometryError(f"LDT line {k}: {name} must be a number, got {s!r}")
    return float(s)


def _ldt_int(lines: list[str], k: int, name: str, lo: int, hi: int) -> int:
    """Line `k` as an integer in [lo, hi]."""
    v = _ldt_num(lines, k, name)
    if v != int(v) or not lo <= v <= hi:
        raise PhotometryError(f"LDT line {k}: {name} must be an integer in [{lo}, {hi}], got {v:g}")
    return int(v)


def _ldt_lamp_sets(lines: list[str], n_sets: int) -> list[tuple[float, float]]:
    """(number of lamps, total lamp flux in lm) of each lamp set, from the per-set blocks after line 26."""
    lamp_sets = []
    for s in range(n_sets):
        n_l = _ldt_num(lines, 27 + s, f"the number of lamps of set {s + 1}")
        flux = _ldt_num(lines, 27 + 2 * n_sets + s, f"the total lamp flux of set {s + 1}")
        lamp_sets.append((n_l, flux))
    return lamp_sets


def _ldt_stored_planes(isym: int, mc: int) -> tuple[int, int]:
    """The slice [lo, hi) of the Mc C planes whose intensities the file stores under symmetry `isym`."""
    if isym == 0:
        return 0, mc
    if isym == 1:
        return 0, 1
    if isym == 2:
        return 0, mc // 2 + 1
    if isym == 3:
        return mc // 4, mc // 4 + mc // 2 + 1
    return 0, mc // 4 + 1


def _ldt_read_tables(lines: list[str], n_sets: int, isym: int, mc: int, ng: int,
                     n_planes: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The C angles (mc,) and γ angles (ng,) in degrees and the stored intensities (n_planes, ng) in cd/klm, which
    follow the lamp sets and the ten direct ratios; nothing may follow the intensities."""
    k = 27 + 6 * n_sets + 10          # past the lamp sets and the ten direct ratios
    c_angles = np.array([_ldt_num(lines, k + i, f"C angle {i + 1}") for i in range(mc)])
    k += mc
    g_angles = np.array([_ldt_num(lines, k + i, f"γ angle {i + 1}") for i in range(ng)])
    k += ng
    values = np.array([_ldt_num(lines, k + i, f"intensity value {i + 1}") for i in range(n_planes * ng)])
    k += n_planes * ng
    if k <= len(lines):
        raise PhotometryError(f"LDT line {k}: unexpected content after the {n_planes}×{ng} intensity table "
                              f"(Isym={isym}, Mc={mc}): {lines[k - 1].strip()!r}")
    return c_angles, g_angles, values.reshape(n_planes, ng)


def _ldt_check_angles(c_angles: np.ndarray, g_angles: np.ndarray, isym: int, mc: int, hi: int) -> None:
    """Angles in degrees, increasing and in range (C angles unused, so unchecked, for axial symmetry), and enough
    C planes for the symmetry's stored slice, which ends at `hi`."""
    _check_angles(g_angles, "γ", 0.0, 180.0, "LDT")
    if isym != 1:
        _check_angles(c_angles, "C", 0.0, 360.0, "LDT")
    if hi > mc and isym != 1:
        raise PhotometryError(f"LDT: Mc={mc} is too small for symmetry Isym={isym}")


def _ldt_check_scale(flux_lamps: float, n_sets: int, conv: float, lorl: float) -> None:
    """The factors that turn cd/klm into cd and give the luminaire flux: lamp flux (lm) and conversion factor
    positive, LORL in (0, 100] %."""
    if not (flux_lamps > 0 and math.isfinite(flux_lamps)):
        raise PhotometryError(f"LDT line {27 + 2 * n_sets}: the lamp flux must be > 0, got {flux_lamps:g}")
    if not (conv > 0 and math.isfinite(conv)):
        raise PhotometryError(f"LDT line 24: the intensity conversion factor must be > 0, got {conv:g}")
    if not (0 < lorl <= 100):
        raise PhotometryError(f"LDT line 23: the light output ratio LORL must be in (0, 100] %, got {lorl:g}")


def parse_ldt(text: str) -> Photometry:
    """Parse a EULUMDAT (.ldt) file.

    Parameters
    ----------
    text : str
        The whole file.

    Raises
    ------
    PhotometryError
        (a ValueError) naming the line (1-based, as the format numbers its fields) that is missing
        or not a number, an unknown symmetry indicator, angles out of range, or a table of the wrong
        size.
    """
    if not isinstance(text, str):
        raise PhotometryError(f"LDT: expected the file text as str, got {type(text).__name__}")
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    while lines and not lines[-1].strip():
        lines.pop()
    isym = _ldt_int(lines, 3, "the symmetry indicator Isym", 0, 4)
    mc = _ldt_int(lines, 4, "the number of C planes Mc", 1, 3600)
    ng = _ldt_int(lines, 6, "the number of intensities per plane Ng", 1, 18001)
    dff = _ldt_num(lines, 22, "the downward flux fraction DFF")
    lorl = _ldt_num(lines, 23, "the light output ratio LORL")
    conv = _ldt_num(lines, 24, "the intensity conversion factor")
    n_sets = _ldt_int(lines, 26, "the number of lamp sets n", 1, 100)
    lamp_sets = _ldt_lamp_sets(lines, n_sets)
    lo, hi = _ldt_stored_planes(isym, mc)
    c_angles, g_angles, values = _ldt_read_tables(lines, n_sets, isym, mc, ng, hi - lo)
    where = "LDT"
    _ldt_check_angles(c_angles, g_angles, isym, mc, hi)
    flux_lamps = lamp_sets[0][1]
    _ldt_check_scale(flux_lamps, n_sets, conv, lorl)
    table = values * conv * flux_lamps / 1000.0
    _check_candela(table, where)
    planes = c_angles[lo:hi] if isym != 1 else np.array([0.0])
    sym = {0: "none", 1: "axial", 2: "bilateral_0_180", 3: "bilateral_90_270", 4: "quadrant"}[isym]
    if sym == "none" and planes[-1] == 360.0:
        planes, table = planes[:-1], table[:-1]
    c_full, t = _full_c(planes, table, sym, where)
    g_full, t = _full_gamma(g_angles, t, where)
    meta = {"symmetry": sym, "manufacturer": _ldt_line(lines, 1, "the company"),
            "catalogue": _ldt_line(lines, 10, "the luminaire number"),
            "lorl_percent": lorl, "dff_percent": dff, "lamp_sets": lamp_sets}
    return Photometry(c_full, g_full, t, flux_lamps * lorl / 100.0, flux_lamps, "ldt", meta)



def parse_photometry(fmt: str, text: str) -> Photometry:
    """Parse a goniometric file: `fmt` is "ies" (IES LM-63) or "ldt" (EULUMDAT).

    Raises
    ------
    PhotometryError
        (a ValueError) for an unknown format or a file that cannot be read, saying what is wrong.
    """
    if fmt == "ies":
        return parse_ies(text)
    if fmt == "ldt":
        return parse_ldt(text)
    raise PhotometryError(f"unknown photometry format {fmt!r}: expected 'ies' or 'ldt'")
