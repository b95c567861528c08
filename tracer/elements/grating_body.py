"""A grating element's body: checked, given its id, and its cost bounded before any work (`tracer.elements.grating`).

The body's fields, units and defaults are in `tracer.elements.grating`'s docstring; here each is checked with a
message that says what is wrong and what to give instead, and `cost` estimates the seconds a preparation takes, so
that `affordable` refuses a body too costly for one request before anything is solved."""

from __future__ import annotations

import hashlib
import json
import math
from typing import Any

from tracer.elements.checks import ElementError, check_fields

SOLVER = "inkstone 0.3.15 (RCWA / Fourier modal method)"
SHAPES_1D = ("lamellar", "sawtooth", "sinusoidal")
SHAPES_2D = ("pillars", "holes", "moth_eye")
MAX_WAVELENGTHS = 401
MAX_ANGLES = 91
MAX_AZIMUTHS = 73
MAX_ORDERS_1D = 60
MAX_ORDERS_2D = 8
MAX_LAYERS = 64
#: What one table point costs (seconds, both polarizations), fitted to bench/grating_prepare.py on the development
#: machine (2 cores, busy, BLAS on one thread): 22.5 ms a point at 21 Fourier orders, 50.9 ms at 41 (a lamellar,
#: one layer), and 1.7 s for 50 layers at 41 (Li's sinusoid in the tests): a fixed part, and per layer the cube of
#: the solve's matrix size (2 G, G the Fourier orders kept). `cost` uses them before any work.
SECONDS_PER_POINT = 0.02
SECONDS_PER_LAYER_CUBE = 6.0e-8
#: The most one body may cost to prepare (seconds, by `cost`) and the most table entries it may keep.
MAX_PREPARE_SECONDS = 300.0
MAX_ENTRIES = 20_000_000

# lookup statuses
OK, WAVELENGTH_OUTSIDE, ANGLE_OUTSIDE, CUT_OFF, NOT_KEPT = 0, 1, 2, 3, 4
STATUS = {OK: "ok", WAVELENGTH_OUTSIDE: "wavelength outside the table", ANGLE_OUTSIDE: "angle outside the table",
          CUT_OFF: "order does not propagate there", NOT_KEPT: "order not in the table"}


def _number(x: Any, where: str, lo: float, hi: float, *, lo_open: bool = False) -> float:
    if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x):
        raise ElementError(f"{where} must be a finite number, got {x!r}"[:300])
    if (x <= lo if lo_open else x < lo) or x > hi:
        raise ElementError(f"{where} must be in {'(' if lo_open else '['}{lo:g}, {hi:g}], got {x!r}")
    return float(x)


def _count(x: Any, where: str, lo: int, hi: int) -> int:
    if isinstance(x, bool) or not isinstance(x, int) or not lo <= x <= hi:
        raise ElementError(f"{where} must be an integer in [{lo}, {hi}], got {x!r}"[:300])
    return int(x)


def _ior(x: Any, where: str, *, lossless: bool = False) -> tuple[float, float]:
    """(n, k) of an index given as n or [n, k] (n - ik: k >= 0 absorbs)."""
    if isinstance(x, list | tuple):
        if len(x) != 2:
            raise ElementError(f"{where} must be n or [n, k] (a metal's n - ik), got {x!r}"[:300])
        n, k = _number(x[0], f"{where}[0]", 0.01, 20.0), _number(x[1], f"{where}[1]", 0.0, 50.0)
    else:
        n, k = _number(x, where, 1.0, 20.0), 0.0
    if lossless and k != 0.0:
        raise ElementError(f"{where} must be lossless (k = 0): the table's orders leave through it")
    return n, k


def _angles(x: Any, where: str, lo: float, hi: float, most: int) -> list[float]:
    if not isinstance(x, list | tuple) or not 1 <= len(x) <= most:
        raise ElementError(f"{where} must be a list of 1 to {most} angles in degrees, got {x!r}"[:300])
    out = [_number(a, f"{where}[{i}]", lo, hi) for i, a in enumerate(x)]
    if any(b <= a for a, b in zip(out, out[1:], strict=False)):
        raise ElementError(f"{where} must be strictly ascending, got {out}"[:300])
    return out


def check(body: Any) -> dict:
    """The checked body with its defaults written out (canonical: the same grating, the same dict).

    Raises
    ------
    ElementError
        Naming the field, what is wrong and what to give instead.
    """
    if not isinstance(body, dict) or body.get("type") != "grating":
        raise ElementError("a grating element is an object {'type': 'grating', ...}")
    check_fields(body, "element", {"type", "profile", "period_um", "wavelengths_nm"},
            {"depth_um", "ridge", "substrate_ior", "ambient_ior", "grooves_along", "wavelength_count", "angles",
             "orders", "layers"})
    prof = body["profile"]
    if not isinstance(prof, dict) or prof.get("shape") not in SHAPES_1D + SHAPES_2D:
        got = prof.get("shape") if isinstance(prof, dict) else prof
        raise ElementError(f"profile.shape {got!r} is unknown; known: {list(SHAPES_1D + SHAPES_2D)}"[:300])
    shape = prof["shape"]
    two_d = shape in SHAPES_2D
    period = _period(body["period_um"], shape, two_d)
    canon_prof = _profile_fields(prof, shape)
    depth = body.get("depth_um")
    if shape == "sawtooth":
        canon_prof["blaze_deg"], depth = _sawtooth_blaze(prof.get("blaze_deg"), depth, period[0])
    if depth is None:
        raise ElementError("element: missing field(s) ['depth_um'] (the relief's depth in um)")
    depth = _number(depth, "depth_um", 0.0, 100.0, lo_open=True)
    canon_ridge = _ridge(body.get("ridge"))
    sub = _ior(body.get("substrate_ior", 1.5), "substrate_ior", lossless=True)[0]
    amb = _ior(body.get("ambient_ior", 1.0), "ambient_ior", lossless=True)[0]
    grooves = body.get("grooves_along", "v")
    if grooves not in ("u", "v"):
        raise ElementError(f"grooves_along must be 'u' or 'v' (the ridges' direction on the face), got {grooves!r}"
                           [:300])
    lo, hi, count = _wavelength_grid(body)
    polar, azimuth = _angle_grid(body.get("angles", {}), two_d)
    orders = _orders(body, two_d, period, lo, max(polar), sub, amb)
    layers = _count(body.get("layers", 16), "layers", 1, MAX_LAYERS)
    if shape in ("lamellar", "pillars", "holes"):
        layers = 1
    canon = {"type": "grating", "profile": canon_prof, "period_um": period if two_d else period[0],
             "depth_um": depth, "ridge": canon_ridge, "substrate_ior": sub, "ambient_ior": amb,
             "wavelengths_nm": [lo, hi], "wavelength_count": count,
             "angles": {"polar_deg": polar, "azimuth_deg": azimuth}, "orders": orders, "layers": layers}
    if not two_d:
        canon["grooves_along"] = grooves
    elif "grooves_along" in body:
        raise ElementError(f"grooves_along is for 1-D profiles; a 2-D lattice ({shape}) has its periods along u "
                           f"and v")
    return canon


def _period(p: Any, shape: str, two_d: bool) -> list[float]:
    """The lattice's periods in um: [p] along the grating vector of a 1-D profile, [px, py] of a 2-D lattice (a
    single p there is square)."""
    if two_d:
        pair = p if isinstance(p, list | tuple) else [p, p]
        if len(pair) != 2:
            raise ElementError(f"period_um of a 2-D lattice is p (square) or [px, py] in um, got {p!r}"[:300])
        return [_number(pair[0], "period_um[0]", 0.0, 1000.0, lo_open=True),
                _number(pair[1], "period_um[1]", 0.0, 1000.0, lo_open=True)]
    if isinstance(p, list | tuple):
        raise ElementError(f"period_um of a 1-D profile ({shape}) is one number in um (the grating vector's "
                           f"period), got {p!r}; [px, py] is for pillars, holes, moth_eye"[:300])
    return [_number(p, "period_um", 0.0, 1000.0, lo_open=True)]


def _profile_fields(prof: dict, shape: str) -> dict[str, Any]:
    """The canonical profile's shape and fill (the ridge's fraction of the period, where the shape has one), its
    keys checked for the shape; a sawtooth's blaze is added by `_sawtooth_blaze`, which needs the depth."""
    canon_prof: dict[str, Any] = {"shape": shape}
    if shape in ("lamellar", "pillars", "holes", "moth_eye"):
        check_fields(prof, "profile", {"shape"}, {"fill"})
        canon_prof["fill"] = _number(prof.get("fill", 0.5 if shape != "moth_eye" else 1.0), "profile.fill", 0.0,
                                     1.0, lo_open=True)
        if shape == "lamellar" and canon_prof["fill"] == 1.0:
            raise ElementError("profile.fill 1 leaves no groove: a lamellar grating's fill is in (0, 1); a flat "
                               "face needs no grating")
    elif shape == "sawtooth":
        check_fields(prof, "profile", {"shape"}, {"blaze_deg"})
    else:
        check_fields(prof, "profile", {"shape"}, set())
    return canon_prof


def _sawtooth_blaze(blaze: Any, depth: Any, period_um: float) -> tuple[float, Any]:
    """A sawtooth's (blaze in degrees, depth): either one implies the other (depth = period tan(blaze), um); both
    given must agree. The depth comes back as given where only it was, for `check` to check."""
    if blaze is None and depth is None:
        raise ElementError("a sawtooth needs profile.blaze_deg or depth_um (depth = period tan(blaze))")
    if blaze is not None:
        b = _number(blaze, "profile.blaze_deg", 0.0, 80.0, lo_open=True)
        from_blaze = period_um * math.tan(math.radians(b))
        if depth is not None:
            d = _number(depth, "depth_um", 0.0, 100.0, lo_open=True)
            if abs(d - from_blaze) > 1e-6 * from_blaze:
                raise ElementError(f"depth_um {d:g} disagrees with profile.blaze_deg {b:g}: a sawtooth of period "
                                   f"{period_um:g} um and that blaze is {from_blaze:.6g} um deep; give one of "
                                   f"the two")
        return float(blaze), from_blaze
    return math.degrees(math.atan(_number(depth, "depth_um", 0.0, 100.0, lo_open=True) / period_um)), depth


def _ridge(ridge: Any) -> dict | None:
    """The ridge's canonical material: None where it is the substrate's, else {'ior': [n, k]}."""
    if ridge is None:
        return None
    if not isinstance(ridge, dict):
        raise ElementError(f"ridge must be null (the substrate's material) or {{'ior': n | [n, k]}}, got "
                           f"{ridge!r}"[:300])
    check_fields(ridge, "ridge", {"ior"}, set())
    n, k = _ior(ridge["ior"], "ridge.ior")
    return {"ior": [n, k]}


def _wavelength_grid(body: dict) -> tuple[float, float, int]:
    """(lo, hi, count) of the table's wavelengths in nm: one wavelength takes a count of 1, a range at least 2
    (default 9)."""
    wl = body["wavelengths_nm"]
    if not isinstance(wl, list | tuple) or len(wl) != 2:
        raise ElementError(f"wavelengths_nm must be [lo, hi] in nm, got {wl!r}"[:300])
    lo, hi = _number(wl[0], "wavelengths_nm[0]", 200.0, 5000.0), _number(wl[1], "wavelengths_nm[1]", 200.0, 5000.0)
    if hi < lo:
        raise ElementError(f"wavelengths_nm [{lo:g}, {hi:g}] must be ascending: [lo, hi]")
    count = _count(body.get("wavelength_count", 1 if lo == hi else 9), "wavelength_count", 1, MAX_WAVELENGTHS)
    if lo == hi and count != 1:
        raise ElementError(f"wavelength_count {count} over one wavelength ({lo:g} nm): give 1 or widen "
                           f"wavelengths_nm")
    if lo < hi and count < 2:
        raise ElementError(f"wavelength_count 1 over [{lo:g}, {hi:g}] nm: give at least 2, or one wavelength "
                           f"[{lo:g}, {lo:g}]")
    return lo, hi, count


def _angle_grid(angles: Any, two_d: bool) -> tuple[list[float], list[float]]:
    """The table's (polar, azimuth) angles in degrees; the default azimuths are the lattice's symmetric ones (0 and
    45 in 2-D, 0 and 180 in 1-D)."""
    if not isinstance(angles, dict):
        raise ElementError(f"angles must be {{'polar_deg': [...], 'azimuth_deg': [...]}}, got {angles!r}"[:300])
    check_fields(angles, "angles", set(), {"polar_deg", "azimuth_deg"})
    polar = _angles(angles.get("polar_deg", [10.0 * i for i in range(9)]), "angles.polar_deg", 0.0, 89.0,
                    MAX_ANGLES)
    azimuth = _angles(angles.get("azimuth_deg", [0.0, 45.0] if two_d else [0.0, 180.0]), "angles.azimuth_deg",
                      0.0, 360.0, MAX_AZIMUTHS)
    return polar, azimuth


def _orders(body: dict, two_d: bool, period: list[float], lo_nm: float, polar_deg: float, n_s: float,
            n_a: float) -> int:
    """The body's ``orders`` (default 3 in 2-D, 10 in 1-D), checked to hold every propagating order
    (`_all_propagating_kept`)."""
    most = MAX_ORDERS_2D if two_d else MAX_ORDERS_1D
    orders = _count(body.get("orders", 3 if two_d else 10), "orders", 1, most)
    _all_propagating_kept(orders, period, lo_nm, polar_deg, n_s, n_a, most)
    return orders


def _all_propagating_kept(orders: int, period: list[float], lo_nm: float, polar_deg: float, n_s: float, n_a: float,
                         most: int) -> None:
    """`ElementError` naming ``orders`` where an order beyond ±`orders` propagates somewhere in the table: the solve
    would leave its light out and share it among the kept ones (a lossless truncated solve still sums to 1), wrong
    without a sign. Along a period p the tangential wave vector of order m is n sin(theta) + m lambda / p (in units
    of the free-space wavenumber, n the index light arrives in: the table is solved from both sides), at most
    n_max sin(theta_max) + |m| lambda / p in size; an order propagates where that is below the larger index n_max, so
    every |m| < n_max (1 + sin(theta_max)) p / lambda_min may."""
    for axis, p in enumerate(period):
        bound = max(n_a, n_s) * (1.0 + math.sin(math.radians(polar_deg))) * p * 1000.0 / lo_nm
        need = math.ceil(bound) - 1   # the largest |m| strictly below the bound
        if need <= orders:
            continue
        where = f"period_um {p:g}" + (f" (axis {'uv'[axis]})" if len(period) > 1 else "")
        fix = (f"give orders >= {need}" if need <= most else
               f"that is more than the {most} a rigorous solve takes here: narrow wavelengths_nm to longer ones, "
               f"angles.polar_deg to smaller ones, or use a shorter period")
        raise ElementError(f"orders {orders} keeps -{orders}..{orders}, but orders up to |m| = {need} propagate in "
                           f"this table ({where}, {lo_nm:g} nm, polar up to {polar_deg:g} deg): their light would be "
                           f"left out of the solve; {fix}")


def element_id(canon: dict) -> str:
    """SHA-256 of the checked body's canonical JSON: the same body, the same id."""
    return hashlib.sha256(json.dumps(canon, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def harmonics(canon: dict) -> int:
    """G, the Fourier orders (plane waves) the solve keeps: 2 orders + 1 in 1-D, its square in 2-D."""
    g = 2 * canon["orders"] + 1
    return g * g if canon["profile"]["shape"] in SHAPES_2D else g


def table_points(canon: dict) -> int:
    """Wavelengths x polar angles x azimuths of a checked body's table: the points solved for each side of the face."""
    return canon["wavelength_count"] * len(canon["angles"]["polar_deg"]) * len(canon["angles"]["azimuth_deg"])


def cost(canon: dict) -> float:
    """Seconds preparing `canon` (a checked body) takes, estimated before any work: per table point (each solved
    twice, lit from either side), a fixed part and, per layer, the cube of the solve's matrix size (2 G)."""
    points = 2 * table_points(canon)
    return points * (SECONDS_PER_POINT + canon["layers"] * SECONDS_PER_LAYER_CUBE * (2 * harmonics(canon)) ** 3)


def affordable(canon: dict) -> None:
    """`ElementError` where preparing `canon` (checked) would cost more than `MAX_PREPARE_SECONDS` (`cost`), saying
    what to reduce."""
    seconds = cost(canon)
    if seconds <= MAX_PREPARE_SECONDS:
        return
    points = table_points(canon)
    raise ElementError(
        f"this grating would take about {seconds:,.0f} s to prepare ({points} table points, each lit from both sides, "
        f"of {canon['layers']} layer(s) and {harmonics(canon)} Fourier orders); one request prepares at most "
        f"{MAX_PREPARE_SECONDS:g} s: give fewer wavelength_count or angles, fewer layers, or a smaller orders")
