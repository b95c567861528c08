"""The bottom-level kinds' contract (tracer/kinds/base.py), checked on every registered kind: its tag and flags, its
routines, and what they promise together — a solid's hit point (`point` of the hit's primitive) is where the ray
met it, its geometric normal is unit in the world and its shading normal on the same side; a sensor's crossing lies
on its plane and answers the side the ray came from. A kind that places itself (a shape) is checked from its own
`EXAMPLE` placement; the mesh and the relief (a part with an element) from the builders below."""

from __future__ import annotations

import numpy as np
import pytest

from tests.tracer.transport_scenes import box
from tracer.accel.traverse import hit_point, sensor_crossings, shading_normal
from tracer.elements import prepare
from tracer.kinds import REGISTRY
from tracer.scene import SHAPES, Scene

SOLID = ("intersect", "primitive", "normal", "shading_normal", "point")
SENSOR = ("cross", "point", "placement")


def _mesh(s: Scene) -> int:
    return s.add_instance(s.add_geometry(*box([-0.5, -0.5, -0.5], [0.5, 0.5, 0.5])), np.eye(4))


def _relief(s: Scene) -> int:
    i = _mesh(s)
    s.set_element(i, prepare({"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 40, "height_mm": 20},
                              "layout": {"type": "hex", "pitch_mm": 100}}), facing=[0, 0, 1])
    return i


BUILDERS = {"mesh": _mesh, "relief": _relief}


def _instance(module, s: Scene) -> int:
    name = module.__name__.rsplit(".", 1)[-1]
    if name in SHAPES:
        return s.add_shape(name, *module.EXAMPLE)
    return BUILDERS[name](s)


@pytest.mark.parametrize("tag", sorted(REGISTRY))
def test_every_kind_states_its_contract(tag: int) -> None:
    m = REGISTRY[tag]
    assert m.KIND == tag and isinstance(m.SENSOR, bool)
    assert m.GEOMETRY is None or isinstance(m.GEOMETRY, str)
    for name in SENSOR if m.SENSOR else SOLID:
        assert callable(getattr(m, name, None)), (m.__name__, name)
    if hasattr(m, "placement"):
        assert np.asarray(m.OBJECT_BOUNDS).shape == (6,)


@pytest.mark.parametrize("tag", sorted(k for k, m in REGISTRY.items() if not m.SENSOR))
def test_a_solid_kind_s_hit_point_and_normals_agree_with_its_intersection(tag: int) -> None:
    s = Scene()
    i = _instance(REGISTRY[tag], s)
    s.commit()
    rng = np.random.default_rng(tag)
    lo, hi = s.instance_bounds(i)
    centre, size = (lo + hi) / 2, float(np.max(hi - lo))
    d = rng.normal(size=(400, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    o = centre + rng.uniform(-0.3, 0.3, (400, 3)) * size - 2 * size * d
    hits = s.intersect(o, d)
    sa = s.arrays()
    met = np.flatnonzero(hits.instance == i)
    assert len(met) > 100
    for q in met:
        p = np.array(hit_point(sa, i, int(hits.primitive[q]), float(hits.u[q]), float(hits.v[q])))
        assert np.allclose(p, o[q] + hits.t[q] * d[q], atol=1e-9 * size), q
        assert abs(np.linalg.norm(hits.normal[q]) - 1) < 1e-9
        ns = np.array(shading_normal(sa, i, int(hits.primitive[q]), float(hits.u[q]), float(hits.v[q])))
        assert ns @ hits.normal[q] > 0


@pytest.mark.parametrize("tag", sorted(k for k, m in REGISTRY.items() if m.SENSOR))
def test_a_sensor_kind_s_crossing_lies_on_its_plane_and_says_the_side(tag: int) -> None:
    s = Scene()
    i = _instance(REGISTRY[tag], s)
    s.commit()
    m = np.eye(4)
    m[:3] = s.arrays().world_from_object[i]
    n = np.cross(m[:3, 0], m[:3, 1])
    n /= np.linalg.norm(n)
    centre = m[:3, 3] + 0.3 * (m[:3, 0] + m[:3, 1])
    out = (np.zeros(4, np.int64), np.zeros(4), np.zeros(4), np.zeros(4), np.zeros(4))
    for side in (1.0, -1.0):
        o = centre + side * n
        k = sensor_crossings(s.arrays(), *o, *(-side * n), 10.0, *out)
        assert k == 1 and out[0][0] == i
        p = o - side * n * out[1][0]
        assert abs((p - m[:3, 3]) @ n) < 1e-12 and np.allclose(p, m[:3, :3] @ [out[2][0], out[3][0], 0] + m[:3, 3])
        assert np.sign(out[4][0]) == side   # > 0: arriving on the front side
