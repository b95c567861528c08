"""A grating element: a periodic relief solved once by rigorous coupled-wave analysis, kept as a table of orders.

Issue 52, docs/DESIGN.md "Elements with a wave solution inside". This module checks a body, solves its relief with the
RCWA library `inkstone` over a grid of wavelengths, incidence directions and both polarizations, and keeps, for each
propagating order (reflected and transmitted), its efficiency and its Jones matrix, lit from the ambient and (its
second half, `GratingTable.inside`) from the substrate. The tracer's inner model (a ray leaving in one order, chosen
by its efficiency) reads it: `tracer.elements.diffraction`.

The body (lengths in um, wavelengths in nm, angles in degrees)::

    {"type": "grating",
     "profile": {"shape": "lamellar", "fill": 0.5}          ridges fill x period wide, one layer
              | {"shape": "sawtooth", "blaze_deg": 10}      a ramp rising depth_um over the period, back wall vertical:
                                                            depth_um = period_um tan(blaze) (give either, or both equal)
              | {"shape": "sinusoidal"}                     height (1 + cos(2 pi x / period)) depth / 2
              | {"shape": "pillars", "fill": 0.5}           2-D lattice of discs, fill = diameter / period
              | {"shape": "holes", "fill": 0.5}             2-D lattice of round holes in the ridge material
              | {"shape": "moth_eye", "fill": 1.0},         2-D lattice of cones, base diameter fill x period
     "period_um": p | [px, py],                             one for 1-D profiles; 2-D ones take p (square) or [px, py]
     "depth_um": d,
     "ridge": null | {"ior": n} | {"ior": [n, k]},           null: the substrate's material; metals as n - ik
     "substrate_ior": 1.5,                                  the part's index the table is solved for (lossless)
     "ambient_ior": 1.0,                                    the medium the face looks into (lossless)
     "grooves_along": "v" | "u",                            1-D: the ridges' direction on the face (the grating
                                                            vector is the other axis)
     "wavelengths_nm": [lo, hi], "wavelength_count": 9,     samples, lo to hi inclusive (one where lo == hi)
     "angles": {"polar_deg": [...], "azimuth_deg": [...]},  incidence (in the medium it comes from), ascending
     "orders": 10,                                          Fourier orders kept in the solve, -orders..orders per axis
     "layers": 16}                                          staircase layers of a graded profile (not lamellar,
                                                            pillars, holes: those are one layer)

Defaults: polar 0, 10, ..., 80; azimuth [0, 180] for 1-D profiles (both sides of the normal in the plane of the grating
vector: a sawtooth is not symmetric), [0, 45] for 2-D ones; orders 10 (1-D) or 3 (2-D); layers 16.

Frame: the table lives in the grating's own frame. x is the (first) grating vector, z the face's normal into the
substrate, the ambient at z < 0. The incidence direction's tangential part is ``n_a sin(polar) (cos az, sin az)``.
Polarization basis of every wave (incident and diffracted): ``s = z x k / |z x k|`` (for a normal wave ``(-sin az,
cos az, 0)``) and ``p = k x s``, so (s, p, k) is right-handed. Lit from the substrate (`inside`, the same layout),
the frame is turned 180 degrees about x: z into the ambient, y reversed, polar angles in the substrate; side 0 is then
reflected back into the substrate, side 1 transmitted into the ambient. Preparing solves both, twice the points.

The table (`GratingTable`; sizes W wavelengths, A polar angles, Z azimuths, K orders, side 0 reflected, 1 transmitted):

================  ===========================  ===========================================================
``wavelength_nm`` (W,) float64                  nm
``polar_deg``     (A,) float64                  degrees, in the ambient
``azimuth_deg``   (Z,) float64                  degrees, from the grating vector x
``orders``        (K, 2) int32                  (m, n): the order's tangential wave vector is the incident's
                                                plus m 2 pi / px x + n 2 pi / py y (n = 0 in 1-D)
``efficiency``    (W, A, Z, 2, 2, K) float32    [..., pol (0 s, 1 p), side, order]: power fraction; NaN where
                                                that order does not propagate on that side (never a zero)
``unpolarized``   (W, A, Z, 2, K) float32       mean of the two polarizations' efficiencies
``jones``         (W, A, Z, 2, K, 2, 2) c64     [..., side, order, out (s, p), in (s, p)]: field amplitudes
                                                scaled so that ``efficiency[pol] = sum |jones[:, pol]|^2``
``direction``     (W, A, Z, 2, K, 3) float32    the order's unit wave vector (from the solver's wave vectors)
================  ===========================  ===========================================================

`GratingTable.lookup` interpolates it and says where it runs out (`Lookup.status`): a wavelength or angle outside
the table, an order that does not propagate there (cut off), an order the table does not hold. Never a silent zero.

Why inkstone (0.3.15, 2024; numpy and scipy only): of the candidates on PyPI, grcwa 0.1.2 (2020, unmaintained,
autograd; permittivity sampled on a grid and FFT'd) and rcwa 1.0.48 (2023; needs pandas, progressbar2 and pytest
at run time), inkstone is the most recently maintained, the lightest (nothing beyond numpy and scipy, which the
tracer has), describes 1-D and 2-D patterns by their exact shapes (analytic Fourier transforms: boxes, discs),
solves conical incidence and answers each order's complex field amplitudes. It reproduces L. Li's published
conical-mount sinusoidal grating (JOSA A 10, 2581 (1993), Table 2) to within 0.003 at 41 orders and 0.0015 at 81,
and every lossless table point sums to 1 (tests/tracer/elements/test_grating_wave.py). torcwa needs torch.
BLAS runs single-threaded while solving (threadpoolctl): its small matrices ran 20x slower with threads competing.
"""

from __future__ import annotations

import io
import json
import math
import time
import warnings
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

# the body's checks and cost bound (check, element_id, harmonics, cost, affordable) are this module's API as well
from tracer.elements.grating_body import (  # noqa: F401
    ANGLE_OUTSIDE,
    CUT_OFF,
    MAX_PREPARE_SECONDS,
    NOT_KEPT,
    OK,
    SHAPES_2D,
    SOLVER,
    STATUS,
    WAVELENGTH_OUTSIDE,
    affordable,
    check,
    cost,
    element_id,
    harmonics,
    table_points,
)


def _structure(canon: dict, inside: bool = False) -> Any:
    """The inkstone model of the relief (lengths in um): ambient, the relief's layers top down, substrate; `inside`:
    seen from the substrate (the frame turned 180 degrees about x: substrate, the layers bottom up, ambient; every
    profile is symmetric under y -> -y, so the patterns stay as they are)."""
    from inkstone import Inkstone

    prof = canon["profile"]
    shape = prof["shape"]
    two_d = shape in SHAPES_2D
    period = canon["period_um"] if two_d else [canon["period_um"]]
    st = Inkstone()
    st.lattice = ((period[0], 0.0), (0.0, period[1])) if two_d else period[0]
    st.num_g = harmonics(canon)
    st.AddMaterial(name="ambient", epsilon=canon["ambient_ior"] ** 2)
    st.AddMaterial(name="substrate", epsilon=canon["substrate_ior"] ** 2)
    if canon["ridge"] is None:
        ridge = "substrate"
    else:
        n, k = canon["ridge"]["ior"]
        # the body's n - ik (exp(+i w t), optics' sign) is n + ik in inkstone's exp(-i w t): Im(eps) > 0 absorbs
        st.AddMaterial(name="ridge", epsilon=complex(n, k) ** 2 if k else n * n)
        ridge = "ridge"
    st.AddLayer(name="in", thickness=0.0, material_background="substrate" if inside else "ambient")
    nl, depth = canon["layers"], canon["depth_um"]
    for j in (reversed(range(nl)) if inside else range(nl)):
        name = f"z{j}"
        z = 1.0 - (j + 0.5) / nl   # the layer's middle height above the substrate, as a fraction of depth (top first)
        if shape == "holes":
            st.AddLayer(name=name, thickness=depth / nl, material_background=ridge)
            st.AddPatternDisk(layer=name, material="ambient", radius=prof["fill"] * min(period) / 2.0)
            continue
        st.AddLayer(name=name, thickness=depth / nl, material_background="ambient")
        if shape == "lamellar":
            st.AddPattern1D(layer=name, material=ridge, width=prof["fill"] * period[0], center=0.0)
        elif shape == "sawtooth":   # height rises linearly from 0 at x = 0 to depth at x = period
            st.AddPattern1D(layer=name, material=ridge, width=(1.0 - z) * period[0], center=(1.0 + z) / 2.0 *
                            period[0] - period[0] / 2.0)
        elif shape == "sinusoidal":   # centre sectioning: ridge where (1 + cos(2 pi x / p)) / 2 >= z
            st.AddPattern1D(layer=name, material=ridge, width=math.acos(2.0 * z - 1.0) / math.pi * period[0],
                            center=0.0)
        elif shape == "pillars":
            st.AddPatternDisk(layer=name, material=ridge, radius=prof["fill"] * min(period) / 2.0)
        else:   # moth_eye: a cone, its tip up
            st.AddPatternDisk(layer=name, material=ridge, radius=prof["fill"] * min(period) / 2.0 * (1.0 - z))
    st.AddLayer(name="out", thickness=0.0, material_background="ambient" if inside else "substrate")
    return st


def _basis(k: np.ndarray, az: float) -> tuple[np.ndarray, np.ndarray]:
    """(s, p) unit vectors of waves with unit wave vectors `k` ((K, 3)): s = z x k / |z x k| (a normal wave's:
    (-sin az, cos az, 0)), p = k x s."""
    s = np.stack([-k[:, 1], k[:, 0], np.zeros(len(k))], axis=1)
    norm = np.linalg.norm(s, axis=1)
    normal = norm < 1e-9
    s[normal] = [-math.sin(math.radians(az)), math.cos(math.radians(az)), 0.0]
    s[~normal] /= norm[~normal, None]
    return s, np.cross(k, s)


@dataclass(frozen=True, eq=False)
class Lookup:
    """One order's table values at a query (interpolated): efficiencies (power fractions) for s and p incidence
    and unpolarized, the Jones matrix ((2, 2) complex, out (s, p) by in (s, p)), and `status` (`STATUS`): anything
    but `OK` means the table has no value there, and the numbers are NaN."""

    status: int
    efficiency_s: float
    efficiency_p: float
    unpolarized: float
    jones: np.ndarray

    @property
    def reason(self) -> str:
        return STATUS[self.status]


@dataclass(frozen=True, eq=False)
class GratingTable:
    """A prepared grating: its checked body and its table of orders (layout in the module docstring)."""

    id: str
    body: dict
    wavelength_nm: np.ndarray
    polar_deg: np.ndarray
    azimuth_deg: np.ndarray
    orders: np.ndarray
    efficiency: np.ndarray
    unpolarized: np.ndarray
    jones: np.ndarray
    direction: np.ndarray
    prepare_seconds: float = 0.0
    inside: GratingTable | None = None   # the same relief lit from the substrate (its frame: module docstring)

    ARRAYS = ("wavelength_nm", "polar_deg", "azimuth_deg", "orders", "efficiency", "unpolarized", "jones",
              "direction")
    INSIDE = ("efficiency", "unpolarized", "jones", "direction")   # what `inside` holds of its own

    @property
    def nbytes(self) -> int:
        """Memory of the table's arrays, both sides (bytes)."""
        own = int(sum(getattr(self, a).nbytes for a in self.ARRAYS))
        return own + (0 if self.inside is None else int(sum(getattr(self.inside, a).nbytes for a in self.INSIDE)))

    def summary(self) -> dict[str, Any]:
        """What a library lists: id, type, bytes, prepare_seconds, solver (features: null)."""
        return {"id": self.id, "type": "grating", "features": None, "bytes": self.nbytes,
                "prepare_seconds": self.prepare_seconds, "solver": SOLVER}

    def to_bytes(self) -> bytes:
        """The table as an .npz (a zip of .npy files, stored, fixed timestamps, sorted names): the same body gives
        the same bytes. ``body`` holds the canonical JSON; the preparation time is not in it."""
        buf = io.BytesIO()
        items = {"body": np.frombuffer(json.dumps(self.body, sort_keys=True).encode(), np.uint8),
                 **{a: getattr(self, a) for a in self.ARRAYS}}
        if self.inside is not None:
            items.update({f"inside_{a}": getattr(self.inside, a) for a in self.INSIDE})
        with zipfile.ZipFile(buf, "w", zipfile.ZIP_STORED) as zf:
            for name in sorted(items):
                one = io.BytesIO()
                np.lib.format.write_array(one, np.ascontiguousarray(items[name]), allow_pickle=False)
                zf.writestr(zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0)), one.getvalue())
        return buf.getvalue()

    @classmethod
    def from_bytes(cls, data: bytes, prepare_seconds: float = 0.0) -> GratingTable:
        """A table written by `to_bytes`, as it was: nothing is solved again."""
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            body = json.loads(bytes(z["body"]).decode())
            arrays: dict[str, Any] = {a: np.array(z[a]) for a in cls.ARRAYS}
            inside: dict[str, Any] | None = ({a: np.array(z[f"inside_{a}"]) for a in cls.INSIDE}
                                             if "inside_efficiency" in z else None)
        eid = element_id(body)
        sub = None if inside is None else cls(eid, body, **{**arrays, **inside})
        return cls(eid, body, prepare_seconds=prepare_seconds, inside=sub, **arrays)

    def order_index(self, m: int, n: int = 0) -> int | None:
        """The row of order (m, n) in `orders`, or None where the table does not hold it."""
        hit = np.flatnonzero((self.orders[:, 0] == m) & (self.orders[:, 1] == n))
        return int(hit[0]) if len(hit) else None

    def lookup(self, wavelength_nm: float, polar_deg: float, azimuth_deg: float, order: tuple[int, int],
               side: int, from_inside: bool = False) -> Lookup:
        """Order `order` = (m, n) on `side` (0 reflected, 1 transmitted) at a wavelength (nm) and incidence
        (degrees, the grating's frame; `from_inside`: lit from the substrate, the polar angle in the substrate, the
        frame turned 180 degrees about x), interpolated linearly between the table's points. Outside the table's
        wavelengths or angles, for an order it does not hold, or one cut off at a surrounding table point, the
        answer's `status` says so and its numbers are NaN: never a silent zero. The table's angles are taken as they
        are: folding a direction by the relief's symmetries onto them is the inner model's
        (`tracer.elements.diffraction`)."""
        if from_inside:
            if self.inside is None:
                raise ValueError("this table was solved for light from the ambient side only")
            return self.inside.lookup(wavelength_nm, polar_deg, azimuth_deg, order, side)
        nan = Lookup(OK, math.nan, math.nan, math.nan, np.full((2, 2), np.nan + 0j))
        k = self.order_index(*order)
        if k is None:
            return _with_status(nan, NOT_KEPT)
        axes = []
        for values, x, bad in ((self.wavelength_nm, wavelength_nm, WAVELENGTH_OUTSIDE),
                               (self.polar_deg, polar_deg, ANGLE_OUTSIDE), (self.azimuth_deg, azimuth_deg,
                                                                            ANGLE_OUTSIDE)):
            span = 1e-9 * max(1.0, abs(float(values[-1])))
            if not values[0] - span <= x <= values[-1] + span:
                return _with_status(nan, bad)
            i = int(np.clip(np.searchsorted(values, x) - 1, 0, max(len(values) - 2, 0)))
            if len(values) == 1:
                axes.append([(0, 1.0)])
            else:
                t = float(np.clip((x - values[i]) / (values[i + 1] - values[i]), 0.0, 1.0))
                axes.append([(i, 1.0 - t), (i + 1, t)])
        eff = np.zeros(2)
        jones = np.zeros((2, 2), complex)
        for (a, wa) in axes[0]:
            for (b, wb) in axes[1]:
                for (c, wc) in axes[2]:
                    w = wa * wb * wc
                    if w == 0.0:
                        continue
                    e = self.efficiency[a, b, c, :, side, k]
                    if not np.isfinite(e).all():
                        return _with_status(nan, CUT_OFF)
                    eff += w * e
                    jones += w * self.jones[a, b, c, side, k]
        return Lookup(OK, float(eff[0]), float(eff[1]), float(eff.mean()), jones)


def _with_status(x: Lookup, status: int) -> Lookup:
    return Lookup(status, x.efficiency_s, x.efficiency_p, x.unpolarized, x.jones)


def prepare(body: Any, progress: Callable[[float], None] | None = None) -> GratingTable:
    """Check a grating body and solve its table (module docstring); `progress(fraction)` after each table point.

    Raises
    ------
    ElementError
        A body that is wrong (naming the field) or would cost more than `MAX_PREPARE_SECONDS` (`cost`).
    """
    t0 = time.perf_counter()
    canon = check(body)
    affordable(canon)
    lo, hi = canon["wavelengths_nm"]
    wl = np.linspace(float(lo), float(hi), int(canon["wavelength_count"]))
    polar = np.array(canon["angles"]["polar_deg"], float)
    azim = np.array(canon["angles"]["azimuth_deg"], float)
    two_d = canon["profile"]["shape"] in SHAPES_2D
    period = canon["period_um"] if two_d else [canon["period_um"], 1.0]
    n_a, n_s = canon["ambient_ior"], canon["substrate_ior"]
    # the orders that can propagate anywhere in the table, lit from either side (the grating equation's bound,
    # widened by one order: the solver's own wave vectors decide below)
    reach = 2.0 * max(n_a, n_s) / (wl[0] / 1000.0)   # |m| / period below it, in 1/um
    mmax = min(canon["orders"], int(reach * period[0]) + 1)
    nmax = min(canon["orders"], int(reach * period[1]) + 1) if two_d else 0
    orders = np.array([(m, n) for m in range(-mmax, mmax + 1) for n in range(-nmax, nmax + 1)], np.int32)
    shape = (len(wl), len(polar), len(azim))
    sides = []
    from threadpoolctl import threadpool_limits

    total = 2 * int(np.prod(shape))
    done = 0
    with threadpool_limits(limits=1, user_api="blas"), warnings.catch_warnings():
        # inkstone 0.3.15 warns on numpy 2's 2-D cross products and on its own layer bookkeeping: not ours to act on
        warnings.simplefilter("ignore")
        for inside, n_in, n_out in ((False, n_a, n_s), (True, n_s, n_a)):
            eff = np.full((*shape, 2, 2, len(orders)), np.nan, np.float32)
            jones = np.full((*shape, 2, len(orders), 2, 2), np.nan + 0j, np.complex64)
            direction = np.full((*shape, 2, len(orders), 3), np.nan, np.float32)
            st = _structure(canon, inside)
            for i, lam in enumerate(wl):
                for a, th in enumerate(polar):
                    for b, ph in enumerate(azim):
                        if th == 0.0 and b > 0:   # normal incidence: the first azimuth's solve in this one's bases
                            _turn_normal(jones[i, a, 0], direction[i, a, 0], azim[0], ph, eff[i, a, b],
                                         jones[i, a, b], direction[i, a, b])
                        else:
                            lam_um = _off_grazing(lam / 1000.0, th, ph, n_in, n_out, period, orders)
                            _solve_point(st, lam_um, th, ph, n_in, n_out, orders, two_d, eff[i, a, b],
                                         jones[i, a, b], direction[i, a, b])
                        done += 1
                        if progress is not None:
                            progress(done / total)
            sides.append((eff, jones, direction))
    keep = np.isfinite(sides[0][0]).any(axis=(0, 1, 2, 3, 4)) | np.isfinite(sides[1][0]).any(axis=(0, 1, 2, 3, 4))
    canon_id = element_id(canon)
    grids = (wl, polar, azim, orders[keep])
    (eff, jones, direction), (eff_in, jones_in, direction_in) = sides
    inside_table = GratingTable(canon_id, canon, *grids, eff_in[..., keep], eff_in.mean(axis=3)[..., keep],
                                jones_in[..., keep, :, :], direction_in[..., keep, :])
    return GratingTable(canon_id, canon, *grids, eff[..., keep], eff.mean(axis=3)[..., keep],
                        jones[..., keep, :, :], direction[..., keep, :], time.perf_counter() - t0, inside_table)


def _turn_normal(jones: np.ndarray, direction: np.ndarray, phi0: float, phi: float, eff_out: np.ndarray,
                 jones_out: np.ndarray, direction_out: np.ndarray) -> None:
    """Fill a normal-incidence table point at azimuth `phi` from the same point solved at `phi0` (degrees): one
    physical problem, whose incident wave and normal (zeroth) orders have their (s, p) bases turned with the azimuth
    (`_basis`); the other orders' waves and bases do not move. Solving it again would only repeat the work, and
    inkstone converges more slowly for TM through metal lines away from azimuth 0 (0.53 against 0.68 at 21
    Fourier orders for the same wire grid, both tending to 0.65): one solve keeps the point's azimuths consistent."""
    z = np.array([[0.0, 0.0, 1.0]])
    (s0, p0), (s1, p1) = _basis(z, phi0), _basis(z, phi)
    b_in = np.array([[s0[0] @ s1[0], s0[0] @ p1[0]], [p0[0] @ s1[0], p0[0] @ p1[0]]])   # a(phi0) = b_in a(phi)
    for side in (0, 1):
        ok = np.isfinite(direction[side, :, 0])
        if not ok.any():
            continue
        k = direction[side, ok].astype(np.float64)
        (sa, pa), (sb, pb) = _basis(k, phi0), _basis(k, phi)
        b_out = np.stack([np.stack([(sb * sa).sum(1), (sb * pa).sum(1)], 1),
                          np.stack([(pb * sa).sum(1), (pb * pa).sum(1)], 1)], 1)   # (K', out(phi), out(phi0))
        j = b_out @ jones[side, ok].astype(np.complex128) @ b_in
        jones_out[side, ok] = j
        eff_out[:, side, ok] = (np.abs(j) ** 2).sum(axis=1).T
        direction_out[side, ok] = direction[side, ok]


GRAZING = 1e-5   # relative: a table point whose order grazes (a Rayleigh anomaly) is solved this far off it


def _off_grazing(lam_um: float, theta: float, phi: float, n_a: float, n_s: float, period: list[float],
                 orders: np.ndarray) -> float:
    """The wavelength (um) to solve a table point at: `lam_um`, or where an order grazes the face there (kz = 0 on
    either side: the Rayleigh anomaly, where the modal solution is singular and inkstone drops the order), a
    wavelength `GRAZING` longer, an efficiency no measurement tells apart."""
    for lam in (lam_um, lam_um * (1.0 + GRAZING)):
        kt = n_a * math.sin(math.radians(theta)) * np.array([math.cos(math.radians(phi)), math.sin(math.radians(phi))])
        kx = kt[0] + orders[:, 0] * lam / period[0]
        ky = kt[1] + orders[:, 1] * lam / period[1]
        k2 = kx * kx + ky * ky
        if not any(np.isclose(k2, n * n, rtol=GRAZING / 10, atol=0.0).any() for n in (n_a, n_s)):
            return lam
    return lam_um * (1.0 + GRAZING)


def _solve_point(st: Any, lam_um: float, theta: float, phi: float, n_a: float, n_s: float, orders: np.ndarray,
                 two_d: bool, eff: np.ndarray, jones: np.ndarray, direction: np.ndarray) -> None:
    """Solve one incidence (both polarizations) and fill one table point's efficiencies (2 pols, 2 sides, K),
    Jones matrices (2 sides, K, 2, 2) and directions (2 sides, K, 3), leaving NaN where an order does not
    propagate."""
    st.frequency = 1.0 / lam_um
    k0 = 2.0 * math.pi / lam_um
    fields = []
    for s_amp, p_amp in ((1.0, 0.0), (0.0, 1.0)):
        st.SetExcitation(theta=theta, phi=phi, s_amplitude=s_amp, p_amplitude=p_amp)
        st.solve()
        st.GetPowerFluxByOrder("in", (0, 0), 0.0)   # solves, and sets the layers' amplitudes up
        st.GetPowerFluxByOrder("out", (0, 0), 0.0)
        idx = st.pr.idx_g
        ks = np.array(st.pr.ks) / k0   # tangential wave vectors of the solver's orders, in units of k0
        want = [tuple(int(x) for x in o) if two_d else (int(o[0]), 0) for o in orders]
        # an order the solver dropped (inkstone removes one grazing exactly, a Wood anomaly) is left NaN
        rows = np.array([idx.index(o) if o in idx else -1 for o in want])
        present = [o for o in want if o in idx]
        per = []
        for layer in ("in", "out"):
            amps = st.GetAmplitudesByOrder(layer, 0.0, present)   # Ex, Ey, Ez, Hx... forward and backward
            full = [np.zeros(len(idx), complex) for _ in range(6)]
            for c in range(6):
                full[c][[idx.index(o) for o in present]] = np.ravel(amps[c])
            per.append(full)
        fields.append((rows, ks, per))
    rows, ks, _ = fields[0]
    # the incident wave (order 0, forward, in the ambient) in our (s, p) basis, for each excitation
    i0 = st.pr.idx_g.index((0, 0))
    kt0 = ks[i0]
    kin = np.array([kt0[0], kt0[1], math.sqrt(max(n_a ** 2 - kt0 @ kt0, 0.0))]) / n_a
    s_in, p_in = _basis(kin[None, :], phi)
    m_in = np.empty((2, 2), complex)
    for e, (_, _, per) in enumerate(fields):
        ex, ey, ez = (per[0][c][i0] for c in (0, 2, 4))
        vec = np.array([ex, ey, ez])
        m_in[:, e] = [s_in[0] @ vec, p_in[0] @ vec]
    m_inv = np.linalg.inv(m_in)
    kz_in = kin[2] * n_a
    for side, (n, comp, sign) in enumerate(((n_a, 1, -1.0), (n_s, 0, 1.0))):
        ok = rows >= 0
        kt = np.where(ok[:, None], ks[np.maximum(rows, 0)], 0.0)
        kz2 = n * n - (kt ** 2).sum(axis=1)
        prop = ok & (kz2 > 1e-12)
        if not prop.any():
            continue
        kz = np.sqrt(np.maximum(kz2, 0.0))
        kvec = np.column_stack([kt, sign * kz]) / n
        s, p = _basis(kvec, phi)
        out = np.zeros((len(rows), 2, 2), complex)
        for e, (_, _, per) in enumerate(fields):
            amp = per[side]
            r = np.maximum(rows, 0)
            vec = np.stack([amp[c + comp][r] for c in (0, 2, 4)], axis=1)   # forward (0) or backward (1)
            out[:, 0, e] = (s * vec).sum(axis=1)
            out[:, 1, e] = (p * vec).sum(axis=1)
        # in our incident basis, scaled to power: flux along z of a plane wave ~ kz |E|^2 in a lossless medium
        j = out @ m_inv * np.sqrt(kz / kz_in)[:, None, None]
        power = (np.abs(j) ** 2).sum(axis=1)   # (K, in pol)
        eff[:, side, prop] = power[prop].T
        jones[side, prop] = j[prop]
        direction[side, prop] = kvec[prop]
