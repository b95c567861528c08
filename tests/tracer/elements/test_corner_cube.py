"""A corner-cube array as a retroreflector, and features with a surface of their own (a printed white dot), checked
against closed forms (issue 36).

Corner cube. A ray along the axis of a cube corner is reflected once by each of its three mutually perpendicular
faces, each flipping one component of its direction in the cube's axes, so it leaves antiparallel; the exit point
is the entry point reflected through the axis (Eckhardt, "Simple model of corner reflector phenomena", Appl. Opt.
10, 1559 (1971)). A ray entering the aperture A at q is therefore returned only where -q (about the axis) lies in A
too: the effective area is |A ∩ -A|. For the triangular aperture of a trihedral corner (the feature here, an
equilateral triangle of side s), A ∩ -A is the regular hexagon left when the three corner triangles of side s/3
are cut off: 1 - 3/9 = 2/3 of A. (A hexagonal "full cube" aperture is its own point reflection: 1.)
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.tracer.transport_scenes import box
from tracer.elements import ElementError, prepare
from tracer.elements import features as fx
from tracer.scene import Scene
from tracer.simulate import Simulation

SIDE, PITCH = 0.5, 0.6          # mm: the triangle's side, the grid's pitch (>= its circumradius x 2 = 0.577)
PLATE = (0.012, 0.012, 0.002)    # m: 20 x 20 cells; the top face (normal +z) carries the corners: u = x, v = y


def corners(relief="bump"):
    return prepare({"type": "microstructure", "feature": {"shape": "corner_cube", "side_mm": SIDE},
                    "relief": relief, "layout": {"type": "grid", "pitch_mm": [PITCH, PITCH]}})


def _triangle(n, rng):
    """n points uniform in the equilateral triangle of side SIDE centred at 0 (a vertex towards +v), mm; and its
    vertices."""
    r = SIDE / math.sqrt(3.0)
    ang = np.radians([90.0, 210.0, 330.0])
    verts = np.column_stack([r * np.cos(ang), r * np.sin(ang)])
    a, b = rng.random(n), rng.random(n)
    flip = a + b > 1.0
    a[flip], b[flip] = 1.0 - a[flip], 1.0 - b[flip]
    return verts[0] + a[:, None] * (verts[1] - verts[0]) + b[:, None] * (verts[2] - verts[0]), verts


def _inside(p, verts, margin=0.0):
    """Whether points p (k, 2) lie in the triangle (counter-clockwise vertices) by more than `margin` mm."""
    ok = np.ones(len(p), bool)
    for k in range(3):
        e = verts[(k + 1) % 3] - verts[k]
        n = np.array([e[1], -e[0]]) / np.linalg.norm(e)        # outward
        ok &= (p - verts[k]) @ n < -margin
    return ok


def test_a_corner_cube_array_returns_two_thirds_of_its_triangular_aperture_antiparallel():
    s = Scene()
    v, t = box([0, 0, 0], PLATE)
    part = s.add_instance(s.add_geometry(v, t), np.eye(4))
    s.set_element(part, corners(), facing=[0, 0, 1])
    s.commit()
    rng = np.random.default_rng(7)
    n = 20_000
    local, verts = _triangle(n, rng)
    cell = rng.integers(0, 20, (n, 2))
    centre = (cell + 0.5) * PITCH                                  # mm, the corners' axes
    o = np.column_stack([(centre + local) * 1e-3, np.full(n, PLATE[2] / 2)])
    d = np.tile([0.0, 0.0, 1.0], (n, 1))
    reflections = np.zeros(n, int)
    alive = np.ones(n, bool)
    for _ in range(5):      # from inside the part, each feature hit reflects (an ideal mirror: TIR at 54.7 deg)
        h = s.intersect(o[alive], d[alive])
        idx = np.flatnonzero(alive)
        on = h.primitive < -1
        assert np.isfinite(h.t).all()
        alive[idx[~on]] = False                                    # met the plate's own faces: left the corners
        k = idx[on]
        p = o[k] + h.t[on, None] * d[k]
        nrm = h.normal[on]
        d[k] = d[k] - 2.0 * np.sum(d[k] * nrm, axis=1)[:, None] * nrm
        o[k] = p - 1e-9 * nrm                                      # back into the part
        reflections[k] += 1
        if not alive.any():
            break
    assert not alive.any()
    returned = np.abs(d[:, 2] + 1.0) < 1e-9
    assert (reflections[returned] == 3).all()
    # the exit point is the entry point reflected through the axis
    exit_uv = o[returned, :2] * 1e3 - centre[returned]
    assert np.abs(exit_uv + local[returned]).max() < 1e-6
    # which rays return: exactly those whose point reflection lies in the aperture (away from its edges)
    mirrored_in = _inside(-local, verts, 1e-6)
    mirrored_out = ~_inside(-local, verts, -1e-6)
    assert returned[mirrored_in].all() and not returned[mirrored_out].any()
    fraction = returned.mean()
    sigma = math.sqrt(2 / 3 * (1 / 3) / n)
    assert abs(fraction - 2.0 / 3.0) < 4 * sigma, (fraction, sigma)


def test_a_corner_cube_is_three_perpendicular_faces_over_its_triangle():
    e = corners()
    assert e.h == pytest.approx(SIDE / math.sqrt(6.0)) and e.a == pytest.approx(SIDE / math.sqrt(3.0))
    from tracer.elements import features as fx

    normals = []
    for ang in (270.0, 30.0, 150.0):                # a point above each face's base edge, inside the triangle
        r = 0.25 * SIDE / math.sqrt(3.0)
        hu, hv = r * math.cos(math.radians(ang)), r * math.sin(math.radians(ang))
        F = np.zeros(fx.NF)
        F[fx.A], F[fx.H], F[fx.RS], F[fx.SIGN], F[fx.CU], F[fx.CV] = e.a, e.h, e.rs, 1.0, 1.0, 1.0
        F[fx.ORG_U] = F[fx.ORG_V] = -0.5
        I = np.zeros(fx.NI, np.int64)
        I[fx.SHAPE], I[fx.LAYOUT], I[fx.NU], I[fx.NV] = e.shape, fx.GRID, 1, 1
        w, nu, nv, nw = fx.surface(F, I, np.zeros((0, 2), np.float32), np.zeros((0, 4)), 0, hu, hv)
        assert w == pytest.approx(e.h - math.sqrt(2.0) * r)
        normals.append([nu, nv, nw])
    g = np.array(normals) @ np.array(normals).T
    assert g == pytest.approx(np.eye(3), abs=1e-12)


def test_printed_white_dots_reflect_their_reflectance_times_their_covered_fraction():
    """White Lambertian dots (reflectance 0.8) on a black plate under a beam at normal incidence: the flux that
    comes back up, caught by a large plane just above, is 0.8 x the fraction of the beam the dots cover x its flux
    (the dots are 10 um high: what their sides send into the plate is below 1e-4 of it)."""
    rho, radius, pitch = 0.8, 0.2, 0.5           # mm
    s = Scene()
    v, t = box([-0.01, -0.01, -0.001], [0.01, 0.01, 0.0])
    part = s.add_instance(s.add_geometry(v, t), np.eye(4))
    dots = prepare({"type": "microstructure", "feature": {"shape": "dome", "radius_mm": radius, "height_mm": 0.01},
                    "material": {"type": "lambertian", "reflectance": rho},
                    "layout": {"type": "grid", "pitch_mm": [pitch, pitch]}})
    s.set_element(part, dots, facing=[0, 0, 1])
    s.commit()
    beam_r, lux = 0.005, 1000.0
    light = {"type": "collimated", "origin": [0.0003, 0.0002, 1e-4], "direction": [0, 0, -1], "radius": beam_r,
             "illuminance_lx": lux}
    sim = Simulation(s, {part: {"type": "black"}}, [light])
    res = sim.grid([-1.0, 1.0, 2e-4], [2.0, 0.0, 0.0], [0.0, -2.0, 0.0], 1, 1, max_photons=40_000, seed=3,
                   estimator="forward")
    flux = float(res.lux[0, 0]) * 4.0
    err = float(res.stderr[0, 0]) * 4.0
    # the fraction of the beam's disk the dots' bases cover (support corner at (-10, -10) mm, cells from there)
    g = (np.arange(4000) + 0.5) / 4000 * 2 * beam_r * 1e3 - beam_r * 1e3
    x, y = np.meshgrid(g + 0.3, g + 0.2)
    disk = (x - 0.3) ** 2 + (y - 0.2) ** 2 <= (beam_r * 1e3) ** 2
    cu, cv = np.mod(x + 10.0, pitch) - pitch / 2, np.mod(y + 10.0, pitch) - pitch / 2
    covered = (cu ** 2 + cv ** 2 <= radius ** 2)[disk].mean()
    expected = rho * covered * lux * math.pi * beam_r ** 2
    assert abs(flux - expected) < 4 * err + 1e-3 * expected, (flux, expected, err)


@pytest.mark.parametrize("body, words", [
    ({"shape": "corner_cube", "side_mm": 0}, "feature.side_mm must be > 0"),
    ({"shape": "corner_cube"}, "missing field(s) ['side_mm']"),
])
def test_a_bad_corner_cube_names_its_field(body, words):
    with pytest.raises(ElementError) as err:
        prepare({"type": "microstructure", "feature": body, "layout": {"type": "grid", "pitch_mm": [1, 1]}})
    assert words in str(err.value)


@pytest.mark.parametrize("material, words", [
    ({"type": "lambertian", "reflectance": -0.1}, "material.reflectance must be >= 0"),
    ({"type": "mirror", "reflectance": 0.9}, "material.type 'mirror' is not a feature material"),
    ({"type": "black", "reflectance": 0.0}, "material: unknown field(s) ['reflectance']"),
    ("white", "material.type 'white'"),
])
def test_a_bad_feature_material_names_its_field(material, words):
    with pytest.raises(ElementError) as err:
        prepare({"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.1, "height_mm": 0.05},
                 "material": material, "layout": {"type": "grid", "pitch_mm": [1, 1]}})
    assert words in str(err.value)


def test_a_feature_material_changes_the_id_and_survives_the_library_file(tmp_path):
    plain = prepare({"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.1, "height_mm": 0.05},
                     "layout": {"type": "grid", "pitch_mm": [1, 1]}})
    white = prepare({**plain.body, "material": {"type": "lambertian", "reflectance": 0.9}})
    assert white.id != plain.id
    from tracer.elements import Microstructure

    np.savez(tmp_path / "e.npz", **white.arrays())
    with np.load(tmp_path / "e.npz") as z:
        back = Microstructure.from_arrays(z)
    assert back.id == white.id and back.material == white.material and back.reflectance == 0.9


H_ROW = SIDE * math.sqrt(3.0) / 2.0    # mm: a triangular layout's row height


def _close_packed_plate():
    s = Scene()
    v, t = box([0, 0, 0], PLATE)
    part = s.add_instance(s.add_geometry(v, t), np.eye(4))
    cubes = prepare({"type": "microstructure", "feature": {"shape": "corner_cube", "side_mm": SIDE},
                     "layout": {"type": "triangular"}})
    s.set_element(part, cubes, facing=[0, 0, 1])
    s.commit()
    return s


def _interior(n, rng):
    """n plane points (mm) inside the tiled rows, away from the rows' ragged ends."""
    rows = int(PLATE[1] * 1e3 // H_ROW)
    return np.column_stack([rng.uniform(SIDE, PLATE[0] * 1e3 - SIDE, n), rng.uniform(0.0, rows * H_ROW, n)])


def test_close_packed_corner_cubes_leave_no_gap_on_the_face():
    """Triangles of side s in rows of height s sqrt(3)/2, every other one turned 180 degrees, tile the plane: a ray
    up into the face anywhere inside the tiled rows meets a corner cube (at a pitch, 1.155 s at least, they covered
    (sqrt(3)/4 s^2) / pitch^2 = 0.65 of it)."""
    s = _close_packed_plate()
    p = _interior(20_000, np.random.default_rng(3))
    o = np.column_stack([p * 1e-3, np.full(len(p), PLATE[2] / 2)])
    hit = s.intersect(o, np.tile([0.0, 0.0, 1.0], (len(p), 1)))
    assert (hit.primitive < -1).all(), int((hit.primitive >= -1).sum())


def test_a_turned_corner_cube_returns_light_as_an_upright_one_through_its_own_axis():
    """In the close-packed array, each ray that enters a cube where its point reflection about that cube's axis is
    in the cube's aperture (turned or not) leaves antiparallel after three reflections, at that point reflection;
    those are 2/3 of the face, and rays elsewhere are not returned in their cube."""
    s = _close_packed_plate()
    rng = np.random.default_rng(9)
    n = 20_000
    p = _interior(n, rng)
    o = np.column_stack([p * 1e-3, np.full(n, PLATE[2] / 2)])
    d = np.tile([0.0, 0.0, 1.0], (n, 1))
    first = s.intersect(o, d)
    f = (-2 - first.primitive) // fx.PART_ROWS   # the feature (the plate carries one element: row 0)
    nu = int(PLATE[0] * 1e3 // (SIDE / 2)) - 1
    i, j = f % nu, f // nu
    turned = (i + j) % 2 == 1
    centre = np.column_stack([(i + 1) * SIDE / 2, (j + np.where(turned, 2.0, 1.0) / 3.0) * H_ROW])
    local = np.where(turned[:, None], -1.0, 1.0) * (p - centre)     # in the cube's own (upright) frame
    _, verts = _triangle(1, rng)
    assert _inside(local, verts, -1e-6).all()                       # each ray met the cube it entered
    reflections = np.zeros(n, int)
    alive = np.ones(n, bool)
    for _ in range(6):
        h = s.intersect(o[alive], d[alive])
        idx = np.flatnonzero(alive)
        on = h.primitive < -1
        alive[idx[~on]] = False
        k = idx[on]
        q = o[k] + h.t[on, None] * d[k]
        nrm = h.normal[on]
        d[k] = d[k] - 2.0 * np.sum(d[k] * nrm, axis=1)[:, None] * nrm
        o[k] = q - 1e-9 * nrm
        reflections[k] += 1
        if not alive.any():
            break
    returned = np.abs(d[:, 2] + 1.0) < 1e-9
    mirrored_in = _inside(-local, verts, 1e-6)
    assert returned[mirrored_in].all() and (reflections[mirrored_in] == 3).all()
    assert np.abs(o[mirrored_in, :2] * 1e3 - (2 * centre[mirrored_in] - p[mirrored_in])).max() < 1e-6
    assert not returned[~_inside(-local, verts, -1e-6)].any()
    for side in (turned, ~turned):
        share = mirrored_in[side].mean()
        assert abs(share - 2 / 3) < 4 * math.sqrt(2 / 9 / side.sum()), share
