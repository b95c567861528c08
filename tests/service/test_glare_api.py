"""UGR and luminance uniformity through the REST API (issue 37), each value with its error bar.

Uniformity: a Lambertian floor of reflectance ρ under a point source of intensity I; nine meters look straight down
at the 9-point figure of a 2 × 1.2 m rectangle. Each reads ρ I cosθ / (π r²) within 4 of its standard errors, and
min/max and min/mean of the readings lie within 4 of their propagated standard errors of the same ratios of the
closed forms. The 13-point figure (issue 53, the SPWG pattern) likewise, its points where the pattern puts them.

UGR: one luminaire, a square panel of exitance M (luminance M/π) facing the observer above the line of sight, the
room black, the background luminance given (CIE 117-1995: L_b = E_ind/π, here stated). The panel lies parallel to
the camera's film and its edges fall on pixel boundaries, so every pixel is either all panel or all black: the image
is exact, with no noise. The answer is compared with CIE 117's formula for the luminaire as one source,
UGR = 8 log₁₀(0.25/L_b · L² ω / p²), with ω the panel's exact solid angle and p the Luckiesh–Guth position index at
its centre (the closed form in `tracer.photometry.glare`). No published worked example with numbers was found in
the references searched (CIE 117 itself is not openly available); this case is computed from the standard's
definitions. The image evaluates p and ω pixel by pixel (as Radiance's evalglare does): its sum converges to
L² ∫ dω / p² over the panel (midpoint rule on 10 × 10 pixels against 400 × 400: within 0.005 UGR), which exceeds
CIE's one-source value L² ω / p(centre)² by 2.3 % here (1/p² is convex over the panel's 11.3°): 0.08 UGR, asserted
as such (within 0.02).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from service_helpers import glb, lit_floor, make_client, node, uid

from lumenlink.errors import LumenLinkError
from tracer.photometry.glare import guth_position_index, ugr, uniformity

I_CD, H, RHO, SIDE, Z = 100.0, 1.5, 0.6, 6.0, 4.0
LIGHT = np.array([0.0, 0.0, H])
NINE = {"origin": [-1.0, -0.6, 0.0], "u": [2.0, 0.0, 0.0], "v": [0.0, 1.2, 0.0]}

# the UGR case: the eye at (0, 0, 1.2) looks along +y; the panel in the plane y = D, facing the eye
EYE_Z, D, M_EXIT, L_B = 1.2, 3.0, 3000.0, 20.0
PANEL_X, PANEL_Z = (0.30, 0.90), (EYE_Z + 0.60, EYE_Z + 1.20)   # on the film: x/D, (z − 1.2)/D in 0.02 pixel steps
HALF_TAN = 0.6    # tan(fov/2): 60 rows of 0.02 on the film
CAMERA = {"type": "camera", "position": [0.0, 0.0, EYE_Z], "look_at": [0.0, D, EYE_Z], "up": [0.0, 0.0, 1.0],
          "fov_deg": math.degrees(2 * math.atan(HALF_TAN)), "width": 80, "height": 60, "name": "observer"}


@pytest.fixture(scope="module")
def client(tmp_path_factory: Any) -> Any:
    with make_client(Path(tmp_path_factory.mktemp("glare")), max_points=10_000) as c:
        yield c


def _put(client: Any, v: np.ndarray, f: np.ndarray) -> str:
    gid, data = glb(v, f)
    assert client.put(f"/geometries/{gid}", content=data, headers={"content-type": "model/gltf-binary"}
                      ).status_code in (200, 201)
    return gid


@pytest.fixture(scope="module")
def floor(client: Any) -> str:
    return lit_floor(client, SIDE, RHO, {"type": "point", "position": LIGHT.tolist(), "intensity_cd": I_CD})


def floor_luminance(x: np.ndarray) -> np.ndarray:
    d = LIGHT - x
    r2 = np.sum(d * d, axis=-1)
    return RHO * I_CD * (H / np.sqrt(r2)) / r2 / math.pi


def test_nine_point_uniformity_of_the_floor(client: Any, floor: str) -> None:
    r = client.post(f"/scenes/{floor}/luminance/uniformity",
                    json={"nine_points": NINE, "direction": [0.0, 0.0, -1.0], "distance": 0.5, "aperture_deg": 1.0,
                          "max_photons": 9 * 6000, "seed": 3})
    assert r.status_code == 200, r.text
    out = r.json()
    pts = np.array(out["points"])
    assert out["figure"] == "9-point" and pts.shape == (9, 3)
    np.testing.assert_allclose(pts[0], [-1.0 + 2 / 6, -0.6 + 1.2 / 6, 0.0], atol=1e-12)
    np.testing.assert_allclose(np.array(out["positions"]) - pts, [[0.0, 0.0, 0.5]] * 9, atol=1e-12)
    lum, err = np.array(out["luminance"]), np.array(out["stderr"])
    exact = floor_luminance(pts)   # the 1° cone's spot (9 mm across) moves E by < 1e-4
    assert np.all(err > 0) and np.all(np.abs(lum - exact) <= Z * err + 1e-4 * exact), (lum, err, exact)
    u = out["uniformity"]
    assert u == pytest.approx(uniformity(lum, err), rel=1e-12)   # the figures are those of the readings
    truth = uniformity(exact)
    for name in ("min_max", "min_mean"):
        assert u[f"{name}_stderr"] > 0
        assert abs(u[name] - truth[name]) <= Z * u[f"{name}_stderr"] + 2e-4, (name, u, truth)
    assert out["estimator"] == "backward" and out["unreachable"] is None and out["photons"] > 0
    assert out["revision"] == client.get(f"/scenes/{floor}").json()["revision"]


def test_the_uniformity_picture_marks_each_point_with_its_reading(client: Any, floor: str) -> None:
    """Issue 53, pictures an engineer reads: ?format=png draws the points where they look (world mm), each coloured on
    a scale from the smallest reading to the largest and labelled with its reading, the uniformity in the title."""
    from service.maps import uniformity_figure

    body = {"nine_points": NINE, "direction": [0.0, 0.0, -1.0], "max_photons": 9 * 2000, "seed": 6}
    r = client.post(f"/scenes/{floor}/luminance/uniformity?format=png", json=body)
    assert r.status_code == 200 and r.headers["content-type"] == "image/png" and r.content[:4] == b"\x89PNG", r.text
    out = client.post(f"/scenes/{floor}/luminance/uniformity", json=body).json()   # the same seed: the same answer
    fig = uniformity_figure(out)
    ax = fig.axes[0]
    dots = ax.collections[0]
    np.testing.assert_allclose(dots.get_offsets(), 1000.0 * np.array(out["points"])[:, :2])
    assert dots.norm.vmin == min(out["luminance"]) and dots.norm.vmax == max(out["luminance"])
    labels = [t.get_text() for t in ax.texts]
    assert len(labels) == 9 and labels[0].startswith(f"1: {out['luminance'][0]:.4g} ± ")
    u = out["uniformity"]
    assert f"min/max {u['min_max']:.3f} ± {u['min_max_stderr']:.3f}" in ax.get_title()
    assert ax.get_xlabel() == "world x (mm)" and ax.get_ylabel() == "world y (mm)"
    r = client.post(f"/scenes/{floor}/luminance/uniformity?format=png&mode=async", json=body)
    assert r.status_code == 422 and "mode=sync" in r.text


def test_thirteen_point_uniformity_of_the_floor(client: Any, floor: str) -> None:
    """The SPWG 13-point figure: the points where the pattern puts them (10 mm from the edges, quarters, middle) and
    each reading the floor's closed form within 4 of its standard errors."""
    r = client.post(f"/scenes/{floor}/luminance/uniformity",
                    json={"thirteen_points": {**NINE, "inset": 0.05}, "direction": [0.0, 0.0, -1.0], "distance": 0.5,
                          "aperture_deg": 1.0, "max_photons": 13 * 6000, "seed": 4})
    assert r.status_code == 200, r.text
    out = r.json()
    pts = np.array(out["points"])
    assert out["figure"] == "13-point" and pts.shape == (13, 3)
    o, su, sv = np.array(NINE["origin"]), 2.0, 1.2
    a, b = 0.05 / su, 0.05 / sv
    want = [(s, t) for t, ss in ((b, (a, 0.5, 1 - a)), (0.25, (0.25, 0.75)), (0.5, (a, 0.5, 1 - a)),
                                 (0.75, (0.25, 0.75)), (1 - b, (a, 0.5, 1 - a))) for s in ss]
    np.testing.assert_allclose(pts, [o + [s * su, t * sv, 0.0] for s, t in want], atol=1e-12)
    lum, err = np.array(out["luminance"]), np.array(out["stderr"])
    exact = floor_luminance(pts)
    assert np.all(err > 0) and np.all(np.abs(lum - exact) <= Z * err + 1e-4 * exact), (lum, err, exact)
    assert out["uniformity"] == pytest.approx(uniformity(lum, err), rel=1e-12)


def test_uniformity_of_listed_points(client: Any, floor: str) -> None:
    pts = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
    r = client.post(f"/scenes/{floor}/luminance/uniformity",
                    json={"points": pts, "direction": [0.0, 0.0, -2.0], "max_photons": 8000})
    assert r.status_code == 200, r.text
    out = r.json()
    assert out["figure"] == "points" and len(out["luminance"]) == 2
    lum, err = np.array(out["luminance"]), np.array(out["stderr"])
    exact = floor_luminance(np.array(pts))   # the 1° cone's spot moves E by < 1e-4 (under the lamp σ is ~1e-7)
    assert np.all(np.abs(lum - exact) <= Z * err + 1e-4 * exact)


@pytest.mark.parametrize("body, says", [
    ({"direction": [0, 0, -1]}, "one of points, nine_points or thirteen_points"),
    ({"points": [[0, 0, 0]], "nine_points": NINE, "direction": [0, 0, -1]}, "one of points"),
    ({"nine_points": NINE, "thirteen_points": NINE, "direction": [0, 0, -1]}, "one of points"),
    ({"thirteen_points": {**NINE, "inset": 0.6}, "direction": [0, 0, -1]}, "thirteen_points.inset"),
    ({"thirteen_points": {**NINE, "inset": 0}, "direction": [0, 0, -1]}, "inset"),
    ({"thirteen_points": {**NINE, "u": [0, 0, 0]}, "direction": [0, 0, -1]}, "thirteen_points.u is the zero vector"),
    ({"points": [[0, 0, 0]], "direction": [0, 0, 0]}, "direction"),
    ({"points": [[0, 0, 0]], "direction": [0, 0, -1], "distance": 0}, "distance"),
    ({"points": [[0, 0, 0]], "direction": [0, 0, -1], "aperture_deg": 200}, "aperture_deg"),
    ({"points": [[0, 0, 0]], "direction": [0, 0, -1], "estimator": "forward"}, "estimator"),
    ({"points": [[0, 0, 0]], "direction": [0, 0, -1], "observe": ["spectrum"]}, "observe"),
    ({"points": [[0, 0, "x"]], "direction": [0, 0, -1]}, "points"),
    ({"points": [[0, 0, 0]], "direction": [0, 0, -1], "max_photons": 10**12}, "max_photons"),
    ({"nine_points": {**NINE, "u": [0, 0, 0]}, "direction": [0, 0, -1]}, "nine_points.u is the zero vector"),
    ({"nine_points": {**NINE, "v": [0, 0, 0]}, "direction": [0, 0, -1]}, "nine_points.v is the zero vector"),
    ({"nine_points": {**NINE, "v": [2 * x for x in NINE["u"]]}, "direction": [0, 0, -1]}, "parallel"),
])
def test_bad_uniformity_queries_say_which_field(client: Any, floor: str, body: dict, says: str) -> None:
    before = client.get(f"/scenes/{floor}").json()
    r = client.post(f"/scenes/{floor}/luminance/uniformity", json=body)
    assert r.status_code == 422 and says in r.text, r.text
    assert client.get(f"/scenes/{floor}").json() == before


def panel_mesh() -> tuple[np.ndarray, np.ndarray]:
    """The panel in the plane y = D, wound so that its front side faces −y (the eye)."""
    (x0, x1), (z0, z1) = PANEL_X, PANEL_Z
    v = np.array([[x0, D, z0], [x0, D, z1], [x1, D, z1], [x1, D, z0]], float)
    return v, np.array([[0, 2, 1], [0, 3, 2]])


def rectangle_solid_angle(x0: float, x1: float, y0: float, y1: float, d: float) -> float:
    """The solid angle of the rectangle [x0, x1] × [y0, y1] at distance d, parallel to the view plane (the corner
    formula Ω(x, y) = atan(x y / (d √(d² + x² + y²))), summed with signs)."""
    def corner(x: float, y: float) -> float:
        return math.atan(x * y / (d * math.sqrt(d * d + x * x + y * y)))
    return corner(x1, y1) - corner(x0, y1) - corner(x1, y0) + corner(x0, y0)


def test_ugr_of_one_panel_matches_the_cie_formula(client: Any) -> None:
    sid = client.post("/scenes", json={"name": "glare"}).json()["id"]
    gid = _put(client, *panel_mesh())
    doc = {"base_revision": 0, "length_unit": "m",
           "nodes": [node(uid(10), None, "room"), node(uid(11), uid(10), "panel", None, gid)]}
    assert client.put(f"/scenes/{sid}/document", json=doc).status_code == 200
    assert client.put(f"/scenes/{sid}/materials/{uid(11)}", json={"type": "black"}).status_code in (200, 201)
    assert client.post(f"/scenes/{sid}/lights", json={"type": "area", "node": uid(11),
                                                      "exitance_lm_m2": M_EXIT}).status_code == 201
    cid = client.post(f"/scenes/{sid}/sensors", json=CAMERA).json()["id"]
    assert client.get(f"/scenes/{sid}/sensors/{cid}/ugr").status_code == 404   # not simulated yet
    r = client.post(f"/scenes/{sid}/sensors/{cid}/simulate", json={"max_photons": 80 * 60 * 8, "seed": 1})
    assert r.status_code == 200, r.text
    img = np.array(r.json()["luminance"])
    assert np.sum(img > 0) == 100 and np.allclose(img[img > 0], M_EXIT / math.pi, rtol=1e-12)   # 10 × 10 pixels

    out = client.get(f"/scenes/{sid}/sensors/{cid}/ugr", params={"background": L_B})
    assert out.status_code == 200, out.text
    got = out.json()
    xc, zc = np.mean(PANEL_X), np.mean(PANEL_Z) - EYE_Z
    beta = math.degrees(math.atan(math.hypot(xc, zc) / D))
    alpha = math.degrees(math.atan2(xc, zc))
    omega = rectangle_solid_angle(*PANEL_X, PANEL_Z[0] - EYE_Z, PANEL_Z[1] - EYE_Z, D)
    cie = ugr([M_EXIT / math.pi], [omega], [float(guth_position_index(alpha, beta))], L_B)["ugr"]
    assert got["source_pixels"] == 100 and got["background"] == L_B and got["background_stderr"] == 0.0
    n = 400   # ∫ dω / p² over the panel, midpoint rule on n × n
    xs = PANEL_X[0] + (np.arange(n) + 0.5) / n * (PANEL_X[1] - PANEL_X[0])
    zs = PANEL_Z[0] - EYE_Z + (np.arange(n) + 0.5) / n * (PANEL_Z[1] - PANEL_Z[0])
    xx, zz = np.meshgrid(xs, zs)
    r2 = D * D + xx * xx + zz * zz
    d_omega = (PANEL_X[1] - PANEL_X[0]) * (PANEL_Z[1] - PANEL_Z[0]) / n ** 2 * D / r2 ** 1.5
    p = guth_position_index(np.degrees(np.arctan2(xx, zz)), np.degrees(np.arccos(D / np.sqrt(r2))))
    integral = 8 * math.log10(0.25 / L_B * (M_EXIT / math.pi) ** 2 * float((d_omega / p ** 2).sum()))
    assert got["ugr"] == pytest.approx(integral, abs=0.005), (got["ugr"], integral)
    assert got["ugr"] - cie == pytest.approx(8 * math.log10(1.0230), abs=0.02), (got["ugr"], cie)
    assert got["stderr"] < 1e-6 and got["revision"] == r.json()["revision"]
    assert got["position"] == CAMERA["position"]

    # the background from the image itself: every other pixel is black, so UGR is undefined, said so
    black = client.get(f"/scenes/{sid}/sensors/{cid}/ugr")
    assert black.status_code == 422 and "background" in black.json()["detail"]
    assert client.get(f"/scenes/{sid}/sensors/{cid}/ugr", params={"background": -1}).status_code == 422
    dark = client.get(f"/scenes/{sid}/sensors/{cid}/ugr", params={"background": L_B, "threshold": 1e6})
    assert dark.status_code == 422 and "no luminaire" in dark.json()["detail"]


def test_ugr_error_bar_propagates_the_pixels_errors() -> None:
    """σ_UGR = 8/ln10 √((σ_Σ/Σ)² + (σ_b/L_b)²): one source pixel, the background from the others."""
    from tracer.photometry.glare import pixel_geometry, ugr_from_image

    img = np.full((4, 4), 10.0)
    err = np.full((4, 4), 0.5)
    img[0, 1], err[0, 1] = 1e4, 100.0
    got = ugr_from_image(img, 60.0, stderr=err)
    omega, _, _ = pixel_geometry(60.0, 4, 4)
    rest = np.ones((4, 4), bool)
    rest[0, 1] = False
    s_b = math.sqrt(((0.5 * omega[rest]) ** 2).sum()) / omega[rest].sum()
    assert got["background"] == pytest.approx(10.0) and got["background_stderr"] == pytest.approx(s_b)
    assert got["stderr"] == pytest.approx(8 / math.log(10) * math.hypot(2 * 100 / 1e4, s_b / 10.0))


# ---------------------------------------------------------------- the Python client and the command line

def _client_on(client: Any) -> Any:
    """A `lumenlink.Client` talking to the test app (the TestClient's transport)."""
    from lumenlink import Client

    return Client("http://testserver", transport=client._transport)


def test_client_and_cli_uniformity_and_ugr(client: Any, floor: str, monkeypatch: Any) -> None:
    import json

    from typer.testing import CliRunner

    import lumenlink.commands_luminance as commands_luminance
    from lumenlink.cli import app

    with _client_on(client) as ll:
        out = ll.uniformity(floor, direction=(0, 0, -1), nine_points={"origin": NINE["origin"], "u": NINE["u"],
                                                                      "v": NINE["v"]}, max_photons=9000, seed=4)
        assert out["figure"] == "9-point" and len(out["luminance"]) == 9
        assert out["uniformity"]["min_max_stderr"] > 0
        out13 = ll.uniformity(floor, direction=(0, 0, -1), thirteen_points={**NINE, "inset": 0.05}, max_photons=13000,
                              seed=5)
        assert out13["figure"] == "13-point" and len(out13["luminance"]) == 13
        with pytest.raises(LumenLinkError, match="one of points, nine_points or thirteen_points"):
            ll.uniformity(floor, direction=(0, 0, -1), nine_points=NINE, thirteen_points=NINE)
        cam = ll.add_sensor(floor, {**CAMERA, "position": [0.0, -2.0, 1.0], "look_at": [0.0, 0.0, 1.0],
                                    "width": 16, "height": 12, "name": "lamp view"})
        ll.simulate(floor, "lamp view", max_photons=16 * 12 * 64)
        # the point lamp is in view, above the line of sight: the pixel it falls in is the luminaire
        rated = ll.ugr(floor, "lamp view")
        assert rated["source_pixels"] >= 1 and rated["stderr"] > 0 and rated["background"] > 0
        assert cam["id"]

    monkeypatch.setattr(commands_luminance, "Client", lambda server: _client_on(client))
    runner = CliRunner()
    r = runner.invoke(app, ["uniformity", "--scene", floor, "--direction", "0,0,-1", "--nine-points", "-1,-0.6,0",
                            "2,0,0", "0,1.2,0", "--max-photons", "9000", "--seed", "4", "--json"])
    assert r.exit_code == 0, r.output
    cli_out = json.loads(r.stdout)
    assert cli_out["luminance"] == out["luminance"] and cli_out["uniformity"] == out["uniformity"]   # same seed
    r = runner.invoke(app, ["uniformity", "--scene", floor, "--direction", "0,0,-1", "--thirteen-points",
                            "-1,-0.6,0", "2,0,0", "0,1.2,0", "--inset", "0.05", "--max-photons", "13000", "--seed",
                            "5", "--json"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["luminance"] == out13["luminance"]   # the client's figure, the same seed
    r = runner.invoke(app, ["uniformity", "--scene", floor, "--direction", "0,0,-1", "--point", "0,0,0", "--point",
                            "1,0,0", "--max-photons", "4000"])
    assert r.exit_code == 0, r.output
    assert r.stdout.splitlines()[0] == "point,x_m,y_m,z_m,cd_m2,stderr_cd_m2" and len(r.stdout.splitlines()) == 3
    assert "min/max" in r.output
    r = runner.invoke(app, ["ugr", "--scene", floor, "--sensor", "lamp view", "--latest", "--json"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["ugr"] == pytest.approx(rated["ugr"])
    r = runner.invoke(app, ["ugr", "--scene", floor, "--sensor", "lamp view", "--max-photons", "12288"])
    assert r.exit_code == 0 and r.stdout.startswith("UGR "), r.output
    # bad usage: exit 2, saying what to do
    r = runner.invoke(app, ["uniformity", "--scene", floor, "--direction", "0,0,-1"])
    assert r.exit_code == 2 and "--nine-points" in r.output
    r = runner.invoke(app, ["uniformity", "--scene", floor, "--direction", "0,0", "--point", "0,0,0"])
    assert r.exit_code == 2 and "--direction" in r.output
