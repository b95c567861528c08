"""What lighting engineers compute from luminance: uniformity and the unified glare rating (UGR, CIE 117-1995).

Plain functions over values and their standard errors (cd/m², sr, degrees); each figure carries its error bar,
propagated to first order (the delta method) from the inputs' standard errors, taken as independent.

- `uniformity`: U₀ = min/mean and U_d = min/max over meters or a camera region; `nine_points` places the 9-point
  grid of a backlight or display (the centres of a 3 × 3 division of the lit area, at 1/6, 1/2, 5/6 of each side).
- `guth_position_index`: the Luckiesh–Guth position index p(α, β), in the closed form used with CIE 117:
  ln p = (35.2 − 0.31889 α − 1.22 e^(−2α/9)) 10⁻³ β + (21 + 0.26667 α − 0.002963 α²) 10⁻⁵ β², with β the angle
  between the line of sight and the direction of the source, α the angle between the vertical plane through the
  line of sight and the plane through the line of sight and the source (both in degrees). Defined for sources above
  the line of sight.
- `ugr`: UGR = 8 log₁₀(0.25 / L_b × Σ L² ω / p²) from listed luminaires (L cd/m², ω sr, p) and a stated
  background luminance L_b; `ugr_from_image` from a camera image (`tracer.sensors.camera`).
"""

from __future__ import annotations

import math

import numpy as np


def _ratio_error(u: float, a: float, sa: float, b: float, sb: float, cov: float = 0.0) -> float:
    """σ of u = a/b to first order, with covariance `cov` of a and b."""
    if a == 0.0 or b == 0.0:
        return math.nan
    rel2 = (sa / a) ** 2 + (sb / b) ** 2 - 2.0 * cov / (a * b)
    return abs(u) * math.sqrt(max(rel2, 0.0))


def uniformity(values, stderr=None) -> dict:
    """Uniformity of luminances (or illuminances) of any shape: {"min", "max", "mean", "min_max", "min_mean",
    "min_max_stderr", "min_mean_stderr"}. The errors hold the smallest and largest value's index fixed (the delta
    method); where `stderr` is None they are 0."""
    v = np.asarray(values, float).ravel()
    if v.size == 0 or not np.all(np.isfinite(v)):
        raise ValueError("uniformity needs at least one finite value")
    s = np.zeros_like(v) if stderr is None else np.asarray(stderr, float).ravel()
    if s.shape != v.shape:
        raise ValueError(f"stderr has {s.size} values, values {v.size}")
    i, j = int(np.argmin(v)), int(np.argmax(v))
    lo, hi, mean = float(v[i]), float(v[j]), float(v.mean())
    s_mean = float(np.sqrt((s * s).sum())) / v.size
    u_d = lo / hi if hi > 0 else math.nan
    u_0 = lo / mean if mean > 0 else math.nan
    return {"min": lo, "max": hi, "mean": mean, "min_max": u_d, "min_mean": u_0,
            "min_max_stderr": 0.0 if i == j else _ratio_error(u_d, lo, float(s[i]), hi, float(s[j])),
            "min_mean_stderr": _ratio_error(u_0, lo, float(s[i]), mean, s_mean, float(s[i]) ** 2 / v.size)}


def nine_points(origin, u, v) -> np.ndarray:
    """(9, 3) points of the 9-point figure on the area origin + s u + t v: s, t in (1/6, 1/2, 5/6), row by row."""
    o, uu, vv = (np.asarray(x, float) for x in (origin, u, v))
    f = np.array([1.0, 3.0, 5.0]) / 6.0
    return np.array([o + s * uu + t * vv for t in f for s in f])


def thirteen_points(origin, u, v, inset: float = 0.01) -> np.ndarray:
    """(13, 3) points of the 13-point figure (the SPWG notebook-panel pattern) on the area origin + s u + t v:
    rows along v at `inset` metres from each edge, at a quarter, a half and three quarters; the rows at the edges
    and the middle hold three points (at `inset` from each side and the middle), the quarter rows two (a quarter and
    three quarters along u); row by row, s increasing. `inset` must be less than half of each edge."""
    o, uu, vv = (np.asarray(x, float) for x in (origin, u, v))
    a, b = inset / np.linalg.norm(uu), inset / np.linalg.norm(vv)
    three, two = (a, 0.5, 1.0 - a), (0.25, 0.75)
    rows = ((b, three), (0.25, two), (0.5, three), (0.75, two), (1.0 - b, three))
    return np.array([o + s * uu + t * vv for t, ss in rows for s in ss])


def guth_position_index(alpha_deg, beta_deg):
    """The Luckiesh–Guth position index p(α, β) (module docstring); arrays broadcast."""
    a = np.asarray(alpha_deg, float)
    b = np.asarray(beta_deg, float)
    ln_p = ((35.2 - 0.31889 * a - 1.22 * np.exp(-2.0 * a / 9.0)) * 1e-3 * b
            + (21.0 + 0.26667 * a - 0.002963 * a * a) * 1e-5 * b * b)
    return np.exp(ln_p)


def ugr(luminance, omega, p, background: float, stderr=None, background_stderr: float = 0.0) -> dict:
    """UGR of listed luminaires: luminance (n,) cd/m², solid angle omega (n,) sr, position index p (n,), seen
    against the background luminance `background` (cd/m², > 0). Returns {"ugr", "stderr", "sum"} (sum: Σ L² ω / p²);
    the error to first order from the luminances' `stderr` (n,) and the background's `background_stderr` (cd/m²),
    taken as independent: σ² = (8/ln 10)² ((σ_Σ/Σ)² + (σ_b/L_b)²)."""
    lum, om, pp = (np.atleast_1d(np.asarray(x, float)) for x in (luminance, omega, p))
    if not (background > 0 and math.isfinite(background)):
        raise ValueError(f"background luminance must be > 0 cd/m², got {background!r}")
    if not (background_stderr >= 0 and math.isfinite(background_stderr)):
        raise ValueError(f"background_stderr must be ≥ 0 cd/m², got {background_stderr!r}")
    terms = lum * lum * om / (pp * pp)
    total = float(terms.sum())
    if not total > 0:
        raise ValueError("no luminaire is seen: UGR is undefined (−∞)")
    value = 8.0 * math.log10(0.25 / background * total)
    rel2 = (background_stderr / background) ** 2
    if stderr is not None:
        d_total = float(np.sqrt(((2.0 * lum * om / (pp * pp) * np.asarray(stderr, float)) ** 2).sum()))
        rel2 += (d_total / total) ** 2
    return {"ugr": value, "stderr": 8.0 / math.log(10.0) * math.sqrt(rel2), "sum": total}


def pixel_geometry(fov_deg: float, width: int, height: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per pixel of a camera image (`tracer.sensors.camera`: vertical field of view, film at unit distance, row 0 on
    top): the solid angle ω (sr), the angle β from the line of sight and the Guth angle α (degrees), (height, width);
    α is NaN below the line of sight."""
    hh = math.tan(math.radians(fov_deg) / 2.0)
    hw = hh * width / height
    pw, ph = 2.0 * hw / width, 2.0 * hh / height
    x = -hw + (np.arange(width) + 0.5) * pw
    y = hh - (np.arange(height) + 0.5) * ph
    xx, yy = np.meshgrid(x, y)
    r2 = 1.0 + xx * xx + yy * yy
    omega = pw * ph / r2 ** 1.5
    beta = np.degrees(np.arccos(1.0 / np.sqrt(r2)))
    with np.errstate(invalid="ignore"):
        alpha = np.where(yy > 0, np.degrees(np.arctan2(np.abs(xx), yy)), np.nan)
    return omega, beta, alpha


def ugr_from_image(luminance, fov_deg: float, stderr=None, background: float | None = None,
                   threshold: float | None = None) -> dict:
    """UGR seen by a camera (its image (height, width) cd/m², vertical field of view `fov_deg`) looking along the
    observer's line of sight. Source pixels: above the line of sight with luminance ≥ `threshold` (default 5 × the
    image's mean luminance weighted by solid angle, evalglare's rule); background L_b: `background`, or the
    solid-angle-weighted mean of the other pixels, with its standard error from theirs. Returns `ugr`'s dict with
    "background", "background_stderr" (0 where the background is given), "threshold" and "source_pixels";
    ValueError where no pixel is a source or the background is black."""
    lum = np.asarray(luminance, float)
    if lum.ndim != 2:
        raise ValueError(f"an image is (height, width), got shape {lum.shape}")
    omega, beta, alpha = pixel_geometry(fov_deg, lum.shape[1], lum.shape[0])
    given_background = background
    if threshold is None:
        threshold = 5.0 * float((lum * omega).sum() / omega.sum())
    source = (lum >= threshold) & np.isfinite(alpha)
    if background is None:
        rest = ~source
        background = float((lum[rest] * omega[rest]).sum() / omega[rest].sum()) if rest.any() else 0.0
    source_count = int(source.sum())
    if source_count == 0:
        raise ValueError(f"no pixel above the line of sight reaches the threshold {threshold:.6g} cd/m²: no "
                         f"luminaire is seen, UGR is undefined")
    background_stderr = 0.0
    if given_background is None and stderr is not None and (~source).any():
        rest = ~source
        s_rest = np.asarray(stderr, float)[rest] * omega[rest]
        background_stderr = float(np.sqrt((s_rest * s_rest).sum()) / omega[rest].sum())
    if not background > 0:
        raise ValueError("the background (every pixel that is not a source) is black: UGR is undefined; give the "
                         "background luminance")
    err = None if stderr is None else np.asarray(stderr, float)[source]
    out = ugr(lum[source], omega[source], guth_position_index(alpha[source], beta[source]), background, err,
              background_stderr)
    return {**out, "background": background, "background_stderr": background_stderr, "threshold": threshold,
            "source_pixels": source_count}
