"""Polarized light: a photon's Stokes vector, its reference frame, and the Mueller matrices that act on it.

A photon of a polarized scene (effect ``polarization``: a polarizer, a retarder, a polarized light, or a query
that observes Stokes) carries, beside its weight w = S0, the normalised Stokes vector (1, s1, s2, s3) and the
x axis ``e`` of its reference frame, a unit vector across its direction d; y = d × e. With the field
E = (Ex, Ey) in that frame, S1 = |Ex|² − |Ey|², S2 = 2 Re(Ex Ey*), S3 = 2 Im(Ex Ey*) (the time factor exp(iωt)
of the n − ik convention, `tracer.optics.thinfilm`); s3 = +1 is right-handed in the IEEE sense. The state lives
in one per-photon array ``pol`` of `N_POL` floats: S1, S2, S3 (over S0), E (3: the frame axis) and ON
(1 where the photon carries polarization: the kinds act on it only then; 0 in unpolarized scenes, which
therefore trace the same paths and pay one branch).

Every operation keeps the weight analog, as the unpolarized kernels do: an interface reflects with the
probability that its Mueller matrix gives the photon's own state, then the state becomes the normalised
image (M s) / (M s)₀. Frames turn with the photon: an operation first rotates the Stokes vector into its own
frame (`rotate_into`: the plane of incidence's normal s = d × n, a polarizer's axis), acts, and hands the
photon its new frame. A diffuse surface or a Henyey–Greenstein scattering depolarizes (`depolarize`).

The Mueller matrix of a non-depolarizing interface in the frame (s, d × s) of each wave is set by four
numbers (`apply_interface`): A = |a_s|², B = |a_p|² (power fractions), C + iD = a_s a_p* (a the Jones
amplitudes in those frames):

    M = ½ [[A+B, A−B, 0, 0], [A−B, A+B, 0, 0], [0, 0, 2C, −2D], [0, 0, 2D, 2C]]

Light polarization on the wire (any light's ``polarization`` field):
``{"type": "linear", "axis": [x, y, z]}`` (the field's axis in world space, projected across each ray; where a ray
runs along the axis its frame is arbitrary), ``{"type": "circular", "handedness": "right" | "left"}``;
absent: unpolarized.
"""

from __future__ import annotations

import math

import numpy as np

from tracer.errors import TracerError
from tracer.jit import njit
from tracer.optics.frames import onb

S1, S2, S3, E, ON = 0, 1, 2, 3, 6   # columns of a photon's ``pol`` array (E: 3 columns)
N_POL = 8
UNPOLARIZED, LINEAR, CIRCULAR = 0, 1, 2   # a light's polarization type (`light_polarization`)
_TINY = 1e-24


class PolarizationError(TracerError):
    """A light's polarization body the tracer cannot use; the message names the field."""


def unit_axis(v) -> tuple[float, float, float] | None:
    """[x, y, z] of finite numbers, not all zero, made unit; None for anything else (the caller says what is wrong)."""
    ok = isinstance(v, list | tuple) and len(v) == 3 and all(
        not isinstance(x, bool) and isinstance(x, int | float) and math.isfinite(x) for x in v)
    m = max(abs(float(x)) for x in v) if ok else 0.0
    if not m > 0.0:
        return None
    s = [float(x) / m for x in v]   # scaled first: squaring 1e154 would overflow
    n = math.hypot(*s)
    return s[0] / n, s[1] / n, s[2] / n


def light_polarization(v, where: str) -> np.ndarray:
    """A light's ``polarization`` body as its packed row (4,) [type, a, b, c]: the axis (world) of a linear one,
    [±1, 0, 0] (right / left) of a circular one; zeros where absent (unpolarized)."""
    if v is None:
        return np.zeros(4)
    at = f"{where}: polarization"
    if not isinstance(v, dict) or v.get("type") not in ("linear", "circular"):
        raise PolarizationError(f"{at} must be {{'type': 'linear', 'axis': [x, y, z]}} or "
                                f"{{'type': 'circular', 'handedness': 'right' | 'left'}}, got {v!r}"[:300])
    if v["type"] == "linear":
        if set(v) != {"type", "axis"}:
            raise PolarizationError(f"{at}: a linear polarization has exactly the fields 'type' and 'axis', "
                                    f"got {sorted(v)}")
        a = unit_axis(v["axis"])
        if a is None:
            raise PolarizationError(f"{at}: 'axis' must be 3 finite numbers, not all zero (the field's direction, "
                                    f"world axes), got {v['axis']!r}"[:300])
        return np.array([LINEAR, *a])
    if set(v) != {"type", "handedness"} or v["handedness"] not in ("right", "left"):
        raise PolarizationError(f"{at}: a circular polarization has 'handedness': 'right' or 'left', got {v!r}"[:300])
    return np.array([CIRCULAR, 1.0 if v["handedness"] == "right" else -1.0, 0.0, 0.0])


# ----------------------------------------------------------------------------------------- kernels


@njit(cache=True, error_model="numpy", _nrt=False)
def across(dx, dy, dz, ax, ay, az):
    """The unit part of a across unit d, (ok, x, y, z); ok is False where a runs (nearly) along d."""
    c = ax * dx + ay * dy + az * dz
    px, py, pz = ax - c * dx, ay - c * dy, az - c * dz
    n2 = px * px + py * py + pz * pz
    if not n2 > 1e-18 * (ax * ax + ay * ay + az * az):
        return False, ax, ay, az
    inv = 1.0 / math.sqrt(n2)
    return True, px * inv, py * inv, pz * inv


@njit(cache=True, error_model="numpy", _nrt=False)
def set_frame(pol, dx, dy, dz, ax, ay, az):
    """Give the photon the frame axis a, made unit and across d (any axis across d where a runs along it);
    the Stokes vector is left as it is (the caller has expressed it in that frame)."""
    ok, ex, ey, ez = across(dx, dy, dz, ax, ay, az)
    if not ok:
        t, _ = onb(dx, dy, dz)
        ex, ey, ez = t[0], t[1], t[2]
    pol[E], pol[E + 1], pol[E + 2] = ex, ey, ez


@njit(cache=True, error_model="numpy", _nrt=False)
def rotation(pol, dx, dy, dz, ax, ay, az):
    """(cos 2φ, sin 2φ) of the frame rotation about d from the photon's axis e to a (across d)."""
    ex, ey, ez = pol[E], pol[E + 1], pol[E + 2]
    c = ex * ax + ey * ay + ez * az
    yx, yy, yz = dy * ez - dz * ey, dz * ex - dx * ez, dx * ey - dy * ex
    s = yx * ax + yy * ay + yz * az
    n2 = c * c + s * s
    if not n2 > _TINY:
        return 1.0, 0.0
    return (c * c - s * s) / n2, 2.0 * c * s / n2


@njit(cache=True, error_model="numpy", _nrt=False)
def rotate_into(pol, dx, dy, dz, ax, ay, az):
    """Express the photon's Stokes vector in the frame whose x axis is a (unit, across d), and take that frame."""
    c2, s2 = rotation(pol, dx, dy, dz, ax, ay, az)
    q, u = pol[S1], pol[S2]
    pol[S1] = c2 * q + s2 * u
    pol[S2] = -s2 * q + c2 * u
    pol[E], pol[E + 1], pol[E + 2] = ax, ay, az


@njit(cache=True, error_model="numpy", _nrt=False)
def interface_power(pol, a, b):
    """(M s)₀ of the interface matrix with power fractions A = a (s) and B = b (p), for the photon's state."""
    return 0.5 * (a + b) + 0.5 * (a - b) * pol[S1]


@njit(cache=True, error_model="numpy", _nrt=False)
def apply_interface(pol, a, b, c, d):
    """Replace the photon's state (in the interface's frame) by its normalised image under M(A, B, C, D);
    returns (M s)₀, the fraction of its power that passes (0: nothing, the state is left as it was)."""
    q, u, v = pol[S1], pol[S2], pol[S3]
    i0 = 0.5 * (a + b) + 0.5 * (a - b) * q
    if not i0 > 0.0:
        return 0.0
    inv = 1.0 / i0
    pol[S1] = (0.5 * (a - b) + 0.5 * (a + b) * q) * inv
    pol[S2] = (c * u - d * v) * inv
    pol[S3] = (d * u + c * v) * inv
    return i0


@njit(cache=True, error_model="numpy", _nrt=False)
def depolarize(pol):
    """Unpolarized light: what a diffuse reflection or an isotropic-frame scattering leaves. The frame axis is left
    as it was, possibly no longer across the new direction: an unpolarized state reads the same in any frame, and
    whatever polarizes it next sets its frame (`set_frame`); `rotation` and `across` take any axis."""
    pol[S1] = 0.0
    pol[S2] = 0.0
    pol[S3] = 0.0


@njit(cache=True, error_model="numpy", _nrt=False)
def emit(pol, rows, j, dx, dy, dz):
    """The state of a photon leaving light j along d in a polarized scene: rows (n, 4) are the lights' packed
    polarizations (`light_polarization`)."""
    pol[ON] = 1.0
    depolarize(pol)
    set_frame(pol, dx, dy, dz, rows[j, 1], rows[j, 2], rows[j, 3])
    if rows[j, 0] == LINEAR:
        ok, _, _, _ = across(dx, dy, dz, rows[j, 1], rows[j, 2], rows[j, 3])
        pol[S1] = 1.0 if ok else 0.0   # along its axis a linear light has no defined field direction
    elif rows[j, 0] == CIRCULAR:
        pol[S3] = rows[j, 1]


@njit(cache=True, error_model="numpy", _nrt=False)
def plane_axis(pol, dx, dy, dz, nx, ny, nz):
    """s = d × n made unit: the normal of the plane of incidence, across d (the photon's own axis where d runs
    along n, at normal incidence: every frame is then a plane-of-incidence frame)."""
    sx, sy, sz = dy * nz - dz * ny, dz * nx - dx * nz, dx * ny - dy * nx
    n2 = sx * sx + sy * sy + sz * sz
    if not n2 > 1e-20:
        ok, sx, sy, sz = across(dx, dy, dz, pol[E], pol[E + 1], pol[E + 2])
        if not ok:
            t, _ = onb(dx, dy, dz)
            return t[0], t[1], t[2]
        return sx, sy, sz
    inv = 1.0 / math.sqrt(n2)
    return sx * inv, sy * inv, sz * inv


@njit(cache=True, error_model="numpy", _nrt=False)
def observed(pol, dx, dy, dz, rx, ry, rz):
    """(s1, s2, s3) of the photon in a receiver's frame: x axis r (the receiver's reference) across d."""
    ok, ax, ay, az = across(dx, dy, dz, rx, ry, rz)
    if not ok:
        return 0.0, 0.0, pol[S3]   # r along d: no linear reference (a receiver seen edge-on by the light)
    c2, s2 = rotation(pol, dx, dy, dz, ax, ay, az)
    return c2 * pol[S1] + s2 * pol[S2], -s2 * pol[S1] + c2 * pol[S2], pol[S3]


@njit(cache=True, error_model="numpy", _nrt=False)
def enter_plane(pol, dx, dy, dz, nx, ny, nz):
    """Rotate the photon's state into the plane-of-incidence frame (s, d × s) of a surface with normal n (or of
    the turn from d to n, any vector in that plane); returns s, which `leave_plane` gives the outgoing photon."""
    sx, sy, sz = plane_axis(pol, dx, dy, dz, nx, ny, nz)
    rotate_into(pol, dx, dy, dz, sx, sy, sz)
    return sx, sy, sz


@njit(cache=True, error_model="numpy", _nrt=False)
def leave_plane(pol, a, b, c, d, ox, oy, oz, sx, sy, sz):
    """Apply the interface matrix M(A, B, C, D) to the state (in the frame of `enter_plane`) and give the photon,
    now along o, the frame (s, o × s); returns the fraction of power passed, (M s)₀."""
    i0 = apply_interface(pol, a, b, c, d)
    set_frame(pol, ox, oy, oz, sx, sy, sz)
    return i0
