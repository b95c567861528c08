"""Writing a far field (`tracer.simulate.Simulation.far_field`) as a goniometric file: IES LM-63-2002 or EULUMDAT.

Both files hold the type-C table of the far field as it is: the γ samples 0°, Δγ, …, 180° and the C samples 0°,
ΔC, …, 360° − ΔC (no symmetry assumed; a far field of one C sample is written as axially symmetric), each value the
intensity averaged over its bin (`tracer.simulate.FarFieldResult`). `tracer.photometry.files` reads them back to the
same table, to the printed precision: candelas are printed in fixed point with six significant digits of the largest
value (`decimals`), so every value is within half a unit of its last printed digit.

IES: absolute photometry (lumens per lamp −1, candela multiplier 1, ballast factor 1, metres, a point: a luminous
opening of 0 × 0 × 0), the flux leaving the scene in ``[_ABSOLUTELUMENS]``; the horizontal angles run 0 … 360 (the
last column repeats C = 0, as LM-63 asks of a table without symmetry). EULUMDAT: Isym 0 (1 for one C sample), one
lamp set whose flux is the flux leaving the scene, LORL 100 %, conversion factor 1, intensities in cd/klm of that
flux; DFF from the table; the ten direct ratios are not computed (0).

The flux a reader integrates from the table (`Photometry.total_flux`, bilinear between the samples) differs from the
flux that left the scene only by the interpolation between bin averages: exact in C (a periodic trapezoid rule), of
second order in Δγ (0.1 % on a 5° grid of a real downlight; tests/tracer/photometry/test_photometry_export.py).
"""

from __future__ import annotations

import datetime as _dt
import math

import numpy as np

from tracer.photometry.files import PhotometryError

__all__ = ["decimals", "write_ies", "write_ldt", "write_photometry"]

PER_LINE = 10          # values per line (IES lines stay far below LM-63's 256 characters)
SIGNIFICANT = 6        # digits of the largest value printed


def decimals(values: np.ndarray, significant: int = SIGNIFICANT) -> int:
    """Decimals that print the largest of `values` with `significant` digits (0 … 12)."""
    top = float(np.max(np.abs(values))) if np.size(values) else 0.0
    if not top > 0.0:
        return 0
    return int(min(12, max(0, significant - 1 - math.floor(math.log10(top)))))


def _fixed(v: float, d: int) -> str:
    s = f"{v:.{d}f}"
    return "0" if float(s) == 0.0 else s     # no "-0.00"


def _rows(values, d: int) -> list[str]:
    vals = [_fixed(float(v), d) for v in values]
    return [" ".join(vals[k:k + PER_LINE]) for k in range(0, len(vals), PER_LINE)]


def _check(candela, c_deg, gamma_deg, flux_lm) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    cd = np.asarray(candela, np.float64)
    c = np.asarray(c_deg, np.float64)
    g = np.asarray(gamma_deg, np.float64)
    if cd.ndim != 2 or cd.shape != (len(g), len(c)):
        raise PhotometryError(f"candela must be (len(gamma_deg), len(c_deg)) = ({len(g)}, {len(c)}), got {cd.shape}")
    if len(g) < 2 or g[0] != 0.0 or g[-1] != 180.0 or not np.all(np.diff(g) > 0):
        raise PhotometryError("gamma_deg must increase from 0 to 180 degrees")
    if len(c) < 1 or c[0] != 0.0 or not np.all(np.diff(c) > 0) or c[-1] >= 360.0:
        raise PhotometryError("c_deg must increase from 0 and stay below 360 degrees")
    if not np.all(np.isfinite(cd)) or np.any(cd < 0):
        raise PhotometryError("candela values must be finite and ≥ 0")
    if not np.any(cd > 0) or not (math.isfinite(flux_lm) and flux_lm > 0):
        raise PhotometryError("nothing left the scene (every intensity is 0): there is no distribution to write")
    return cd, c, g, float(flux_lm)


def _text(s: str, limit: int = 78) -> str:
    return " ".join(str(s).split())[:limit]


def write_ies(candela, c_deg, gamma_deg, flux_lm: float, *, name: str = "far field", notes: str = "",
              date: _dt.date | None = None) -> str:
    """IES LM-63-2002 text of a type-C table: candela (nγ, nc) cd at `gamma_deg` (0 … 180) × `c_deg` (0 … < 360),
    `flux_lm` the flux it stands for (``[_ABSOLUTELUMENS]``). See the module docstring."""
    cd, c, g, flux = _check(candela, c_deg, gamma_deg, flux_lm)
    d = decimals(cd)
    if len(c) == 1:
        horiz, cols = [0.0], [cd[:, 0]]
    else:
        horiz, cols = [*c.tolist(), 360.0], [*cd.T, cd[:, 0]]
    day = (date or _dt.date.today()).isoformat()
    lines = ["IESNA:LM-63-2002",
             "[TEST] LumenLink far-field simulation",
             "[TESTLAB] LumenLink (simulated, not measured)",
             f"[ISSUEDATE] {day}",
             "[MANUFAC] LumenLink",
             f"[LUMCAT] {_text(name)}",
             f"[LUMINAIRE] {_text(name)}",
             f"[_ABSOLUTELUMENS] {_fixed(flux, decimals(np.array([flux]), 10))}"]
    if notes:
        lines.append(f"[OTHER] {_text(notes, 240)}")
    lines += ["[OTHER] far field: the scene as a point source, valid where it is small against the viewing distance",
              "TILT=NONE",
              f"1 -1 1 {len(g)} {len(horiz)} 1 2 0 0 0",
              "1 1 0"]
    d_angles = 6
    lines += _rows(g, d_angles)
    lines += _rows(horiz, d_angles)
    for col in cols:
        lines += _rows(col, d)
    return "\n".join(lines) + "\n"


def write_ldt(candela, c_deg, gamma_deg, flux_lm: float, *, name: str = "far field", notes: str = "",
              date: _dt.date | None = None) -> str:
    """EULUMDAT text of a type-C table (arguments as for `write_ies`): intensities in cd/klm of `flux_lm`, one lamp
    set of that flux, LORL 100 %. See the module docstring."""
    cd, c, g, flux = _check(candela, c_deg, gamma_deg, flux_lm)
    nc, ng = len(c), len(g)
    rel = cd * (1000.0 / flux)                  # cd/klm
    d = decimals(rel)
    # downward flux fraction from the bins: rows below 90°, the share of a row's band below 90°
    dg = 180.0 / (ng - 1)
    lo = np.radians(np.clip(g - dg / 2, 0.0, 180.0))
    hi = np.radians(np.clip(g + dg / 2, 0.0, 180.0))
    band = np.cos(lo) - np.cos(hi)
    below = np.cos(lo) - np.cos(np.minimum(hi, math.pi / 2))
    below = np.where(lo < math.pi / 2, below, 0.0)
    row_flux = cd.mean(axis=1) * band
    dff = 100.0 * float((cd.mean(axis=1) * below).sum() / row_flux.sum()) if row_flux.sum() > 0 else 0.0
    day = (date or _dt.date.today()).isoformat()
    axial = nc == 1
    head = ["LumenLink (simulated far field)",
            "1" if axial else "3",                 # Ityp: point source, axial / other symmetry
            "1" if axial else "0",                 # Isym
            str(nc),                               # Mc
            _fixed(0.0 if axial else 360.0 / nc, 6),   # Dc
            str(ng),                               # Ng
            _fixed(dg, 6),                         # Dg
            "LumenLink far field",                 # measurement report
            _text(name), _text(name),              # luminaire name, number
            _text(name.replace(" ", "_") + ".ldt"),
            _text(f"{day} {notes}"),
            "0", "0", "0", "0", "0", "0", "0", "0", "0",   # luminaire and luminous-area dimensions, mm: a point
            _fixed(dff, 4), "100", "1", "0",      # DFF %, LORL %, conversion factor, tilt
            "1",                                   # lamp sets
            "1", "simulated", _fixed(flux, decimals(np.array([flux]), 10)), "0", "0", "0"]
    head += ["0"] * 10                             # direct ratios: not computed
    body = [_fixed(x, 6) for x in (c if not axial else [0.0])]
    body += [_fixed(x, 6) for x in g]
    planes = rel.T if not axial else rel.T[:1]
    body += [_fixed(float(v), d) for plane in planes for v in plane]
    return "\r\n".join(head + body) + "\r\n"


def write_photometry(fmt: str, candela, c_deg, gamma_deg, flux_lm: float, **kw) -> str:
    """`write_ies` for fmt "ies", `write_ldt` for "ldt"; `PhotometryError` for another format."""
    if fmt == "ies":
        return write_ies(candela, c_deg, gamma_deg, flux_lm, **kw)
    if fmt == "ldt":
        return write_ldt(candela, c_deg, gamma_deg, flux_lm, **kw)
    raise PhotometryError(f"unknown photometry format {fmt!r}: expected 'ies' or 'ldt'")
