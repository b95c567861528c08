"""The `measured_brdf` kind (issue 38) against closed forms, through the switch the transport kernel inlines
(`scatter_contract.Case`: a flat quad, front side +z, node frame = world, N photons each on its own stream).

- A table of the constant ρ/π is the Lambertian surface: the carried weight is ρ within 4σ at 0° and 50°, cos²θo and
  the azimuth are uniform (10 and 8 bins within 4 binomial σ); through the transport kernel a beam onto a floor
  gives the same illuminance on an off-axis receiver as `lambertian` (the difference within 4 combined σ).
- Energy in one cell only: every surviving photon leaves inside that cell's θo and |Δφ| bounds, on the specular
  side, in the share a(θi) = f · 2Δφ_w (cos²θa − cos²θb) / 2 (within 4 binomial σ).
- Between two measured θi rows the albedo is their linear interpolation.
- The text format reads to the same table as the inline one; bad tables name their field (albedo > 1 included).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scatter_contract import Case, mean_and_error

from tracer.optics.surfaces import lambertian, measured_brdf
from tracer.optics.surfaces.base import CONTINUES, MaterialError, spec_from_body

WHITE = ("white", 0.0, 0.0, 0.0, 0.0)
K = 4.0
N = 20_000
TO = [0, 15, 30, 45, 60, 75, 90]
DP = [0, 45, 90, 135, 180]


def spec(table):
    return spec_from_body(measured_brdf.Spec, "measured_brdf", {"type": "measured_brdf", "table": table}, "test")


def arriving(theta_deg: float) -> np.ndarray:
    t = math.radians(theta_deg)
    return -np.array([math.sin(t), 0.0, math.cos(t)])


def constant(rho: float, ti=(0, 30, 60, 85)) -> dict:
    return {"theta_i_deg": list(ti), "theta_o_deg": TO, "dphi_deg": DP,
            "brdf": [[[rho / math.pi] * (len(DP) - 1)] * (len(TO) - 1)] * len(ti)}


def binomial_ok(counts, p, n):
    return np.all(np.abs(counts - p * n) <= K * np.sqrt(n * p * (1 - p)))


@pytest.mark.parametrize("theta", [0.0, 50.0])
def test_a_constant_table_is_the_lambertian_surface(theta):
    rho = 0.6
    out, _ = Case(measured_brdf, spec(constant(rho)), "front", theta, arriving(theta), WHITE).run(n=N, seed=3)
    alive = out[:, 0] == CONTINUES
    mean, err = mean_and_error(np.where(alive, out[:, 4], 0.0))
    assert abs(mean - rho) <= K * max(err, math.sqrt(rho * (1 - rho) / N)), (mean, err)
    wo = out[alive, 1:4]
    assert np.all(wo[:, 2] > 0) and np.allclose(np.linalg.norm(wo, axis=1), 1.0)
    m = len(wo)
    assert binomial_ok(np.histogram(wo[:, 2] ** 2, bins=10, range=(0, 1))[0], 0.1, m)
    az = (np.arctan2(wo[:, 1], wo[:, 0]) / (2 * math.pi)) % 1.0
    assert binomial_ok(np.histogram(az, bins=8, range=(0, 1))[0], 1 / 8, m)


def test_energy_in_one_cell_goes_into_that_cell():
    # cell θo ∈ [30°, 45°), Δφ ∈ [135°, 180°] (the specular side), the same in every θi row
    w = 2 * math.radians(45) * (math.cos(math.radians(30)) ** 2 - math.cos(math.radians(45)) ** 2) / 2
    f = 0.5 / w
    cell = [[[0.0] * 4 for _ in range(6)] for _ in range(2)]
    for r in cell:
        r[2][3] = f
    s = spec({"theta_i_deg": [0, 70], "theta_o_deg": TO, "dphi_deg": DP, "brdf": cell})
    assert s.table.albedo() == pytest.approx([0.5, 0.5])
    out, _ = Case(measured_brdf, s, "front", 40.0, arriving(40.0), WHITE).run(n=N, seed=4)
    alive = out[:, 0] == CONTINUES
    assert binomial_ok(np.array([alive.sum()]), 0.5, N), alive.sum()
    wo = out[alive, 1:4]
    th = np.degrees(np.arccos(wo[:, 2]))
    # Δφ from the plane of incidence on the source's side (the source is towards +x)
    src = -arriving(40.0)
    dphi = np.degrees(np.abs(np.arctan2(wo[:, 1], wo[:, 0]) - math.atan2(src[1], src[0])))
    dphi = np.minimum(dphi, 360 - dphi)
    assert np.all((th >= 30 - 1e-9) & (th <= 45 + 1e-9)), (th.min(), th.max())
    assert np.all(dphi >= 135 - 1e-9), dphi.min()
    # within the cell, cos²θo is uniform (the cosθo dω density)
    u = (wo[:, 2] ** 2 - math.cos(math.radians(45)) ** 2) / (math.cos(math.radians(30)) ** 2 - 0.5)
    assert binomial_ok(np.histogram(u, bins=5, range=(0, 1))[0], 0.2, len(u))


def test_between_two_rows_the_albedo_is_interpolated():
    table = {"theta_i_deg": [0, 60], "theta_o_deg": [0, 90], "dphi_deg": [0, 180],
             "brdf": [[[0.2 / math.pi]], [[0.8 / math.pi]]]}
    out, _ = Case(measured_brdf, spec(table), "front", 30.0, arriving(30.0), WHITE).run(n=N, seed=5)
    alive = (out[:, 0] == CONTINUES).mean()
    assert abs(alive - 0.5) <= K * math.sqrt(0.25 / N), alive


def test_the_text_format_reads_as_the_inline_table(tmp_path):
    inline = constant(0.3, ti=(0, 45))
    lines = ["# a test table", "theta_i_deg 0 45", "theta_o_deg " + " ".join(map(str, TO)),
             "dphi_deg " + " ".join(map(str, DP))]
    lines += [" ".join(repr(0.3 / math.pi) for _ in DP[1:]) for _ in range(2 * (len(TO) - 1))]
    path = tmp_path / "paint.brdf.txt"
    path.write_text("\n".join(lines) + "\n")
    body = measured_brdf.load(path)
    assert spec_from_body(measured_brdf.Spec, "measured_brdf", body, "t") == spec(inline)
    assert spec(inline).table.albedo() == pytest.approx([0.3, 0.3])


def _too_bright():
    t = constant(0.5)
    t["brdf"] = [row for row in t["brdf"]]
    t["brdf"][2] = [[1.2 / math.pi] * 4] * 6
    return t


@pytest.mark.parametrize(("table", "match"), [
    (_too_bright(), r"'table.brdf' reflects more than it receives: its directional albedo at theta_i = 60° is 1.2 > 1"),
    ({**constant(0.5), "brdf": [[[-0.1] * 4] * 6] * 4}, "'table.brdf' must be finite and ≥ 0"),
    ({**constant(0.5), "brdf": [[[float("nan")] * 4] * 6] * 4}, "'table.brdf' must be finite"),
    ({**constant(0.5), "brdf": [[[0.1] * 3] * 6] * 4}, "'table.brdf' must have shape"),
    ({**constant(0.5), "theta_o_deg": [0, 45, 80]}, "'table.theta_o_deg' are bin edges from 0 to 90"),
    ({**constant(0.5), "dphi_deg": [0, 90, 90, 180]}, "'table.dphi_deg' must be strictly increasing"),
    ({**constant(0.5), "theta_i_deg": [0, 30, 60, 90]}, "'table.theta_i_deg' must lie in [0, 90)"),
    ({"theta_i_deg": [0], "theta_o_deg": TO, "dphi_deg": DP}, "missing 'table.brdf'"),
    ("theta_i_deg 0\ntheta_o_deg 0 90\ndphi_deg 0 180\n0.1 0.2\n", "needs 1 × 1 lines of 1 values"),
    (3, "'table' must be an object"),
])
def test_bad_tables_name_their_field(table, match):
    with pytest.raises(MaterialError) as info:
        spec(table)
    assert match in str(info.value), str(info.value)


def test_through_the_transport_kernel_a_constant_table_lights_a_receiver_as_lambertian_does():
    """A 100 lx beam straight down onto a floor; a receiver (radius 0.2 m) at (1, 0, 1) facing down sees the spot
    at 45°: the same illuminance, within 4 combined σ, for `lambertian` ρ = 0.7 and the table of 0.7/π."""
    from tracer.scene import Scene
    from tracer.simulate import Simulation
    from tracer.warmup import box

    s = Scene()
    plane = s.add_instance(s.add_geometry(*box([-50, -50, -0.1], [50, 50, 0.0])), np.eye(4))
    s.commit()
    beam = {"type": "collimated", "origin": [0, 0, 2.0], "direction": [0, 0, -1], "radius": 0.01,
            "illuminance_lx": 100.0}
    got = []
    for mat in ({"type": "lambertian", "reflectance": 0.7}, {"type": "measured_brdf", "table": constant(0.7)}):
        sim = Simulation(s, {plane: mat}, [beam])
        res = sim.illuminance([[1.0, 0, 1.0]], [[0, 0, -1.0]], radius=0.2, max_photons=40_000, seed=2)
        got.append((res.lux[0], res.stderr[0]))
    (a, ea), (b, eb) = got
    # closed form of the Lambertian spot, for scale: E = ρ Φ cos²45° / (π r²) with r² = 2, Φ = 100 lx · π 0.01²
    assert a == pytest.approx(0.7 * 100 * math.pi * 1e-4 * 0.5 / (math.pi * 2), rel=0.2)
    assert abs(a - b) <= K * math.hypot(ea, eb), (a, ea, b, eb)
    assert lambertian.NAME == "lambertian"
