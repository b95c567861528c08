"""Thin-film interference: reflectance and transmittance of a stack of coherent dielectric layers.

Method: the characteristic (transfer) matrix of Born & Wolf, *Principles of Optics* §1.6, in the
admittance form of Macleod, *Thin-Film Optical Filters* ch. 2. Each layer j contributes
[[cos δ, i sin δ / η], [i η sin δ, cos δ]] with δ = 2π d q / λ, q = n cos θ = sqrt(n² − (n_in sin θ_in)²),
and tilted admittance η = q (s) or n² / q (p); the product over the layers, applied to the exit medium,
gives r and t. Agrees with the `tmm` package (Byrnes, arXiv:1603.02720) to rounding.

Conventions: complex index n − ik (k ≥ 0 absorbs), so forward waves in the exit medium have
q = a − ib with a, b ≥ 0 (evanescent beyond the critical angle: q = −ib). Layer rows are
[n, thickness in nm], outermost first (the stack's first row touches the ambient medium). Wavelengths in nm.
Transmittance is the power carried into the exit medium, Ts = Re(q_out) / q_in |t_s|² and the
equivalent of `tmm`'s conjugate-cosine form for p.

Limits: coherent layers only (no incoherent thick plates); layers have real indices (no absorption in
the coating); the incidence medium is lossless; the exit medium may absorb (e.g. a metal behind a
mirror coating). Evanescent decay per layer is capped at e^-35 in amplitude (as `tmm` does), which
changes R by less than 1e-30 and keeps the matrix finite.

Kernel rules (numba `njit` and numba-cuda `cuda.jit(device=True)` compile the same source): plain
Python over floats, no allocation, no exceptions. Because layer indices are real, q² is real and every
layer matrix is [[real, i·real], [i·real, real]], so the loop runs in real arithmetic; only the exit
medium is complex.
"""

from __future__ import annotations

import cmath
import math

from tracer.jit import njit

_MAX_DECAY = 35.0   # cap on |Im δ| per layer (amplitude e^-35), as in tmm
_SMALL_PHASE = 1e-4  # below this |δ|, cos δ and sin δ / δ by their series (error < δ⁴/24)


@njit(cache=True, error_model="numpy", _nrt=False)
def _layer_terms(u, kd):
    """cos δ and sin δ / q (both real) of one layer, with q² = u real and kd = 2π d / λ; δ = kd q."""
    x = kd * math.sqrt(abs(u))
    if u >= 0.0:
        if x < _SMALL_PHASE:
            return 1.0 - 0.5 * x * x, kd * (1.0 - x * x / 6.0)
        return math.cos(x), kd * math.sin(x) / x
    if x > _MAX_DECAY:  # evanescent and thick: taken as a barrier of decay e^-35
        kd = kd * _MAX_DECAY / x
        x = _MAX_DECAY
    if x < _SMALL_PHASE:
        return 1.0 + 0.5 * x * x, kd * (1.0 + x * x / 6.0)
    return math.cosh(x), kd * math.sinh(x) / x


@njit(cache=True, error_model="numpy", _nrt=False)
def _times(a, b, c, d, ca, b2, c2):
    """[[a, ib], [ic, d]] · [[ca, i b2], [i c2, ca]], entries as the real numbers a, b, c, d."""
    return a * ca - b * c2, a * b2 + b * ca, c * ca + d * c2, d * ca - c * b2


@njit(cache=True, error_model="numpy", _nrt=False)
def _exit_q(n_out, k_out, beta):
    """q = N cos θ in the exit medium N = n_out − i k_out, on the forward branch (Re ≥ 0, Im ≤ 0)."""
    q = cmath.sqrt(complex(n_out * n_out - k_out * k_out - beta, -2.0 * n_out * k_out))
    if q.imag > 0.0:
        q = -q
    return q


@njit(cache=True, error_model="numpy", _nrt=False)
def _abs2(z):
    return z.real * z.real + z.imag * z.imag


@njit(cache=True, error_model="numpy", _nrt=False)
def _clip01(x):
    return min(1.0, max(0.0, x))


@njit(cache=True, error_model="numpy", _nrt=False)
def _s_amplitudes(a, b, c, d, q_in, q_out):
    """r_s, t_s (complex, of the tangential field) and Ts from the s stack matrix [[a, ib], [ic, d]]: admittance
    η = q, [B, C] = M [1, q_out], r = (η_in B − C) / (η_in B + C), t = 2 η_in / (η_in B + C)."""
    bb = a + 1j * b * q_out
    cc = 1j * c + d * q_out
    den = q_in * bb + cc
    return (q_in * bb - cc) / den, 2.0 * q_in / den, _clip01(4.0 * q_in * q_out.real / _abs2(den))


@njit(cache=True, error_model="numpy", _nrt=False)
def _p_amplitudes(a, b, c, d, n_in, q_in, n_out, k_out, q_out):
    """r_p, t_p (complex, of the tangential field) and Tp from the p stack matrix [[a, ib], [ic, d]]: admittance
    η = n² / q.

    [B, C] = M [1, η_out] is scaled by 1 / η_out = q_out / N_out² and r, T are multiplied through by
    q_in, so nothing divides by a cosine that may be 0. T = 4 Re(η_in) Re(η_out) / |η_in B + C|² is
    `tmm`'s |t_p|² Re(N_out conj(cos_out)) / Re(n_in conj(cos_in)) written with admittances.
    """
    n_c = complex(n_out, -k_out)
    g = q_out / (n_c * n_c)
    bb = a * g + 1j * b
    cc = 1j * c * g + d
    n2 = n_in * n_in
    den = n2 * bb + q_in * cc
    return (n2 * bb - q_in * cc) / den, 2.0 * n2 * g / den, _clip01(4.0 * n2 * q_in * g.real / _abs2(den))


@njit(cache=True, error_model="numpy", _nrt=False)
def _amplitudes(layers, first, count, reverse, n_in, n_out, k_out, lam_nm, c_in):
    """(r_s, t_s, Ts, r_p, t_p, Tp) of the stack, arguments as `stack_rt` (0 < c_in ≤ 1)."""
    beta = n_in * n_in * (1.0 - c_in * c_in)  # (n_in sin θ_in)², the same in every medium
    k0 = 2.0 * math.pi / lam_nm
    # stack matrices [[a, ib], [ic, d]] for s and p, the layers in the order the light crosses them
    sa, sb, sc, sd = 1.0, 0.0, 0.0, 1.0
    pa, pb, pc, pd = 1.0, 0.0, 0.0, 1.0
    for i in range(count):
        row = first + count - 1 - i if reverse else first + i
        n2 = layers[row, 0] * layers[row, 0]
        u = n2 - beta
        cd, sq = _layer_terms(u, k0 * layers[row, 1])
        sa, sb, sc, sd = _times(sa, sb, sc, sd, cd, sq, u * sq)
        pa, pb, pc, pd = _times(pa, pb, pc, pd, cd, u * sq / n2, n2 * sq)
    q_in = n_in * c_in
    q_out = _exit_q(n_out, k_out, beta)
    rs, ts, t_s = _s_amplitudes(sa, sb, sc, sd, q_in, q_out)
    rp, tp, t_p = _p_amplitudes(pa, pb, pc, pd, n_in, q_in, n_out, k_out, q_out)
    return rs, ts, t_s, rp, tp, t_p


@njit(cache=True, error_model="numpy", _nrt=False)
def stack_rt(layers, first, count, reverse, n_in, n_out, k_out, lam_nm, cos_in):
    """Power reflectance and transmittance (Rs, Rp, Ts, Tp) of a thin-film stack at one wavelength.

    layers: (m, 2) float64, rows [n, thickness nm], outermost first; the stack is rows first .. first+count-1
    (count 0: a bare interface). reverse: False when light arrives from the ambient side (exit medium =
    substrate), True from the substrate side (layers crossed innermost first). n_in: real index of the
    incidence medium; n_out − i k_out: the exit medium (k_out ≥ 0). lam_nm: vacuum wavelength in nm;
    cos_in: cosine of the angle of incidence, in [0, 1]. Ts, Tp are 0 when the exit wave is evanescent.
    """
    if count == 0 and n_in == n_out and k_out == 0.0:
        return 0.0, 0.0, 1.0, 1.0
    c_in = min(1.0, max(0.0, cos_in))
    if c_in == 0.0:  # grazing: everything is reflected
        return 1.0, 1.0, 0.0, 0.0
    rs, _, ts, rp, _, tp = _amplitudes(layers, first, count, reverse, n_in, n_out, k_out, lam_nm, c_in)
    return _clip01(_abs2(rs)), _clip01(_abs2(rp)), ts, tp


@njit(cache=True, error_model="numpy", _nrt=False)
def stack_mueller(layers, first, count, reverse, n_in, n_out, k_out, lam_nm, cos_in):
    """The stack's reflection and transmission as Mueller parameters (Rs, Rp, Cr, Dr, Ts, Tp, Ct, Dt), arguments
    as `stack_rt`: each wave in its frame (s, d × s), s the normal of the plane of incidence, as
    `tracer.optics.polarization.apply_interface` reads them.

    Cr + iDr = a_s a_p* of the reflected wave. Its p frame turns over with the direction (d × s against the
    incident one), so its Jones p amplitude is −r_p of the tangential-field convention here: a mirror at
    normal incidence keeps S1 and turns S2 and S3 over. Ct + iDt = √(Ts Tp) e^{i(arg t_s − arg t_p)}.
    """
    if count == 0 and n_in == n_out and k_out == 0.0:
        return 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0
    c_in = min(1.0, max(0.0, cos_in))
    if c_in == 0.0:  # grazing: everything is reflected
        return 1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0
    rs, ts, t_s, rp, tp, t_p = _amplitudes(layers, first, count, reverse, n_in, n_out, k_out, lam_nm, c_in)
    r_s, r_p = _clip01(_abs2(rs)), _clip01(_abs2(rp))
    zr = -rs * rp.conjugate()
    zt = ts * tp.conjugate()
    m = abs(zt)
    ct, dt = 0.0, 0.0
    if m > 0.0:
        scale = math.sqrt(t_s * t_p) / m
        ct, dt = zt.real * scale, zt.imag * scale
    return r_s, r_p, zr.real, zr.imag, t_s, t_p, ct, dt


@njit(cache=True, error_model="numpy", _nrt=False)
def stack_reflectance(layers, first, count, reverse, n_in, n_out, k_out, lam_nm, cos_in):
    """Unpolarized reflectance (Rs + Rp) / 2 of the stack; arguments as stack_rt."""
    rs, rp, _, _ = stack_rt(layers, first, count, reverse, n_in, n_out, k_out, lam_nm, cos_in)
    return 0.5 * (rs + rp)
