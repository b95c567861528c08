"""The demo-guide's figures (issue 54, item 8): compared maps on one colour scale that spans the data (not from 0),
every title and label inside the saved picture, and axes named alike for the same axis, with units; the pack's
picture names the element's face frame and the sensor grid's world axes apart. Checked on the matplotlib figures,
without running the demo."""

from __future__ import annotations

import io

import numpy as np
from matplotlib.image import AxesImage
from matplotlib.text import Text

from lumenlink.guide_demo import GRID, compare_figure
from service.pack import plot_figure

UNIFORM = np.array([[905.0, 950.0, 921.0], [1002.0, 1051.0, 990.0], [1060.0, 1102.0, 1080.0]])
GRADED = np.array([[990.0, 1010.0, 995.0], [1001.0, 1020.0, 1005.0], [985.0, 1012.0, 998.0]])


def _inside(fig) -> list[str]:
    """The texts that reach outside the figure once it is drawn as saved (a PNG), with their extents: the titles,
    axis labels (colour bars' too), tick labels in view, the suptitle and the texts drawn in the axes."""
    fig.savefig(io.BytesIO(), format="png")
    renderer = fig.canvas.get_renderer()
    box = fig.bbox
    out = []
    texts: list[Text] = [fig._suptitle] if fig._suptitle is not None else []
    for ax in fig.axes:
        texts += [ax.title, ax.xaxis.label, ax.yaxis.label, *ax.texts]
        for axis in (ax.xaxis, ax.yaxis):   # the ticks it draws (in view), as matplotlib's draw picks them
            texts += [label for tick in axis._update_ticks() for label in (tick.label1, tick.label2)]
    for t in texts:
        if not t.get_visible() or not t.get_text().strip():
            continue
        e = t.get_window_extent(renderer)
        if e.x0 < box.x0 - 0.5 or e.y0 < box.y0 - 0.5 or e.x1 > box.x1 + 0.5 or e.y1 > box.y1 + 0.5:
            out.append(f"{t.get_text()!r} at {e.bounds} in {box.bounds}")
    return out


def test_compared_maps_share_one_scale_spanning_the_data_and_name_their_axes_alike() -> None:
    fig = compare_figure([("uniform", UNIFORM, UNIFORM * 0.01), ("graded", GRADED, GRADED * 0.01)], GRID,
                         title="the lit face, two dot patterns (400,000 photons each)")
    images = [im for ax in fig.axes for im in ax.get_images() if isinstance(im, AxesImage)]
    assert len(images) == 2
    norms = {(im.norm.vmin, im.norm.vmax) for im in images}
    assert norms == {(905.0, 1102.0)}          # one scale, the data's min to max (> 0, not from 0)
    maps = [ax for ax in fig.axes if ax.get_images()]
    assert len({ax.get_xlabel() for ax in maps}) == 1 and len({ax.get_ylabel() for ax in maps}) == 1
    assert "x (mm)" in maps[0].get_xlabel() and "y (mm)" in maps[0].get_ylabel()
    # the grid's u runs along world y, its v along world x: the picture's x extent is the grid's v, in mm
    assert np.allclose(images[0].get_extent(), [10.0, 110.0, 10.0, 70.0])
    # cell (row j along v = x, column i along u = y) sits where it is on the face: the image is the transpose
    assert np.array_equal(images[0].get_array(), UNIFORM.T)
    assert _inside(fig) == []


def test_the_pack_picture_keeps_its_texts_inside_and_names_each_frame_with_units() -> None:
    lux = UNIFORM
    record = {"fill": (np.ones((8, 24)) * np.linspace(0.3, 0.9, 24)).tolist(), "lux": lux.tolist(),
              "figure": "min_max", "uniformity": 0.821, "uniformity_stderr": 0.012, "target": 0.95,
              "stopped": "target", "grid": {k: GRID[k] for k in ("origin", "u", "v")},
              "history": [{"iteration": i, "uniformity": 0.8 + 0.03 * i, "stderr": 0.01, "seconds": 3.0}
                          for i in range(4)]}
    record["history"][-1]["confirmation"] = {"uniformity": 0.86, "stderr": 0.01, "photons": 1000, "seed": 1,
                                             "confirmed": False}   # drawn beside its reading, in the legend
    fig = plot_figure(record, {"origin_mm": [0, 0], "size_mm": [120, 80], "pitch_mm": 0.6})
    density, measured = (ax for ax in fig.axes if ax.get_images())
    assert (density.get_xlabel(), density.get_ylabel()) == ("element u on the face (mm)",
                                                            "element v on the face (mm)")
    assert (measured.get_xlabel(), measured.get_ylabel()) == ("world y (mm)", "world x (mm)")
    labels = [ax.get_xlabel() for ax in (density, measured)] + [ax.get_ylabel() for ax in (density, measured)]
    assert len(set(labels)) == 4 and all("(mm)" in x for x in labels)   # no bare "u" naming two axes
    im = measured.get_images()[0]
    assert (im.norm.vmin, im.norm.vmax) == (905.0, 1102.0)
    assert np.allclose(im.get_extent(), [10.0, 70.0, 10.0, 110.0])
    history = next(ax for ax in fig.axes if ax.get_legend() is not None)
    assert "fresh-seed confirmation" in [t.get_text() for t in history.get_legend().get_texts()]
    assert _inside(fig) == []
