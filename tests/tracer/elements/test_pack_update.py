"""The pack's update rule (issue 41; `tracer.elements.pack`) on arrays whose answer is known: no change where the
map is flat or a deviation is within its noise, the sensor's correction carried exactly onto the support where the
cells coincide, the fill kept in [0, max_fill], and the refusals."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracer.elements import prepare
from tracer.elements.pack import MAX_STEP, NOISE_SIGMAS, PackError, check, correction, density_body, on_support, update

BODY = {"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.25, "height_mm": 0.1},
        "layout": {"type": "density", "origin_mm": [0.0, 0.0], "size_mm": [30.0, 20.0], "fill": [[0.5] * 3] * 2,
                   "seed": 1, "pitch_mm": 0.6}}


def test_a_flat_map_or_a_deviation_within_its_noise_changes_nothing() -> None:
    lux = np.full((3, 3), 100.0)
    d, worst, _ = correction(lux, np.full((3, 3), 1.0))
    assert not d.any() and worst == 0.0
    lux[1, 1] = 101.5   # 1.5 % off, its error 1 %: within 2 sigma
    d, _, typical = correction(lux, np.full((3, 3), 1.0))
    assert not d.any() and typical == pytest.approx(0.01, rel=0.02)
    lux[1, 1] = 150.0   # far off: the log-deviation less 2 sigma, capped
    d, _, _ = correction(lux, np.full((3, 3), 1.0))
    mean = lux.mean()
    assert d[1, 1] == pytest.approx(math.log(mean / 150.0) + NOISE_SIGMAS * 1.0 / 150.0)
    assert d[0, 0] == pytest.approx(math.log(mean / 100.0) - NOISE_SIGMAS * 0.01)
    assert correction(np.array([[1.0, 1000.0]]), np.zeros((1, 2)))[0].max() == pytest.approx(MAX_STEP)


def test_the_correction_lands_on_the_map_cells_the_sensor_cells_cover() -> None:
    # a 2 x 3 map over a 30 x 20 mm face, the sensor's cells the same rectangles (world = mm / 1000, z up)
    sensor = {"type": "grid", "origin": [0.0, 0.0, 0.003], "u": [0.03, 0.0, 0.0], "v": [0.0, 0.02, 0.0], "nu": 3,
              "nv": 2}
    d = np.array([[0.1, -0.2, 0.3], [0.0, 0.4, -0.1]])
    got = on_support(d, sensor, (2, 3), BODY["layout"], np.zeros(3), np.array([1e-3, 0, 0]), np.array([0, 1e-3, 0]))
    # bilinear between centres, clamped at the edges: each map cell the mean of its 5 x 5 samples; row 0, column 0
    # in closed form (its samples short of the centre clamped, those past it pulled toward column 1 and row 1)
    k = (np.arange(5) + 0.5) / 5
    assert got.shape == (2, 3)
    fx_ = np.clip(k - 0.5, 0.0, None)
    fy = np.clip(k - 0.5, 0.0, None)
    expect = np.mean([(1 - a) * (1 - b) * d[0, 0] + a * (1 - b) * d[0, 1] + (1 - a) * b * d[1, 0] + a * b * d[1, 1]
                      for b in fy for a in fx_])
    assert got[0, 0] == pytest.approx(expect)
    flat = on_support(np.full((2, 3), 0.25), sensor, (4, 7), BODY["layout"], np.zeros(3), np.array([1e-3, 0, 0]),
                      np.array([0, 1e-3, 0]))
    assert np.allclose(flat, 0.25)   # a uniform correction is uniform on any map


def test_the_fill_stays_in_its_range_and_a_cell_that_cannot_rise_pulls_the_rest_down() -> None:
    fill = np.array([[0.2, 0.5, 0.9]])
    d = np.array([[0.0, 0.0, math.log(2.0)]])
    new = update(fill, d, 1.0, 1.0)
    assert new.max() == pytest.approx(1.0) and new[0, 0] == pytest.approx(0.2 / 1.8)
    assert update(np.array([[0.0, 0.5]]), np.array([[0.5, 0.0]]), 1.0, 1.0)[0, 0] > 0   # 0 can rise
    assert np.all(update(fill, -np.ones_like(fill), 0.5, 0.6) >= 0)


@pytest.mark.parametrize("kwargs, field", [({"target": 1.01}, "target"), ({"target": 0.0}, "target"),
                                           ({"target": True}, "target"), ({"damping": 0}, "damping"),
                                           ({"max_fill": 1.5}, "max_fill"), ({"figure": "nine"}, "figure"),
                                           ({"pitch_mm": 0.2}, "pitch_mm")])
def test_a_pack_that_cannot_run_is_refused_naming_the_field(kwargs: dict, field: str) -> None:
    args = {"target": 0.8, **kwargs}
    with pytest.raises(PackError, match=field) if field != "pitch_mm" else pytest.raises(ValueError, match=field):
        check(prepare(BODY), **args)
    with pytest.raises(PackError, match="density"):
        check(prepare({**BODY, "layout": {"type": "grid", "pitch_mm": [1.0, 1.0]}}), 0.8)
    assert density_body(BODY, np.ones((2, 3)))["layout"]["fill"] == [[1.0] * 3] * 2
