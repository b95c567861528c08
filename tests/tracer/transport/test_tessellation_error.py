"""The tessellation error budget (issue 24, in part; `tracer.transport.tessellation_error`).

Geometry: a cadquery sphere and paraboloid, meshed by the project's own `cad_adapter.tessellate.mesh_shape` at
coarse settings and at a much finer one; the true error of each mesh is measured against the closed-form surface
(sphere: |p| − R and normal p/|p|; paraboloid z = ρ²/4f: the nearest point by Newton's method on the meridian,
normal (−x/2f, −y/2f, 1)) on 28 points per triangle, corners, edges and inside, with the normal the tracer uses
(the interpolated vertex normal). Each estimate must bound the measured error and be at most `LOOSE` times it.

LOOSE = 20 for the position: the bounds are worst cases over a triangle (circumcentre 4/3, √2 for a diagonal,
OCCT's 2.5) applied to the worst triangle, so a few times the measured distance is expected and 20× would mean a
wrong model. The normal bound is first order against a second-order error (module docstring): it must bound the
measured error, which on the paraboloid is asserted to be second order (≤ ψ²/4) rather than within 20×, and on a
sphere is float32 noise (~1e-7 rad: the interpolated normal of a facet is exact there). The finer mesh (linear
0.001, angular 0.05; 100k triangles on the sphere) is itself measured against the closed form and must be at least
10× closer than the coarse one: it stands for "tessellated finely enough".
"""

from __future__ import annotations

import math

import numpy as np
import pytest

cq = pytest.importorskip("cadquery")

from cad_adapter.tessellate import mesh_shape  # noqa: E402
from tracer.transport.tessellation_error import (  # noqa: E402
    R_MAX,
    SAFETY,
    converged,
    extrapolate,
    from_mesh,
    from_settings,
    refine,
)

R = 10.0              # sphere radius (mesh units)
F = 5.0               # paraboloid focal length: z = ρ² / 4F, smallest radius of curvature 2F at the apex
RIM = 12.0            # paraboloid rim radius
LOOSE = 20.0
FINE = (0.001, 0.05)
COARSE = [(1.0, 0.5), (0.1, 0.5), (0.5, 0.2), (0.05, 0.5), (0.2, 0.3)]


def sphere_shape(radius=R):
    return cq.Workplane().sphere(radius).val().wrapped


def paraboloid_shape(f=F, rim=RIM):
    """The dish z = ρ²/4f, ρ ≤ rim, as one face: a quadratic Bézier is exactly that parabola, revolved about z."""
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeRevol
    from OCP.gp import gp_Ax1, gp_Dir, gp_Pnt

    edge = cq.Edge.makeBezier([cq.Vector(0, 0, 0), cq.Vector(rim / 2, 0, 0), cq.Vector(rim, 0, rim * rim / (4 * f))])
    return BRepPrimAPI_MakeRevol(edge.wrapped, gp_Ax1(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)), 2 * math.pi).Shape()


def samples(v, t, n=6):
    """Barycentric weights (s, 3) and points (m, s, 3) on every triangle (corners, edges, inside)."""
    w = np.array([(i / n, j / n, 1 - (i + j) / n) for i in range(n + 1) for j in range(n + 1 - i)])
    return w, np.einsum("sk,mkd->msd", w, v[t])


def sphere_truth(p, radius=R):
    """(distance to the sphere, the true outward normal at the nearest point)."""
    rho = np.linalg.norm(p, axis=-1, keepdims=True)
    return np.abs(rho[..., 0] - radius), p / rho


def paraboloid_truth(p, f=F):
    """(distance to z = ρ²/4f, the true normal (upward, towards the focus) at the nearest point)."""
    rho, z = np.hypot(p[..., 0], p[..., 1]), p[..., 2]
    x = rho.copy()
    for _ in range(60):   # minimise (x − ρ)² + (x²/4f − z)² over x ≥ 0
        g = (x - rho) + (x * x / (4 * f) - z) * x / (2 * f)
        h = 1 + (x / (2 * f)) ** 2 + (x * x / (4 * f) - z) / (2 * f)
        x = np.maximum(x - g / h, 0.0)
    phi = np.arctan2(p[..., 1], p[..., 0])
    q = np.stack([x * np.cos(phi), x * np.sin(phi), x * x / (4 * f)], -1)
    nrm = np.stack([-x / (2 * f) * np.cos(phi), -x / (2 * f) * np.sin(phi), np.ones_like(x)], -1)
    return np.linalg.norm(p - q, axis=-1), nrm / np.linalg.norm(nrm, axis=-1, keepdims=True)


def measured(mesh, truth, steps=6):
    """(largest distance of the mesh from the true surface, largest angle between the interpolated vertex normal
    and the true normal), over `samples`."""
    v, t, n = (np.asarray(a, np.float64) for a in (mesh.vertices, mesh.triangles, mesh.normals))
    t = t.astype(np.int64)
    w, p = samples(v, t, steps)
    dist, true_n = truth(p)
    sn = np.einsum("sk,mkd->msd", w, n[t])
    sn /= np.linalg.norm(sn, axis=-1, keepdims=True)
    true_n = true_n * np.sign(np.sum(sn * true_n, axis=-1, keepdims=True))   # either orientation
    ang = np.arctan2(np.linalg.norm(np.cross(sn, true_n), axis=-1), np.sum(sn * true_n, axis=-1))
    return float(dist.max()), float(ang.max())


SURFACES = {"sphere": (sphere_shape, sphere_truth, R), "paraboloid": (paraboloid_shape, paraboloid_truth, 2 * F)}


@pytest.fixture(scope="module")
def fine_errors():
    """The finer tessellation of each B-rep, measured against its closed form."""
    out = {}
    for name, (shape, truth, _) in SURFACES.items():
        mesh, _ = mesh_shape(shape(), *FINE)
        out[name] = measured(mesh, truth, 3)
    return out


@pytest.mark.parametrize("name", sorted(SURFACES))
@pytest.mark.parametrize("linear,angular", COARSE)
def test_the_estimates_bound_the_measured_error_of_a_coarse_mesh(name, linear, angular, fine_errors):
    shape, truth, radius = SURFACES[name]
    mesh, _ = mesh_shape(shape(), linear, angular)
    pos, nrm = measured(mesh, truth)
    fine_pos, fine_nrm = fine_errors[name]
    assert fine_pos * 10 <= pos                      # the finer mesh stands for the true surface at this scale
    for est in (from_settings(linear, angular, radius), from_mesh(mesh.vertices, mesh.triangles, mesh.normals)):
        assert pos <= est.position <= LOOSE * pos, (est, pos)
        assert nrm <= est.normal, (est, nrm)
        assert est.curvature == pytest.approx(1 / radius, rel=0.05)   # the largest curvature: 1/R, 1/2F at the apex
    if name == "sphere":
        assert nrm < 1e-6      # the interpolated normal of a facet on a sphere is p/|p|: exact up to float32
    else:
        # the first-order bound ψ against a second-order error: documented in tracer.transport.tessellation_error
        est = from_mesh(mesh.vertices, mesh.triangles, mesh.normals)
        assert fine_nrm * 10 <= nrm <= 0.25 * est.normal ** 2


def test_a_flat_mesh_has_no_tessellation_error():
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    t = np.array([[0, 1, 2], [0, 2, 3]])
    est = from_mesh(v, t, np.tile([0, 0, 1.0], (4, 1)))
    assert est.position == 0 and est.normal == 0 and not est.curved
    assert not from_settings(0.1, 0.5, math.inf).curved


# ------------------------------------------------------------------------------------------------ illuminance

DISH_F, DISH_RIM = 0.25, 0.5          # m: a paraboloid mirror focusing a collimated beam at (0, 0, DISH_F)
BEAM = {"type": "collimated", "origin": [0, 0, 1.0], "direction": [0, 0, -1], "radius": 0.45, "illuminance_lx": 1000.0}


def dish(linear, angular, material=None):
    from tracer.scene import Scene
    from tracer.simulate import Simulation

    mesh, _ = mesh_shape(paraboloid_shape(DISH_F, DISH_RIM), linear, angular)
    s = Scene()
    i = s.add_instance(s.add_geometry(mesh.vertices, mesh.triangles, mesh.normals), np.eye(4))
    s.commit()
    return Simulation(s, {i: material or {"type": "mirror", "reflectance": 1.0}}, [BEAM])


def test_the_lux_a_coarse_dish_misses_lies_within_its_tessellation_budget():
    """The focus (every reflected photon, 0.45²/0.05² × 1000 lx = 81,000 lx through the true dish) and two points
    in the cone beyond it, on a coarse dish (linear 1 cm, angular 0.5) and a fine one (0.5 mm, 0.05): the coarse
    value lies within its own budget plus 4 combined standard errors of the fine one, and the coarse dish does lose
    light at the focus (the test is not empty)."""
    pts = np.array([[0, 0, DISH_F], [0, 0, 0.6], [0.1, 0, 0.6]])
    nrm = np.tile([0, 0, -1.0], (3, 1))
    runs = {}
    for name, settings in (("coarse", (0.01, 0.5)), ("fine", (0.0005, 0.05))):
        runs[name] = dish(*settings).illuminance(pts, nrm, radius=0.05, max_photons=400_000, seed=3,
                                                 estimator="forward")
    c, f = runs["coarse"], runs["fine"]
    assert f.lux[0] == pytest.approx(0.45 ** 2 / 0.05 ** 2 * 1000, rel=1e-9)   # the fine dish: all at the focus
    se = np.hypot(c.stderr, f.stderr)
    gap = np.abs(c.lux - f.lux)
    assert gap[0] > 4 * se[0] + 0.05 * f.lux[0]           # the coarse dish misses the focus by > 5 %
    budget = c.error_budget["tessellation"]
    assert budget.shape == (3,) and np.all(budget >= 0)
    assert np.all(gap <= budget + 4 * se), (gap, budget, se)
    assert np.all(f.error_budget["tessellation"] < budget)  # a finer mesh, a smaller budget


def test_the_budget_is_there_only_for_curved_optical_surfaces():
    pts, nrm = np.array([[0, 0, 0.6]]), np.array([[0, 0, -1.0]])
    grid = dish(0.01, 0.5).grid([-0.2, -0.2, 0.6], [0.4, 0, 0], [0, -0.4, 0], 3, 2, max_photons=20_000)
    assert grid.error_budget["tessellation"].shape == (2, 3)       # (nv, nu), like the lux
    diffuse = dish(0.01, 0.5, {"type": "lambertian", "reflectance": 0.5})
    assert diffuse.illuminance(pts, nrm, max_photons=20_000, estimator="forward").error_budget is None

    from tracer.scene import Scene
    from tracer.simulate import Simulation

    s = Scene()          # a flat mirror with vertex normals: nothing to tessellate
    i = s.add_instance(s.add_geometry(np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float),
                                      np.array([[0, 1, 2], [0, 2, 3]]), np.tile([0, 0, 1.0], (4, 1))), np.eye(4))
    s.commit()
    flat = Simulation(s, {i: {"type": "mirror", "reflectance": 1.0}}, [BEAM])
    assert flat.illuminance(pts, nrm, max_photons=20_000, estimator="forward").error_budget is None


# ------------------------------------------------------------------------------------------------ the estimate (42)

FOCUS_LIGHT = {"type": "point", "position": [0, 0, DISH_F], "intensity_cd": 1000.0}


def focus_dish(linear, angular):
    from tracer.scene import Scene
    from tracer.simulate import Simulation

    mesh, _ = mesh_shape(paraboloid_shape(DISH_F, DISH_RIM), linear, angular)
    s = Scene()
    i = s.add_instance(s.add_geometry(mesh.vertices, mesh.triangles, mesh.normals), np.eye(4))
    s.commit()
    return Simulation(s, {i: {"type": "mirror", "reflectance": 1.0}}, [FOCUS_LIGHT]), len(mesh.triangles)


def _mean_normal_error(v, t, n, truth, steps=3) -> float:
    """Mean angle (rad) between the interpolated vertex normal and the true one, over `samples`."""
    v, n, t = np.asarray(v, np.float64), np.asarray(n, np.float64), np.asarray(t, np.int64)
    w, p = samples(v, t, steps)
    _, true_n = truth(p)
    sn = np.einsum("sk,mkd->msd", w, n[t])
    sn /= np.linalg.norm(sn, axis=-1, keepdims=True)
    true_n = true_n * np.sign(np.sum(sn * true_n, axis=-1, keepdims=True))
    return float(np.mean(np.arctan2(np.linalg.norm(np.cross(sn, true_n), axis=-1), np.sum(sn * true_n, axis=-1))))


def test_refine_converges_to_the_true_surface_positions_and_normals():
    """Each split puts the new vertices on the surface the mesh's positions and normals describe, with its normal:
    the position error falls as h² (4× a split) and so does the interpolated normal's (second order), i.e. the
    refined meshes approach the true paraboloid, not a surface of their own (the PN midpoints did not: 0.75 → 0.67
    → 0.53 mrad). Measured on the coarse dish (572 triangles): position 2.5 → 0.64 → 0.16 mm, mean normal error
    0.75 → 0.18 → 0.044 mrad; asserted ≥ 3× a split (4× is h²; the fit's own error is O(h⁴))."""
    mesh, _ = mesh_shape(paraboloid_shape(DISH_F, DISH_RIM), 0.005, 0.5)
    truth = lambda p: paraboloid_truth(p, DISH_F)   # noqa: E731
    v, t, n = mesh.vertices, mesh.triangles, mesh.normals
    levels = []
    for _ in range(3):
        class M:
            vertices, triangles, normals = v, t, n
        levels.append((measured(M, truth, 3)[0], _mean_normal_error(v, t, n, truth)))
        v, t, n = refine(v, t, n)
    assert len(t) == 16 * 4 * len(mesh.triangles) and len(v) == len(n)
    (p0, n0), (p1, n1), (p2, n2) = levels
    assert p1 <= p0 / 3 and p2 <= p1 / 3, levels
    assert n1 <= n0 / 3 and n2 <= n1 / 3, levels
    with pytest.raises(ValueError, match="normals"):
        refine(mesh.vertices, mesh.triangles, mesh.normals[:-1])


def test_extrapolate_is_richardson_with_the_observed_order_and_the_gci_factor():
    """Values converging geometrically (E_k = E∞ + C·r^k): with r ≤ ½ the estimate is SAFETY·|E∞ − E_0|, exactly;
    converging slower than first order (r > ½), r is taken as ½ (the tail |d_L|); a sign change (oscillation) or
    a first difference within noise takes r = ½ too and adds the tail's size. Bad shapes are a ValueError."""
    truth, c = 100.0, np.array([40.0, -8.0, 3.0])
    for r in (0.25, 0.5, 0.1):
        lux = truth + c[None] * r ** np.arange(3)[:, None]
        est, se, used = extrapolate(lux, np.zeros_like(lux))
        assert np.allclose(used, r) and np.allclose(est, SAFETY * np.abs(c)), (r, est)
        assert np.all(se == 0)
    lux = truth + c[None] * 0.9 ** np.arange(4)[:, None]          # pre-asymptotic: r clipped to ½
    est, _, used = extrapolate(lux, np.zeros_like(lux))
    assert np.allclose(used, R_MAX) and not converged(lux, np.zeros_like(lux))
    last = np.abs(lux[-1] - lux[-2])
    assert np.allclose(est, SAFETY * (np.abs(lux[-1] - lux[0]) + last))
    lux = np.array([[0.0], [10.0], [8.0]])                          # oscillating
    est, _, used = extrapolate(lux, np.zeros_like(lux))
    assert used[0] == R_MAX and est[0] == pytest.approx(SAFETY * (8.0 + 2.0))
    noisy = np.array([[0.0], [1.0], [1.5]])
    est, se, used = extrapolate(noisy, np.ones_like(noisy))       # the first difference is noise: r = ½
    assert used[0] == R_MAX and se[0] > 0 and converged(noisy, np.ones_like(noisy))
    with pytest.raises(ValueError, match="L >= 2"):
        extrapolate(lux[:2], lux[:2])


def informs(estimate, error, value, noise):
    """Issue 42's aim, per value: the estimate lies between the true error and 10× it, or within 5 % of the value of
    it; `noise` (3 combined standard errors of the measured error) widens each side by what the measurement allows."""
    return (((error - noise <= estimate) & (estimate <= 10 * (error + noise)))
            | (np.abs(estimate - error) <= 0.05 * value + noise))


def test_the_tessellation_estimate_tracks_the_true_error_of_a_coarse_dish():
    """A point source at the focus of the dish (f 0.25 m, rim 0.5 m): the reflected beam is collimated, lighting a
    plane 3 m up (receivers of 5 cm facing down). Truth: a 6,360-triangle mesh (linear 0.5 mm, angular 0.05). The
    coarse mesh (linear 5 mm, angular 0.5: 572 triangles) is off by several %; at every point its estimate meets
    issue 42's aim (`informs`, with 3σ of the measured error), where that error exceeds 3σ today's bound is over
    1000× it, and on the fine mesh the estimate is < 5 % of the value."""
    pts = np.array([[x, 0.0, 3.0] for x in np.linspace(0.0, 0.45, 7)])
    nrm = np.tile([0, 0, -1.0], (len(pts), 1))
    q = {"radius": 0.05, "max_photons": 2_000_000, "estimator": "forward", "tessellation_estimate": True}
    fine_sim, n_fine = focus_dish(0.0005, 0.05)
    coarse_sim, n_coarse = focus_dish(0.005, 0.5)
    assert n_coarse < 600 < 6000 < n_fine
    f = fine_sim.illuminance(pts, nrm, seed=11, **q)
    c = coarse_sim.illuminance(pts, nrm, seed=3, **q)
    err = np.abs(c.lux - f.lux)
    se = np.hypot(c.stderr, f.stderr)
    real = err > 3 * se
    assert real.sum() >= 4, (err, se)                 # the coarse dish is measurably wrong at most points
    est = c.error_budget["tessellation_estimate"]
    assert np.all(informs(est, err, f.lux, 3 * se)), (est / err, est, err, se)
    assert np.all(c.error_budget["tessellation"][real] / err[real] > 1000)   # the bound: says nothing
    assert np.all(c.error_budget["tessellation_estimate_stderr"] > 0)
    assert c.error_budget["tessellation_estimate_levels"] in (2, 3)
    assert c.error_budget["tessellation_estimate_seconds"] > 0
    assert np.all(f.error_budget["tessellation_estimate"] < 0.05 * f.lux), f.error_budget


def test_no_estimate_unless_asked_or_without_curved_surfaces():
    sim, _ = focus_dish(0.01, 0.5)
    r = sim.illuminance([[0, 0, 3.0]], [[0, 0, -1.0]], max_photons=20_000, estimator="forward")
    assert set(r.error_budget) == {"tessellation"}
    diffuse = dish(0.01, 0.5, {"type": "lambertian", "reflectance": 0.5})
    r = diffuse.illuminance([[0, 0, 0.6]], [[0, 0, -1.0]], max_photons=20_000, estimator="forward",
                            tessellation_estimate=True)
    assert r.error_budget is None


def test_a_grid_gets_the_estimate_per_cell():
    sim, _ = focus_dish(0.01, 0.5)
    g = sim.grid([-0.2, -0.2, 3.0], [0.4, 0, 0], [0, -0.4, 0], 3, 2, max_photons=20_000, tessellation_estimate=True)
    for key in ("tessellation", "tessellation_estimate", "tessellation_estimate_stderr"):
        assert g.error_budget[key].shape == (2, 3) and np.all(g.error_budget[key] >= 0)


def test_an_estimate_too_large_to_refine_is_refused_before_anything_runs(monkeypatch):
    """Two splits multiply the triangles by 16: past `MAX_TRIANGLES` the query is refused (a ValueError naming the
    option), not run out of memory."""
    import tracer.simulate as simulate
    from tracer.simulate import SimulationError

    sim, n = focus_dish(0.01, 0.5)
    monkeypatch.setattr(simulate, "MAX_TRIANGLES", 16 * n - 1)
    with pytest.raises(SimulationError, match="tessellation_estimate") as info:
        sim.illuminance([[0, 0, 3.0]], [[0, 0, -1.0]], max_photons=1000, tessellation_estimate=True)
    assert isinstance(info.value, ValueError)
