"""The demo car's scene, as `lumenlink demo` dresses it and the benchmarks measure it (`bench/bench_luminance.py`,
`bench/bench_polarization_default.py`): its materials, a concrete floor, its lights and sensors, put onto a pushed
car through the REST API (`dress`), and the edits the demo makes."""

from __future__ import annotations

from pathlib import Path
from typing import Any


class MissingPart(RuntimeError):
    """A part of LumenLink the demo needs is not there yet.

    Parameters
    ----------
    part : str
        What is missing (a module, a function, an endpoint).
    issue : int
        The issue that builds it.
    detail : str
        What went wrong when the demo tried to use it.
    """

    def __init__(self, part: str, issue: int, detail: str = "") -> None:
        super().__init__(f"{part} is not built yet (issue {issue})" + (f": {detail}" if detail else ""))
        self.part = part
        self.issue = issue


def check(response: Any, what: str) -> Any:
    """The JSON of a 2xx answer, or a RuntimeError quoting the service's problem detail."""
    if response.status_code == 404 and "Not Found" in response.text and "detail" not in response.text:
        raise MissingPart(f"the endpoint behind {what}", 5, response.text)
    if response.status_code == 503:
        detail = response.json().get("detail", response.text)
        raise MissingPart(f"the part behind {what}", 6, detail)
    if response.status_code // 100 != 2:
        raise RuntimeError(f"{what} failed: HTTP {response.status_code}: {response.text[:500]}")
    return response.json() if response.content else None


#: Cells of the floor sensor (the e2e test and `--photons` keep these; photon counts scale the noise).
GRID_NU, GRID_NV = 32, 24
LENS_RADIUS_BEFORE_MM = 120.0  # the sample's default lens
LENS_RADIUS_AFTER_MM = 75.0  # a more strongly curved lens: a narrower, brighter low beam
DOOR_OPEN_DEG = 65.0
SCENE_NAME = "demo car"

PAINT = {"type": "mix", "diffuse": 0.35, "specular": 0.05}
GLASS = {"type": "dielectric", "ior": 1.5}
TYRE = {"type": "black"}
CHROME = {"type": "mirror", "reflectance": 0.9}
CONCRETE = {"type": "lambertian", "reflectance": 0.25}

# Where the demo asks for illuminance (world metres: x forward, y to the left, z up, origin on the
# ground under the middle of the car); receivers are horizontal disks facing up.
NAMED_POINTS = {
    "road 3 m ahead of the left headlamp": (5.0, 0.54, 0.0),
    "road 1.5 m ahead of the bumper": (3.5, 0.0, 0.0),
    "ground outside the left door": (0.3, 1.6, 0.0),
    "bonnet, above the engine": (1.6, 0.0, 1.0),
}
POINT_RADIUS = 0.2  # m: a receiver that forward photons actually hit
# Time budgets (s) of the four queries, so that the demo stays under two minutes on a slow or busy
# machine whatever --photons says; each answer names the rule that stopped it.
GRID_SECONDS = 10.0
POINTS_SECONDS = 5.0

# The floor sensor: 8 m × 6 m of floor in front of the car, front side up (u × v = +z).
GRID = {"type": "grid", "name": "floor in front of the car", "origin": [2.2, -2.5, 0.0], "u": [8.0, 0.0, 0.0],
        "v": [0.0, 6.0, 0.0], "nu": GRID_NU, "nv": GRID_NV}


def floor_mesh(half: float = 15.0) -> tuple[Any, Any]:
    import numpy as np

    v = np.array([[-half, -half, 0.0], [half, -half, 0.0], [half, half, 0.0], [-half, half, 0.0]], np.float32)
    return v, np.array([[0, 1, 2], [0, 2, 3]], np.uint32)


def lights(uuid_of: dict[str, str]) -> dict[str, dict[str, Any]]:
    """The car's lights by key: a 5000 cd spot inside the left headlamp (attached to its node, in its frame, m) and a
    532 lm downlight from a real IES file (RAB DLED6R8Y), 3 m up."""
    ies = (Path(__file__).parent / "data" / "rab_dled6r8y_7.ies").read_text()
    return {
        "headlamp": {"type": "spot", "name": "left low beam", "attached_to": uuid_of["headlamp"],
                     # inside the housing, just behind the lens, in the headlamp's frame (m)
                     "position": [-0.0025, 0.0, 0.0], "direction": [1.0, 0.0, -0.1],
                     "cone_deg": 25.0, "falloff_deg": 8.0, "intensity_cd": 5000.0},
        "ceiling": {"type": "goniometric", "name": "ceiling downlight (RAB DLED6R8Y, IES)",
                    "position": [3.5, 0.5, 3.0], "format": "ies", "data": ies},
    }


def dress(http: Any, scene_id: str, uuid_of: dict[str, str],
          light_keys: tuple[str, ...] = ("headlamp", "ceiling")) -> None:
    """Dress a pushed car (`uuid_of`: node name -> UUID) through the service (`http`, an httpx client at its base
    URL): paint on the car (its body and doors inherit it), glass in the windscreen and the headlamp's lens, a chrome
    reflector, black tyres; a 30 m x 30 m concrete floor owned by the simulation (pushes never touch it); the lights
    of `light_keys` (`lights`). A refusal raises `RuntimeError` quoting the service (`check`)."""
    from cad_adapter.glb import encode_glb
    from tracer.geometry_id import geometry_id

    for name, material in (("car", PAINT), ("windscreen", GLASS), ("lens", GLASS), ("housing", CHROME),
                           *((w, TYRE) for w in ("wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr"))):
        check(http.put(f"/scenes/{scene_id}/materials/{uuid_of[name]}", json=material), f"material of {name}")
    fv, ft = floor_mesh()
    fgid = geometry_id(fv, ft)
    check(http.put(f"/geometries/{fgid}", content=encode_glb(fv, ft), headers={"content-type": "model/gltf-binary"}),
          "uploading the floor")
    check(http.post(f"/scenes/{scene_id}/objects", json={"geometry": fgid, "mesh_unit": "m", "name": "floor",
                                                          "material": CONCRETE}), "adding the floor")
    bodies = lights(uuid_of)
    for key in light_keys:
        check(http.post(f"/scenes/{scene_id}/lights", json=bodies[key]), f"adding the {key} light")


def add_sensors(http: Any, scene_id: str, uuid_of: dict[str, str]) -> tuple[str, str]:
    """The floor grid (`GRID`) and a surface sensor on the car: their ids."""
    grid = check(http.post(f"/scenes/{scene_id}/sensors", json=GRID), "adding the floor sensor")["id"]
    surface = check(http.post(f"/scenes/{scene_id}/sensors", json={"type": "surface", "node": uuid_of["car"],
                                                                   "name": "the car in lux"}),
                    "adding the car's surface sensor")["id"]
    return grid, surface
