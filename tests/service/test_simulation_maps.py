"""False-colour maps: readable PNGs, the cell layout, the change summary, and refused inputs."""

from __future__ import annotations

import io

import matplotlib.image as mpimg
import numpy as np
import pytest

from service.maps import (
    MapError,
    cell_centres,
    difference_map_png,
    illuminance_map_png,
    summarize_change,
)

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
FRAME = ([1.0, -2.0, 0.0], [4.0, 0.0, 0.0], [0.0, 2.0, 0.0])


def decode(png: bytes) -> np.ndarray:
    assert png.startswith(PNG_SIGNATURE)
    return mpimg.imread(io.BytesIO(png), format="png")


def test_map_is_a_png_that_shows_varying_colour(rng: np.random.Generator) -> None:
    lux = rng.uniform(0, 500, size=(10, 20))
    image = decode(illuminance_map_png(lux, *FRAME, stderr=0.01 * lux, title="floor"))
    assert image.ndim == 3 and image.shape[0] > 200 and image.shape[1] > 400
    # many distinct colours: the data is drawn, not a blank canvas
    assert len(np.unique(image.reshape(-1, image.shape[2])[:, :3], axis=0)) > 50


def test_uniform_and_zero_grids_render() -> None:
    decode(illuminance_map_png(np.zeros((3, 3)), *FRAME))
    decode(illuminance_map_png(np.full((1, 1), 7.0), *FRAME, vmax=10.0))
    decode(difference_map_png(np.ones((2, 2)), np.ones((2, 2)), *FRAME))


def test_a_map_scaled_to_the_data_runs_its_colours_from_the_smallest_cell_and_states_the_uniformity() -> None:
    """A near-uniform face (95 to 105 lx): from 0 its cells would share the top tenth of the colours; scaled to the
    data they span them all. The caption gives min/mean with the delta method's error
    (`tracer.photometry.glare.uniformity`)."""
    from service.maps import illuminance_map_figure

    lux = np.array([[95.0, 100.0, 105.0], [100.0, 101.0, 99.0], [104.0, 98.0, 100.0]])
    se = np.full_like(lux, 1.0)
    norm = illuminance_map_figure(lux, *FRAME, stderr=se).axes[0].images[0].norm
    assert (norm.vmin, norm.vmax) == (0.0, 105.0)
    fig = illuminance_map_figure(lux, *FRAME, stderr=se, scale="data")
    norm = fig.axes[0].images[0].norm
    assert (norm.vmin, norm.vmax) == (95.0, 105.0)
    from tracer.photometry.glare import uniformity

    u = uniformity(lux, se)
    assert u["min_mean"] == 95.0 / lux.mean() and u["min_mean_stderr"] > 0
    title = fig.axes[0].get_title()
    assert f"uniformity min/mean {u['min_mean']:.3f} ± {u['min_mean_stderr']:.3f}" in title and "\n" in title
    stated = illuminance_map_figure(lux, *FRAME, vmin=50.0, vmax=150.0, scale="data").axes[0].images[0].norm
    assert (stated.vmin, stated.vmax) == (50.0, 150.0)
    flat = illuminance_map_figure(np.full((2, 2), 7.0), *FRAME, scale="data").axes[0].images[0].norm
    assert flat.vmin == 7.0 and flat.vmax > 7.0   # a flat map still has a scale


def test_cell_centres_follow_the_grid_layout() -> None:
    c = cell_centres(*FRAME, nu=4, nv=2)
    assert c.shape == (2, 4, 3)
    # row j along v, column i along u: the centre of cell (j, i) is origin + (i+½)/nu u + (j+½)/nv v
    np.testing.assert_allclose(c[0, 0], [1.5, -1.5, 0.0])
    np.testing.assert_allclose(c[1, 3], [4.5, -0.5, 0.0])


def test_change_summary_finds_the_significant_cells() -> None:
    before = np.full((4, 5), 100.0)
    after = before.copy()
    after[3, 1] = 180.0  # +80 lx, far beyond 2σ
    after[0, 4] = 40.0  # −60 lx
    after[2, 2] = 101.0  # +1 lx, within noise (σ = hypot(1, 1) ≈ 1.4 lx)
    se = np.ones_like(before)
    s = summarize_change(before, after, *FRAME, stderr_before=se, stderr_after=se)
    assert (s.cells, s.significant, s.increased, s.decreased) == (20, 2, 1, 1)
    assert s.max_increase_lux == pytest.approx(80.0) and s.max_decrease_lux == pytest.approx(60.0)
    np.testing.assert_allclose(s.max_increase_at, cell_centres(*FRAME, 5, 4)[3, 1])
    np.testing.assert_allclose(s.max_decrease_at, cell_centres(*FRAME, 5, 4)[0, 4])
    assert s.mean_after_lux - s.mean_before_lux == pytest.approx((80 - 60 + 1) / 20)
    decode(difference_map_png(before, after, *FRAME, stderr_before=se, stderr_after=se))


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: illuminance_map_png(np.ones(5), *FRAME), "2-d"),
        (lambda: illuminance_map_png(np.ones((2, 0)), *FRAME), "at least one cell"),
        (lambda: illuminance_map_png(np.array([[1.0, np.nan]]), *FRAME), "NaN"),
        (lambda: illuminance_map_png(-np.ones((2, 2)), *FRAME), "non-negative"),
        (lambda: illuminance_map_png(np.ones((2, 2)), [0, 0], [1, 0, 0], [0, 1, 0]), "origin"),
        (lambda: illuminance_map_png(np.ones((2, 2)), [0, 0, 0], [0, 0, 0], [0, 1, 0]), "non-zero"),
        (lambda: illuminance_map_png(np.ones((2, 2)), *FRAME, stderr=np.ones((3, 2))), "shape"),
        (lambda: illuminance_map_png(np.ones((2, 2)), *FRAME, vmax=float("inf")), "vmax"),
        (lambda: illuminance_map_png(np.ones((2, 2)), *FRAME, vmin=-1.0), "vmin"),
        (lambda: illuminance_map_png(np.ones((2, 2)), *FRAME, scale="log"), "scale"),
        (lambda: difference_map_png(np.ones((2, 2)), np.ones((2, 3)), *FRAME), "shape"),
        (lambda: cell_centres(*FRAME, nu=0, nv=2), "at least 1"),
    ],
)
def test_bad_inputs_are_refused_with_a_reason(call, message: str) -> None:
    with pytest.raises(MapError, match=message):
        call()


def test_axes_show_world_coordinates_when_the_grid_is_axis_aligned() -> None:
    from service.maps import _axes_frame

    extent, xl, yl = _axes_frame(*(np.asarray(a, float) for a in FRAME))
    assert extent == (1.0, 5.0, -2.0, 0.0) and (xl, yl) == ("x (m)", "y (m)")
    # a wall grid: u along y, v along z
    extent, xl, yl = _axes_frame(np.array([0.0, 1.0, 0.5]), np.array([0.0, 3.0, 0.0]), np.array([0.0, 0.0, 2.0]))
    assert extent == (1.0, 4.0, 0.5, 2.5) and (xl, yl) == ("y (m)", "z (m)")
    # tilted or reversed: metres along u and v
    for u in ([1.0, 1.0, 0.0], [-1.0, 0.0, 0.0]):
        extent, xl, _ = _axes_frame(np.zeros(3), np.array(u), np.array([0.0, 0.0, 1.0]))
        assert extent[0] == 0.0 and extent[1] == pytest.approx(np.linalg.norm(u)) and xl == "along u (m)"
