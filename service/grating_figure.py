"""A grating's order efficiencies against the wavelength, as a PNG (``GET /elements/{id}/orders.png``, issue 52).

One table point's angles (a polar angle and an azimuth the table was solved at, lit from the ambient or from the
substrate): each order that carries at least `SHOWN` of the light somewhere in the table's wavelengths is a line,
transmitted solid, reflected dashed, the unpolarized efficiency (the mean of s and p) against the wavelength, the
sum of all orders beside them (1 for a lossless relief, less where a metal absorbs). Built with matplotlib's
object-oriented API on an Agg canvas and written by `service.maps.figure_png`, as the maps are.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from service.errors import Invalid
from service.maps import figure_png

SHOWN = 0.005   # an order below this efficiency everywhere on the plot is left out (it would be a line on zero)
LIT_FROM = ("ambient", "substrate")


def _index(values: np.ndarray, x: float | None, name: str) -> int:
    """The table's index of angle `x` (degrees; None: the first), else a 422 listing the angles it holds."""
    if x is None:
        return 0
    hit = np.flatnonzero(np.isclose(values, x, rtol=0.0, atol=1e-9))
    if not len(hit):
        raise Invalid(f"{name} {x:g} is not one of the table's angles: give one of {[float(v) for v in values]}")
    return int(hit[0])


def orders_png(table: Any, polar_deg: float | None = None, azimuth_deg: float | None = None,
               lit_from: str = "ambient") -> bytes:
    """The figure (module docstring) of a `tracer.elements.grating.GratingTable`; a 422 (`Invalid`) naming the field
    for an angle the table was not solved at or an unknown `lit_from`."""
    if lit_from not in LIT_FROM:
        raise Invalid(f"lit_from must be one of {list(LIT_FROM)}, got {lit_from!r}")
    a = _index(table.polar_deg, polar_deg, "polar_deg")
    z = _index(table.azimuth_deg, azimuth_deg, "azimuth_deg")
    tab = table if lit_from == "ambient" or table.inside is None else table.inside
    wl = np.asarray(table.wavelength_nm, float)
    eff = np.asarray(tab.unpolarized[:, a, z], float)    # (W, side, K), NaN where an order does not propagate
    two_d = bool(np.any(table.orders[:, 1]))
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.0, 4.2), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    marker = "o" if len(wl) < 12 else None
    for side, style, word in ((1, "-", "T"), (0, "--", "R")):
        for k, (m, n) in enumerate(table.orders):
            y = eff[:, side, k]
            if not np.nanmax(np.nan_to_num(y, nan=0.0)) >= SHOWN:
                continue
            label = f"{word} {m:+d}" + (f",{n:+d}" if two_d else "")
            ax.plot(wl, y, style, marker=marker, label=label)
    ax.plot(wl, np.nansum(eff, axis=(1, 2)), ":", color="black", label="sum")
    ax.set_xlabel("wavelength (nm)")
    ax.set_ylabel("efficiency (unpolarized)")
    ax.set_ylim(0.0, 1.05)
    medium = "ambient" if lit_from == "ambient" else "substrate"
    ax.set_title(f"orders at polar {table.polar_deg[a]:g}°, azimuth {table.azimuth_deg[z]:g}° (lit from the "
                 f"{medium}; T transmitted, R reflected)", fontsize=9)
    ax.legend(fontsize=7, ncols=2, loc="center left", bbox_to_anchor=(1.0, 0.5))
    ax.grid(alpha=0.3)
    return figure_png(fig)
