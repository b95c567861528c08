"""Every registered feature shape keeps the contract of `tracer.elements.shapes.base`: its three descriptions of one
solid (the base it covers, the height and normal of its surface, a ray's interval inside it) agree with each other,
and its body is checked as the others' are. A new shape is tested here by its registration alone."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracer.elements import ElementError, prepare
from tracer.elements.microstructure import LAYOUTS
from tracer.elements.shapes.dispatch import KINDS, SHAPE_OF_NAME, shape_covers, shape_interval, shape_surface

SHAPES = [pytest.param(k, id=m.NAME) for k, m in enumerate(KINDS)]


def _params(k: int) -> tuple[float, float, float, float, np.ndarray]:
    """(a, h, rs, slope, P) of the shape's example body, as `tracer.elements.support` packs them."""
    _, a, h, rs, P = KINDS[k].parse(KINDS[k].EXAMPLE)
    return a, h, rs, a / h, P


def _plane_points(a: float, n: int = 400, seed: int = 3) -> np.ndarray:
    """Random plane points (du, dv) from a feature's centre, within 1.5 a."""
    return np.random.default_rng(seed).uniform(-1.5 * a, 1.5 * a, (n, 2))


@pytest.mark.parametrize("k", SHAPES)
def test_a_shape_states_its_contract(k: int) -> None:
    m = KINDS[k]
    assert SHAPE_OF_NAME[m.NAME] == k
    assert isinstance(m.FIELDS, set) and "shape" not in m.FIELDS
    assert set(m.EXAMPLE) == {"shape", *m.FIELDS} and m.EXAMPLE["shape"] == m.NAME
    assert m.LAYOUTS and set(m.LAYOUTS) <= set(LAYOUTS), m.LAYOUTS
    assert isinstance(m.ROUND, bool) and isinstance(m.RIDGE, bool)
    canon, a, h, rs, P = m.parse(dict(m.EXAMPLE))
    assert canon["shape"] == m.NAME and set(canon) == set(m.EXAMPLE)
    assert a > 0 and h > 0 and rs >= 0 and all(math.isfinite(x) for x in (a, h, rs))
    assert P.dtype == np.float64 and P.ndim == 2 and P.shape[1] == 4 and P.flags.c_contiguous
    again = m.parse(canon)
    assert again[1:4] == (a, h, rs) and np.array_equal(again[4], P), "the canonical body prepares the same solid"


@pytest.mark.parametrize("k", SHAPES)
def test_the_base_it_covers_is_where_its_surface_stands_above_the_plane(k: int) -> None:
    """`covers` and `surface` describe one solid: the height is >= 0 exactly over the base, and the normal is a unit
    vector pointing up, out of the solid."""
    a, h, rs, slope, P = _params(k)
    for du, dv in _plane_points(a):
        covered = shape_covers(k, a, P, du, dv)
        w, nu, nv, nw = shape_surface(k, a, h, rs, slope, P, du, dv)
        assert covered == (w >= -1e-12 * h), (du, dv, covered, w)
        assert w <= h * (1 + 1e-12)
        if covered:
            assert math.isclose(nu * nu + nv * nv + nw * nw, 1.0, rel_tol=1e-12) and nw > 0
    if KINDS[k].RIDGE:   # a ridge runs across the whole support: nothing changes along v
        assert all(shape_covers(k, a, P, du, 50 * a) == shape_covers(k, a, P, du, 0.0) for du, _ in _plane_points(a))


@pytest.mark.parametrize("k", SHAPES)
def test_a_ray_straight_down_enters_the_solid_at_its_surface(k: int) -> None:
    """`interval` and `surface` agree: a ray down the w' axis from above the top enters the solid where the surface
    height says, over the base; it misses the solid (above the plane) elsewhere."""
    a, h, rs, slope, P = _params(k)
    top = 2.0 * h
    for du, dv in _plane_points(a, seed=5):
        lo, hi = shape_interval(k, a, h, rs, slope, P, 0.0, 0.0, du, dv, top, 0.0, 0.0, -1.0)
        w, *_ = shape_surface(k, a, h, rs, slope, P, du, dv)
        if shape_covers(k, a, P, du, dv) and w > 1e-9 * h:
            assert lo < hi and math.isclose(top - lo, w, rel_tol=1e-9, abs_tol=1e-12 * h), (du, dv, lo, w)
        else:
            assert not (lo < hi and top - lo > 1e-9 * h), (du, dv, lo, hi)


@pytest.mark.parametrize("k", SHAPES)
def test_the_normal_is_the_surface_heights_gradient(k: int) -> None:
    """The normal ``surface`` gives is ``(-dw/du, -dw/dv, 1)`` normalised, by central differences of its height,
    at points well inside the base and away from its edges and ridges."""
    a, h, rs, slope, P = _params(k)
    e = 1e-6 * a
    checked = 0
    for du, dv in _plane_points(0.5 * a, seed=7):
        w, nu, nv, nw = shape_surface(k, a, h, rs, slope, P, du, dv)
        around = [shape_surface(k, a, h, rs, slope, P, du + x, dv + y)[1:] for x in (-e, e) for y in (-e, e)]
        if not shape_covers(k, a, P, du, dv) or any(not np.allclose(n, (nu, nv, nw)) for n in around):
            continue   # a face's edge is near: the normal jumps there
        gu = (shape_surface(k, a, h, rs, slope, P, du + e, dv)[0] - shape_surface(k, a, h, rs, slope, P, du - e, dv)[0])
        gv = (shape_surface(k, a, h, rs, slope, P, du, dv + e)[0] - shape_surface(k, a, h, rs, slope, P, du, dv - e)[0])
        g = np.array([-gu / (2 * e), -gv / (2 * e), 1.0])
        assert np.allclose(g / np.linalg.norm(g), (nu, nv, nw), atol=1e-5), (du, dv, g, (nu, nv, nw))
        checked += 1
    assert checked >= 50


@pytest.mark.parametrize("k", SHAPES)
def test_a_body_of_the_shape_is_refused_naming_its_field(k: int) -> None:
    """Each of its fields missing, one unknown, and a layout it does not take: refused, naming what is wrong."""
    m = KINDS[k]
    layout = {"type": "grid", "pitch_mm": [1.0, 1.0]}
    for field in m.FIELDS:
        feature = {f: v for f, v in m.EXAMPLE.items() if f != field}
        with pytest.raises(ElementError, match=field):
            prepare({"type": "microstructure", "feature": feature, "layout": layout})
        with pytest.raises(ElementError, match=field):
            prepare({"type": "microstructure", "feature": {**m.EXAMPLE, field: -1.0}, "layout": layout})
    with pytest.raises(ElementError, match="colour"):
        prepare({"type": "microstructure", "feature": {**m.EXAMPLE, "colour": 1}, "layout": layout})
    for other in sorted(set(LAYOUTS) - set(m.LAYOUTS)):
        with pytest.raises(ElementError, match=f"'{other}' layout does not take the feature shape '{m.NAME}'"):
            prepare({"type": "microstructure", "feature": m.EXAMPLE, "layout": {"type": other, "pitch_mm": 1.0}})
