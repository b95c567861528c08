"""A feature given as a mesh (tracer.elements.shapes.mesh, issue 53): the same solid as an analytic shape meets the
same rays, a dome given as a mesh lights a floor as the analytic dome does, the face planes are kept once, and every
mesh that cannot be a feature is refused naming the field."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.tracer.elements.test_relief_geometry import plate_scene, rays_from_inside
from tests.tracer.transport_scenes import box
from tracer.elements import ElementError, prepare
from tracer.elements.microstructure import Microstructure
from tracer.elements.shapes import mesh
from tracer.scene import Scene
from tracer.simulate import Simulation


def pyramid_mesh(base: float, height: float) -> dict:
    """The square pyramid `base` x `base` mm, `height` mm high, as a mesh feature (outward triangles)."""
    b = base / 2
    return {"shape": "mesh", "vertices_mm": [[-b, -b, 0], [b, -b, 0], [b, b, 0], [-b, b, 0], [0, 0, height]],
            "triangles": [[0, 2, 1], [0, 3, 2], [0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]]}


def dome_mesh(radius: float, height: float, segments: int = 48, rings: int = 8) -> dict:
    """The spherical cap of base `radius` and `height` (mm) as a mesh: `rings` rings of `segments` vertices on the
    sphere from the rim to the apex (each quad between two rings is planar), and a fan closing the base."""
    rs = (radius * radius + height * height) / (2 * height)
    phi_max = math.asin(radius / rs)
    theta = 2 * math.pi * np.arange(segments) / segments
    verts = []
    for r in range(rings):
        phi = phi_max * (rings - r) / rings
        verts += [[rs * math.sin(phi) * math.cos(t), rs * math.sin(phi) * math.sin(t),
                   (height - rs) + rs * math.cos(phi)] for t in theta]
    apex, centre = len(verts), len(verts) + 1
    verts += [[0.0, 0.0, height], [0.0, 0.0, 0.0]]
    verts[:segments] = [[x, y, 0.0] for x, y, _ in verts[:segments]]   # the rim exactly on the support
    tris = []
    for r in range(rings - 1):
        for k in range(segments):
            a0, a1 = r * segments + k, r * segments + (k + 1) % segments
            b0, b1 = a0 + segments, a1 + segments
            tris += [[a0, a1, b1], [a0, b1, b0]]
    last = (rings - 1) * segments
    tris += [[last + k, last + (k + 1) % segments, apex] for k in range(segments)]
    tris += [[centre, (k + 1) % segments, k] for k in range(segments)]
    return {"shape": "mesh", "vertices_mm": verts, "triangles": tris}


def element(feature: dict, relief: str = "bump", layout: dict | None = None) -> Microstructure:
    return prepare({"type": "microstructure", "feature": feature, "relief": relief,
                    "layout": layout or {"type": "grid", "pitch_mm": [0.5, 0.5]}})


@pytest.mark.parametrize("relief", ["bump", "pit"])
@pytest.mark.parametrize("layout", [{"type": "grid", "pitch_mm": [0.6, 0.6]},
                                    {"type": "density", "origin_mm": [0, 0], "size_mm": [50, 30],
                                     "fill": [[0.2, 0.9]], "pitch_mm": 0.6}])
def test_a_pyramid_given_as_a_mesh_meets_every_ray_where_the_pyramid_does(relief, layout):
    """The mesh's four side planes are the analytic pyramid's own (normalised), so each ray meets the same feature at
    the same point with the same normal, up to rounding. (A mesh's base counts as round, its circumradius 0.28 mm:
    a pitch of 0.6 mm for both.)"""
    hits = []
    for feature in ({"shape": "pyramid", "base_mm": 0.4, "height_mm": 0.15}, pyramid_mesh(0.4, 0.15)):
        s, i = plate_scene()
        s.set_element(i, element(feature, relief, layout), facing=[0, 0, -1])
        s.commit()
        hits.append(s.intersect(*rays_from_inside(5000, [0.3, -0.2, -1.0], seed=11)))
    a, b = hits
    assert 500 < (a.primitive < -1).sum() < 4500
    assert np.array_equal(a.primitive, b.primitive) and np.array_equal(a.instance, b.instance)
    assert np.allclose(a.t, b.t, rtol=1e-12, atol=0)
    assert np.allclose(a.normal, b.normal, atol=1e-9)


def test_a_mesh_feature_keeps_its_face_planes_once_whatever_its_copies():
    dome = element(dome_mesh(0.2, 0.1), layout={"type": "grid", "pitch_mm": [0.5, 0.5]})
    few = element(dome_mesh(0.2, 0.1), layout={"type": "points", "uv_mm": [[1.0, 1.0], [2.0, 1.0]]})
    many = element(dome_mesh(0.2, 0.1), layout={"type": "points", "uv_mm": [[0.5 * i, 0.5 * j] for i in range(40)
                                                                            for j in range(40)]})
    # 7 rings of planar quads and the apex fan: 7 x 48 + 48 distinct planes (the base is no face of the relief)
    assert dome.faces.shape == (8 * 48, 4) and np.allclose(np.linalg.norm(dome.faces[:, :3], axis=1), 1.0)
    assert np.array_equal(few.faces, many.faces)
    assert many.nbytes - few.nbytes == (1600 - 2) * 12 + (many.bins.nbytes - few.bins.nbytes)
    again = Microstructure.from_arrays(dome.arrays())
    assert again.id == dome.id and np.array_equal(again.faces, dome.faces)
    older = {k: v for k, v in element({"shape": "dome", "radius_mm": 0.2, "height_mm": 0.1}).arrays().items()
             if k != "faces"}   # a library file written before mesh features
    assert Microstructure.from_arrays(older).faces.shape == (0, 4)
    s, i = plate_scene()
    j = s.add_instance(s.instance_geometry(i), np.eye(4))
    s.set_element(i, dome, facing=[0, 0, -1])
    s.set_element(j, dome, facing=[0, 0, -1])
    s.commit()
    assert s.arrays().el_face.shape == dome.faces.shape   # one table for both parts


def test_a_dome_given_as_a_mesh_lights_the_floor_as_the_analytic_dome():
    """20 x 20 domes on the bottom of a PMMA plate lit at 30 degrees, as the analytic cap and as a 48 x 8 mesh of
    it: the illuminance map below agrees cell by cell within 4 combined sigma, plus the mesh's own facetting (its
    polygon covers 0.3 % less of the plane than the circle; 0.5 % of the mean allowed, as for the meshed plate)."""
    n, pitch, radius, height, thick = 20, 0.2e-3, 0.08e-3, 0.04e-3, 1e-3
    size = n * pitch
    s30 = math.sin(math.radians(30))
    light = {"type": "collimated", "origin": [size / 2 - 2e-3 * s30, size / 2, thick + 2e-3],
             "direction": [s30, 0, -math.cos(math.radians(30))], "radius": 1.2e-3, "illuminance_lx": 1000.0}
    floor = ([-2e-3, -2e-3, -1e-3], [size + 4e-3, 0, 0], [0, size + 4e-3, 0], 4, 4)
    maps = []
    for feature in ({"shape": "dome", "radius_mm": radius * 1e3, "height_mm": height * 1e3},
                    dome_mesh(radius * 1e3, height * 1e3)):
        s = Scene()
        v, t = box([0, 0, 0], [size, size, thick])
        part = s.add_instance(s.add_geometry(v, t), np.eye(4))
        s.set_element(part, element(feature, layout={"type": "grid", "pitch_mm": [pitch * 1e3, pitch * 1e3]}),
                      facing=[0, 0, -1])
        s.commit()
        sim = Simulation(s, {part: {"type": "dielectric", "ior": 1.49}}, [light])
        maps.append(sim.grid(*floor, max_photons=300_000, seed=5, estimator="forward"))
    a, b = maps
    lit = a.lux > 0.05 * a.lux.max()
    assert lit.sum() >= 4
    sigma = np.sqrt(a.stderr ** 2 + b.stderr ** 2)
    z = np.abs(a.lux - b.lux)[lit] / (4 * sigma[lit] + 0.005 * a.lux.mean())
    assert (z < 1).all(), (a.lux, b.lux, sigma)
    assert abs(a.lux.sum() - b.lux.sum()) < 4 * math.sqrt((sigma ** 2).sum()) + 0.005 * a.lux.sum()


def _dented() -> dict:
    """The pyramid with one side pushed in: a closed mesh, not convex."""
    m = pyramid_mesh(0.4, 0.15)
    m["vertices_mm"].append([0.0, -0.05, 0.04])
    m["triangles"] = [t for t in m["triangles"] if t != [0, 1, 4]] + [[0, 1, 5], [1, 4, 5], [4, 0, 5]]
    return m


def upside_down() -> dict:
    """A frustum wider at the top than at its base: its sides look down."""
    lo, hi = 0.05, 0.1
    verts = [[-lo, -lo, 0], [lo, -lo, 0], [lo, lo, 0], [-lo, lo, 0], [-hi, -hi, 0.1], [hi, -hi, 0.1], [hi, hi, 0.1],
             [-hi, hi, 0.1]]
    tris = [[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4], [1, 2, 6], [1, 6, 5], [2, 3, 7],
            [2, 7, 6], [3, 0, 4], [3, 4, 7]]
    return {"shape": "mesh", "vertices_mm": verts, "triangles": tris}


PYRAMID = pyramid_mesh(0.4, 0.15)


@pytest.mark.parametrize("feature, words", [
    ({**PYRAMID, "triangles": PYRAMID["triangles"][:-1]}, "not closed: edge"),
    ({**PYRAMID, "triangles": PYRAMID["triangles"][:-1] + [[3, 4, 0]]}, "is run the same way by two triangles"),
    (_dented(), "the mesh is not convex"),
    (upside_down(), "must look up"),
    ({**PYRAMID, "vertices_mm": [[u, v, w + 0.01] for u, v, w in PYRAMID["vertices_mm"]]},
     "the lowest vertex is at w = 0.01 mm"),
    ({**PYRAMID, "triangles": [*PYRAMID["triangles"][:-1], [3, 0, 9]]}, "feature.triangles[5][2] = 9 is no vertex"),
    ({**PYRAMID, "triangles": [*PYRAMID["triangles"][:-1], [3, 3, 4]]}, "repeats a vertex"),
    ({**PYRAMID, "triangles": [[float(i) for i in t] for t in PYRAMID["triangles"]]},
     "feature.triangles must be a non-empty list of [i, j, k] vertex indices"),
    ({**PYRAMID, "vertices_mm": [[0, 0], [1, 0], [0, 1], [1, 1], [0.5, 0.5]]},
     "feature.vertices_mm must be a non-empty list of [u, v, w] in mm"),
    ({**PYRAMID, "vertices_mm": [*PYRAMID["vertices_mm"][:4], [0, 0, float("nan")]]},
     "feature.vertices_mm[4] is not finite"),
    ({**PYRAMID, "vertices_mm": [[u, v, 0.0] for u, v, _ in PYRAMID["vertices_mm"]]}, "the mesh is flat"),
    (dome_mesh(0.2, 0.1, segments=128, rings=40), "more than 4096"),
])
def test_a_mesh_that_cannot_be_a_feature_is_refused_naming_the_field(feature, words):
    with pytest.raises(ElementError, match="feature") as e:
        element(feature)
    assert words in str(e.value)


def test_a_mesh_given_inward_is_the_same_solid_as_given_outward():
    inward = {**PYRAMID, "triangles": [t[::-1] for t in PYRAMID["triangles"]]}
    assert np.allclose(mesh.parse(inward)[4], mesh.parse(PYRAMID)[4], rtol=0, atol=1e-15)


def test_a_mesh_that_repeats_its_vertices_for_each_face_is_the_same_solid():
    """A CAD tessellation repeats a corner for each face it bounds: its vertices at one position are one corner, so
    the mesh is closed and has the same planes."""
    verts = [PYRAMID["vertices_mm"][i] for t in PYRAMID["triangles"] for i in t]
    soup = {"shape": "mesh", "vertices_mm": verts, "triangles": [[3 * k, 3 * k + 1, 3 * k + 2] for k in range(6)]}
    assert np.allclose(mesh.parse(soup)[4], mesh.parse(PYRAMID)[4], rtol=0, atol=1e-15)
    torn = {**soup, "vertices_mm": [[u + 1e-3, v, w] if k == 0 else [u, v, w] for k, (u, v, w) in enumerate(verts)]}
    with pytest.raises(ElementError, match="not closed"):
        mesh.parse(torn)
