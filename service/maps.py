"""False-colour illuminance maps of grid sensors, as PNG bytes (the view of the paper's fig. 4).

A grid sensor is a rectangle ``origin + s·u + t·v`` (s, t in [0, 1], metres) split into
``nu × nv`` cells; its result is an array ``lux`` of shape ``(nv, nu)`` where row ``j``, column
``i`` is the cell whose centre is ``origin + (i + ½)/nu·u + (j + ½)/nv·v``. The maps draw that
array in the sensor's own frame: the horizontal axis runs along ``u``, the vertical along ``v``,
both in metres from ``origin``, so the picture is what you see looking at the sensor's front side
(``u × v`` towards you).

Figures are built with the object-oriented matplotlib API on an Agg canvas (no ``pyplot``): the
service renders maps from worker threads, and ``pyplot`` keeps global state that is not thread-safe.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from service.errors import ServiceError

if TYPE_CHECKING:   # matplotlib itself is imported with the first picture (`_canvas`): 1.6 s of the service's start
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

# A change counts as significant where |ΔE| exceeds this many combined standard errors
# (2σ: about 5 % of unchanged cells of a large grid are flagged by chance, which is why the
# summary reports the count rather than listing each cell).
SIGNIFICANCE_SIGMAS = 2.0

# Dots that flag insignificant cells are drawn only on grids up to this many cells; beyond it
# they would cover the colours.
_MAX_DOTTED_CELLS = 60 * 60


class MapError(ServiceError):
    """The arrays or the sensor frame handed to a map are inconsistent (a programming error upstream, hence 500)."""

    status = 500
    title = "Map cannot be drawn"


@dataclass(frozen=True)
class ChangeSummary:
    """Where a grid's illuminance changed between two results.

    Attributes
    ----------
    cells : int
        Number of cells in the grid.
    significant : int
        Cells whose change exceeds ``SIGNIFICANCE_SIGMAS`` combined standard errors.
    increased, decreased : int
        Significant cells that became brighter, resp. darker.
    max_increase_lux, max_decrease_lux : float
        Largest rise and largest fall in lx (0 where there is none), over all cells.
    max_increase_at, max_decrease_at : tuple of float
        World position (m) of the centre of the cell with the largest rise, resp. fall.
    mean_before_lux, mean_after_lux : float
        Mean illuminance over the grid before and after, lx.
    """

    cells: int
    significant: int
    increased: int
    decreased: int
    max_increase_lux: float
    max_increase_at: tuple[float, float, float]
    max_decrease_lux: float
    max_decrease_at: tuple[float, float, float]
    mean_before_lux: float
    mean_after_lux: float


def _check_frame(origin: object, u: object, v: object) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    arrays = []
    for name, value in (("origin", origin), ("u", u), ("v", v)):
        a = np.asarray(value, dtype=float)
        if a.shape != (3,) or not np.all(np.isfinite(a)):
            raise MapError(f"{name} must be 3 finite numbers (metres), got {value!r}")
        arrays.append(a)
    o, uu, vv = arrays
    if np.linalg.norm(uu) == 0.0 or np.linalg.norm(vv) == 0.0:
        raise MapError("u and v must be non-zero edge vectors of the sensor rectangle")
    return o, uu, vv


def _check_grid(name: str, values: object, shape: tuple[int, ...] | None = None) -> np.ndarray:
    a = np.asarray(values, dtype=float)
    if a.ndim != 2 or a.shape[0] < 1 or a.shape[1] < 1:
        raise MapError(f"{name} must be a 2-d array (nv, nu) with at least one cell, got shape {a.shape}")
    if shape is not None and a.shape != shape:
        raise MapError(f"{name} has shape {a.shape}, expected {shape}")
    if not np.all(np.isfinite(a)):
        raise MapError(f"{name} contains NaN or infinite values")
    return a


def median_relative_error(lux: object, stderr: object, floor: float = 0.05) -> float:
    """Median of stderr/lux over the cells brighter than ``floor`` × the maximum (NaN if none).

    Dark cells are left out: their relative error is large and says nothing about the lit area a
    reader looks at; the same figure is printed by the demo and on the maps.
    """
    e = np.asarray(lux, dtype=float)
    se = np.asarray(stderr, dtype=float)
    if e.shape != se.shape:
        raise MapError(f"lux and stderr shapes differ: {e.shape} vs {se.shape}")
    top = float(e.max()) if e.size else 0.0
    lit = e > floor * top if top > 0 else np.zeros(e.shape, bool)
    return float(np.median(se[lit] / e[lit])) if np.any(lit) else float("nan")


def cell_centres(origin: object, u: object, v: object, nu: int, nv: int) -> np.ndarray:
    """World positions of the cell centres of a grid sensor.

    Parameters
    ----------
    origin, u, v : (3,) float
        Corner and edge vectors of the sensor rectangle, metres.
    nu, nv : int
        Cells along ``u`` and along ``v``.

    Returns
    -------
    (nv, nu, 3) float
        Centre of cell ``(j, i)`` in metres, matching the layout of a grid result.
    """
    o, uu, vv = _check_frame(origin, u, v)
    if nu < 1 or nv < 1:
        raise MapError(f"nu and nv must be at least 1, got nu={nu}, nv={nv}")
    s = (np.arange(nu) + 0.5) / nu
    t = (np.arange(nv) + 0.5) / nv
    return o + s[None, :, None] * uu + t[:, None, None] * vv


def _axes_frame(o: np.ndarray, uu: np.ndarray, vv: np.ndarray) -> tuple[tuple[float, float, float, float], str, str]:
    """Extent and axis labels: world coordinates when u and v run along world axes, else metres along u, v."""
    names = "xyz"
    iu, iv = np.flatnonzero(uu), np.flatnonzero(vv)
    if len(iu) == 1 and len(iv) == 1 and iu[0] != iv[0] and uu[iu[0]] > 0 and vv[iv[0]] > 0:
        a, b = int(iu[0]), int(iv[0])
        extent = (float(o[a]), float(o[a] + uu[a]), float(o[b]), float(o[b] + vv[b]))
        return extent, f"{names[a]} (m)", f"{names[b]} (m)"
    return (0.0, float(np.linalg.norm(uu)), 0.0, float(np.linalg.norm(vv))), "along u (m)", "along v (m)"


def _canvas(width: float, height: float) -> Figure:
    """A figure of width x height inches on an Agg canvas; matplotlib is imported here, with the first picture a
    service process draws, not when the service starts (1.6 s of it)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _figure(aspect: float) -> tuple[Figure, Axes]:
    # Width fixed, height from the sensor's aspect ratio (clamped so labels stay legible).
    width = 7.0
    height = float(np.clip(width * aspect * 0.85 + 1.2, 3.5, 9.0))
    fig = _canvas(width, height)
    return fig, fig.add_subplot()


def figure_png(fig: Figure) -> bytes:
    """A figure's PNG bytes (every figure the service draws goes out through here)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def illuminance_map_png(lux: object, origin: object, u: object, v: object, **options: Any) -> bytes:
    """`illuminance_map_figure` as a PNG (the same arguments)."""
    return figure_png(illuminance_map_figure(lux, origin, u, v, **options))


def illuminance_map_figure(
    lux: object,
    origin: object,
    u: object,
    v: object,
    *,
    stderr: object | None = None,
    title: str | None = None,
    subtitle: str | None = None,
    vmax: float | None = None,
    vmin: float | None = None,
    scale: str = "zero",
) -> Figure:
    """A grid sensor's illuminance as a false-colour map with a labelled lux colour bar.

    Parameters
    ----------
    lux : (nv, nu) float
        Illuminance per cell, lx (row j runs along ``v``, column i along ``u``).
    origin, u, v : (3,) float
        The sensor rectangle, metres; only used for the axis extents and the caption.
    stderr : (nv, nu) float, optional
        Standard error per cell, lx; its median relative value goes into the caption, so the
        reader sees how noisy the picture is.
    title, subtitle : str, optional
        Heading lines; the subtitle defaults to min / mean / max, the uniformity min/mean with its standard error
        (`tracer.photometry.glare.uniformity`) and the noise figure.
    vmax, vmin : float, optional
        Top and bottom of the colour scale in lx (to show two maps on the same scale); default the maximum, and
        the bottom by `scale`.
    scale : "zero" | "data"
        Where the colour scale starts without `vmin`: at 0 lx (an isolux picture), or at the smallest cell, so
        that a near-uniform face's non-uniformity fills the colours.

    Returns
    -------
    Figure
        The matplotlib figure on an Agg canvas (`illuminance_map_png` saves it as a PNG).
    """
    e = _check_grid("lux", lux)
    if np.any(e < 0):
        raise MapError("lux must be non-negative")
    se = None if stderr is None else _check_grid("stderr", stderr, e.shape)
    o, uu, vv = _check_frame(origin, u, v)
    lu, lv = float(np.linalg.norm(uu)), float(np.linalg.norm(vv))
    bottom, top = _lux_range(e, vmax, vmin, scale)

    from matplotlib.colors import Normalize

    fig, ax = _figure(lv / lu)
    extent, xlabel, ylabel = _axes_frame(o, uu, vv)
    im = ax.imshow(e, origin="lower", extent=extent, cmap="turbo",
                   norm=Normalize(bottom, top), interpolation="nearest", aspect="equal")
    bar = fig.colorbar(im, ax=ax, shrink=0.9)
    bar.set_label("Illuminance E (lx)" + (", scale from the smallest cell" if bottom > 0 and vmin is None else ""))
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    nv, nu = e.shape
    caption = subtitle if subtitle is not None else _lux_caption(e, se)
    heading = title or "Illuminance"
    ax.set_title(f"{heading}\n{caption}", fontsize=9)
    fig.text(0.01, 0.005, f"grid {nu}×{nv} cells, origin ({o[0]:.3g}, {o[1]:.3g}, {o[2]:.3g}) m",
             fontsize=7, color="0.35")
    return fig


def _lux_range(e: np.ndarray, vmax: float | None, vmin: float | None, scale: str) -> tuple[float, float]:
    """(bottom, top) of a lux map's colour scale, lx: the stated ends, else 0 (``scale`` "zero") or the smallest
    cell ("data") up to the largest; a flat map gets a scale of some width about its value."""
    top = float(e.max()) if vmax is None else float(vmax)
    if not np.isfinite(top) or top < 0:
        raise MapError(f"vmax must be a non-negative finite number, got {vmax!r}")
    if scale not in ("zero", "data"):
        raise MapError(f"scale must be 'zero' or 'data', got {scale!r}")
    bottom = float(vmin) if vmin is not None else (float(e.min()) if scale == "data" else 0.0)
    if not np.isfinite(bottom) or bottom < 0:
        raise MapError(f"vmin must be a non-negative finite number, got {vmin!r}")
    if top <= bottom:   # a flat map (or a stated range the caller checked): a scale of some width about it
        top = bottom + (0.01 * bottom if bottom > 0 else 1.0)
    return bottom, top


def _lux_caption(e: np.ndarray, se: np.ndarray | None) -> str:
    """min / mean / max, then the uniformity min/mean (± its standard error) and the noise figure: two short lines,
    so that a narrow map does not cut them off."""
    caption = f"min {e.min():.4g} lx · mean {e.mean():.4g} lx · max {e.max():.4g} lx"
    second = []
    if e.mean() > 0:
        from tracer.photometry.glare import uniformity

        u = uniformity(e, se)
        second.append(f"uniformity min/mean {u['min_mean']:.3f}"
                      + (f" ± {u['min_mean_stderr']:.3f}" if se is not None else ""))
    if se is not None:
        rel = median_relative_error(e, se)
        if np.isfinite(rel):
            second.append(f"median std. error {100 * rel:.2g} % (lit cells)")
    if second:
        caption += "\n" + " · ".join(second)
    return caption


#: CIE XYZ → linear sRGB (IEC 61966-2-1, D65 white)
_XYZ_TO_SRGB = np.array([[3.2406, -1.5372, -0.4986], [-0.9689, 1.8758, 0.0415], [0.0557, -0.2040, 1.0570]])


def chromaticity_rgb(cie_xy: object, lux: object) -> np.ndarray:
    """Display colours of light: (…, 2) CIE 1931 xy and (…) lux → (…, 3) sRGB in [0, 1].

    The hue is the light's own (out-of-gamut colours, such as a spectral line, are clipped to the gamut's
    edge and scaled down to fit), the brightness ∝ lux / max lux; cells without light (xy null/NaN) are black.
    """
    xy = np.asarray(cie_xy, dtype=float)
    e = np.asarray(lux, dtype=float)
    top = float(e.max()) if e.size and e.max() > 0 else 1.0
    x, y = xy[..., 0], xy[..., 1]
    ok = np.isfinite(x) & np.isfinite(y) & (y > 0)
    big_y = np.where(ok, e / top, 0.0)
    safe_y = np.where(ok, y, 1.0)
    xyz = np.stack([big_y * np.where(ok, x, 0) / safe_y, big_y, big_y * np.where(ok, 1 - x - y, 0) / safe_y], -1)
    rgb = np.clip(xyz @ _XYZ_TO_SRGB.T, 0.0, None)
    peak = rgb.max(axis=-1, keepdims=True)
    rgb = np.where(peak > 1.0, rgb / np.where(peak > 0, peak, 1.0), rgb)
    return np.where(rgb <= 0.0031308, 12.92 * rgb, 1.055 * np.power(rgb, 1 / 2.4) - 0.055)


def colour_map_png(cie_xy: object, lux: object, origin: object, u: object, v: object, *,
                   title: str | None = None) -> bytes:
    """Render a grid sensor's light as the colour it has (`chromaticity_rgb`), brightness by illuminance."""
    e = _check_grid("lux", lux)
    xy = np.asarray(cie_xy, dtype=float)
    if xy.shape != e.shape + (2,):
        raise MapError(f"cie_xy must have shape {e.shape + (2,)}, got {xy.shape}")
    o, uu, vv = _check_frame(origin, u, v)
    fig, ax = _figure(float(np.linalg.norm(vv)) / float(np.linalg.norm(uu)))
    extent, xlabel, ylabel = _axes_frame(o, uu, vv)
    ax.imshow(chromaticity_rgb(xy, e), origin="lower", extent=extent, interpolation="nearest", aspect="equal")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    lit = np.isfinite(xy[..., 0])
    mean_xy = np.nanmean(xy[lit], axis=0) if lit.any() else (math.nan, math.nan)
    ax.set_title(f"{title or 'Colour of the light'}\nCIE 1931 mean x {mean_xy[0]:.4f}, y {mean_xy[1]:.4f} · "
                 f"brightness ∝ illuminance (max {e.max():.4g} lx)", fontsize=9)
    return figure_png(fig)



def difference_map_png(
    lux_before: object,
    lux_after: object,
    origin: object,
    u: object,
    v: object,
    *,
    stderr_before: object | None = None,
    stderr_after: object | None = None,
    title: str | None = None,
) -> bytes:
    """Render ``after − before`` on a diverging scale centred on zero, flagging insignificant cells.

    Parameters
    ----------
    lux_before, lux_after : (nv, nu) float
        Illuminance of the same grid at two revisions, lx.
    origin, u, v : (3,) float
        The sensor rectangle, metres.
    stderr_before, stderr_after : (nv, nu) float, optional
        Standard errors, lx. Given both, cells whose change is within ``SIGNIFICANCE_SIGMAS``
        combined standard errors are marked with a grey dot: Monte Carlo noise alone can
        colour them.
    title : str, optional
        Heading line.

    Returns
    -------
    bytes
        A PNG image.
    """
    before = _check_grid("lux_before", lux_before)
    after = _check_grid("lux_after", lux_after, before.shape)
    o, uu, vv = _check_frame(origin, u, v)
    sigma = None
    if stderr_before is not None and stderr_after is not None:
        sb = _check_grid("stderr_before", stderr_before, before.shape)
        sa = _check_grid("stderr_after", stderr_after, before.shape)
        sigma = np.hypot(sb, sa)
    delta = after - before
    lu, lv = float(np.linalg.norm(uu)), float(np.linalg.norm(vv))
    span = float(np.abs(delta).max())
    span = span if span > 0 else 1.0

    from matplotlib.colors import TwoSlopeNorm

    fig, ax = _figure(lv / lu)
    extent, xlabel, ylabel = _axes_frame(o, uu, vv)
    im = ax.imshow(delta, origin="lower", extent=extent, cmap="RdBu_r",
                   norm=TwoSlopeNorm(0.0, -span, span), interpolation="nearest", aspect="equal")
    bar = fig.colorbar(im, ax=ax, shrink=0.9)
    bar.set_label("ΔE = after − before (lx)")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    nv, nu = delta.shape
    rise = f"largest rise {delta.max():+.4g} lx" if delta.max() > 0 else "no rise"
    fall = f"largest fall {delta.min():+.4g} lx" if delta.min() < 0 else "no fall"
    caption = f"{rise} · {fall}"
    if sigma is not None:
        quiet = np.abs(delta) <= SIGNIFICANCE_SIGMAS * sigma
        caption += f" · {int((~quiet).sum())}/{delta.size} cells changed beyond {SIGNIFICANCE_SIGMAS:g}σ"
        if delta.size <= _MAX_DOTTED_CELLS and np.any(quiet):
            jj, ii = np.nonzero(quiet)
            x0, x1, y0, y1 = extent
            ax.scatter(x0 + (ii + 0.5) / nu * (x1 - x0), y0 + (jj + 0.5) / nv * (y1 - y0), s=2.0, c="0.45", marker=".",
                       label=f"|ΔE| ≤ {SIGNIFICANCE_SIGMAS:g}σ (noise)")
            ax.legend(loc="upper right", fontsize=7, framealpha=0.8)
    ax.set_title(f"{title or 'Change in illuminance'}\n{caption}", fontsize=9)
    fig.text(0.01, 0.005, f"grid {nu}×{nv} cells, origin ({o[0]:.3g}, {o[1]:.3g}, {o[2]:.3g}) m",
             fontsize=7, color="0.35")
    return figure_png(fig)


def summarize_change(
    lux_before: object,
    lux_after: object,
    origin: object,
    u: object,
    v: object,
    *,
    stderr_before: object,
    stderr_after: object,
) -> ChangeSummary:
    """Say where a grid's illuminance changed beyond noise.

    Parameters
    ----------
    lux_before, lux_after, stderr_before, stderr_after : (nv, nu) float
        Two results of the same grid sensor and their standard errors, lx.
    origin, u, v : (3,) float
        The sensor rectangle, metres (to name cell positions in world coordinates).

    Returns
    -------
    ChangeSummary
    """
    before = _check_grid("lux_before", lux_before)
    after = _check_grid("lux_after", lux_after, before.shape)
    sb = _check_grid("stderr_before", stderr_before, before.shape)
    sa = _check_grid("stderr_after", stderr_after, before.shape)
    nv, nu = before.shape
    centres = cell_centres(origin, u, v, nu, nv)
    delta = after - before
    significant = np.abs(delta) > SIGNIFICANCE_SIGMAS * np.hypot(sb, sa)
    j_up, i_up = np.unravel_index(int(np.argmax(delta)), delta.shape)
    j_dn, i_dn = np.unravel_index(int(np.argmin(delta)), delta.shape)
    return ChangeSummary(
        cells=int(delta.size),
        significant=int(significant.sum()),
        increased=int((significant & (delta > 0)).sum()),
        decreased=int((significant & (delta < 0)).sum()),
        max_increase_lux=max(0.0, float(delta.max())),
        max_increase_at=tuple(float(x) for x in centres[j_up, i_up]),  # type: ignore[arg-type]
        max_decrease_lux=max(0.0, float(-delta.min())),
        max_decrease_at=tuple(float(x) for x in centres[j_dn, i_dn]),  # type: ignore[arg-type]
        mean_before_lux=float(before.mean()),
        mean_after_lux=float(after.mean()),
    )


#: a luminance map is drawn on a log scale where its lit pixels span more than this ratio
LOG_SCALE_RATIO = 100.0


def luminance_map_png(luminance: object, *, stderr: object | None = None, title: str | None = None,
                      vmax: float | None = None) -> bytes:
    """Render a camera's image as a false-colour map with a labelled cd/m² colour bar (log scale where the lit
    pixels span more than `LOG_SCALE_RATIO`).

    Parameters
    ----------
    luminance : (height, width) float
        Luminance per pixel, cd/m², row 0 the top of the image.
    stderr : (height, width) float, optional
        Standard error per pixel, cd/m²; its median relative value (lit pixels) goes into the caption.
    title : str, optional
        Heading line.
    vmax : float, optional
        Top of the colour scale in cd/m²; default the maximum.

    Returns
    -------
    bytes
        A PNG image.
    """
    from matplotlib.colors import LogNorm, Normalize

    lum = _check_grid("luminance", luminance)
    if np.any(lum < 0):
        raise MapError("luminance must be non-negative")
    se = None if stderr is None else _check_grid("stderr", stderr, lum.shape)
    top = float(lum.max()) if vmax is None else float(vmax)
    top = top if top > 0 else 1.0
    lit = lum[lum > 0]
    low = float(lit.min()) if lit.size else top
    floor = max(low, top / 1e6)
    log = top / low > LOG_SCALE_RATIO
    norm = LogNorm(floor, top) if log else Normalize(0.0, top)
    h, w = lum.shape
    fig, ax = _figure(h / w)
    im = ax.imshow(np.where(lum > 0, lum, floor) if log else lum, origin="upper",
                   cmap="turbo", norm=norm, interpolation="nearest", aspect="equal")
    bar = fig.colorbar(im, ax=ax, shrink=0.9)
    bar.set_label("Luminance L (cd/m²)" + (", log scale" if log else ""))
    ax.set_xticks([])
    ax.set_yticks([])
    caption = f"min {lum.min():.4g} · mean {lum.mean():.4g} · max {lum.max():.4g} cd/m²"
    if se is not None:
        rel = median_relative_error(lum, se)
        if np.isfinite(rel):
            caption += f" · median std. error {100 * rel:.2g} % (lit pixels)"
    ax.set_title(f"{title or 'Luminance'}\n{caption}", fontsize=9)
    fig.text(0.01, 0.005, f"camera {w}×{h} pixels", fontsize=7, color="0.35")
    return figure_png(fig)


def conoscope_figure(answer: dict[str, Any]) -> Figure:
    """A conoscopic view (``POST …/luminance/conoscope``'s answer) as a polar plot: the azimuth around, the polar
    angle from the normal outwards (degrees), each reading a cell of a cd/m² colour scale from the smallest reading
    to the largest (so that a near-flat view shows its variation), the half-luminance angle as a dashed ring, the
    on-axis luminance, that angle and the flatness min/max with their standard errors in the title."""
    theta = np.asarray(answer["theta_deg"], float)
    phi = np.radians(np.asarray(answer["phi_deg"], float))
    lum = _check_grid("luminance", answer["luminance"], (len(theta), len(phi)))
    step_t = theta[1] - theta[0]
    step_p = 2.0 * math.pi / len(phi)
    r_edges = np.concatenate([[0.0], theta[:-1] + step_t / 2.0, [theta[-1] + step_t / 2.0]])
    p_edges = np.concatenate([phi - step_p / 2.0, [phi[-1] + step_p / 2.0]])
    from matplotlib.colors import Normalize
    from matplotlib.ticker import MaxNLocator

    fig = _canvas(6.4, 6.0)
    ax: Any = fig.add_subplot(projection="polar")   # a PolarAxes
    lo, hi = float(lum.min()), float(lum.max())
    mesh = ax.pcolormesh(p_edges, r_edges, lum, cmap="turbo", shading="flat",
                         norm=Normalize(lo, hi if hi > lo else lo + max(abs(lo), 1.0) * 1e-6))
    ax.set_ylim(0.0, r_edges[-1])
    ax.set_rlabel_position(22.5)
    ax.yaxis.set_major_locator(MaxNLocator(5))
    ax.yaxis.set_major_formatter(lambda x, _: f"{x:g}°")
    bar = fig.colorbar(mesh, ax=ax, shrink=0.8, pad=0.08)
    bar.set_label("Luminance L (cd/m²)")
    flat = answer["flatness"]
    ratio = "—" if flat.get("min_max") is None else f"{flat['min_max']:.4g} ± {flat['min_max_stderr']:.2g}"
    spread = answer.get("half_angle_deg")
    if spread is not None and answer.get("half_angle_within_view"):
        ax.plot(np.linspace(0.0, 2.0 * math.pi, 181), np.full(181, spread), color="white", ls="--", lw=1.2)
        spread_text = f"{spread:.1f} ± {answer['half_angle_stderr']:.1f}°"
    else:
        spread_text = "—" if spread is None else f"≥ {spread:g}°"
    ax.set_title(f"Conoscopic view: luminance against viewing angle\non axis {answer['on_axis']:.4g} ± "
                 f"{answer['on_axis_stderr']:.2g} cd/m² · half-luminance angle {spread_text} · min/max {ratio}",
                 fontsize=9)
    fig.text(0.01, 0.005, f"polar angle from the normal, 0-{theta[-1]:g}°; azimuth from phi_zero; "
             f"{answer['aperture_deg']:g}° meters", fontsize=7, color="0.35")
    return fig


def uniformity_figure(answer: dict[str, Any]) -> Figure:
    """Luminance meters' readings (``POST …/luminance/uniformity``'s answer) where they look on the lit face: each
    point marked and numbered, coloured on a cd/m² scale from the smallest reading to the largest and labelled with
    its reading ± error; the two world axes along which the points spread most, in mm; the figure's uniformity
    (min/max, min/mean) with its standard errors in the title."""
    pts = np.asarray(answer["points"], float)
    lum, err = np.asarray(answer["luminance"], float), np.asarray(answer["stderr"], float)
    a, b = (int(k) for k in np.argsort(np.ptp(pts, axis=0))[::-1][:2])
    x, y = 1000.0 * pts[:, a], 1000.0 * pts[:, b]
    from matplotlib.colors import Normalize

    fig = _canvas(7.0, 5.2)
    ax = fig.add_subplot()
    lo, hi = float(lum.min()), float(lum.max())
    dots = ax.scatter(x, y, c=lum, s=260, cmap="turbo", edgecolors="black",
                      norm=Normalize(lo, hi if hi > lo else lo + max(abs(lo), 1.0) * 1e-6))
    for k in range(len(lum)):
        ax.annotate(f"{k + 1}: {lum[k]:.4g} ± {err[k]:.2g}", (x[k], y[k]), textcoords="offset points",
                    xytext=(0, 12), ha="center", fontsize=7)
    ax.margins(0.15)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set(xlabel=f"world {'xyz'[a]} (mm)", ylabel=f"world {'xyz'[b]} (mm)")
    fig.colorbar(dots, ax=ax, shrink=0.8).set_label("Luminance L (cd/m²), min to max")
    u = answer["uniformity"]

    def pm(name: str) -> str:
        return "—" if u.get(name) is None else f"{u[name]:.3f} ± {u[f'{name}_stderr']:.3f}"

    ax.set_title(f"{answer['figure']} luminance uniformity: min/max {pm('min_max')} · min/mean {pm('min_mean')}\n"
                 f"mean {u['mean']:.4g} cd/m² · {answer['aperture_deg']:g}° meters", fontsize=9)
    return fig


def uniformity_png(answer: dict[str, Any]) -> bytes:
    """`uniformity_figure` as a PNG."""
    return figure_png(uniformity_figure(answer))


def conoscope_png(answer: dict[str, Any]) -> bytes:
    """`conoscope_figure` as a PNG."""
    return figure_png(conoscope_figure(answer))
