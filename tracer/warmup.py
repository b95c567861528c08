"""Compile the kernels a first query needs before it arrives: `warm_kernels` (the service calls it in a
background thread when it starts).

numba compiles a kernel on its first call and keeps it in its on-disk cache. On a fresh install that
first call is the user's first query, which then waits for the compiler. `warm_kernels` makes those calls
on a tiny scene instead: a box room (Lambertian), a mirror and an absorbing glass block, lit by a point
light, queried once forward and once backward, so that scene building, commit, receiver placement, the
forward kernel (photon state "white", the one every effect needs today) and the backward kernel are
compiled (or loaded from the cache, in about a second) before anybody waits for them. A query that arrives while
they compile waits only for what is still compiling (numba's compiler lock), never compiles twice.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np


def _box(lo, hi):
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = np.array([[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
                  [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]], float)
    t = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                  [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])
    return v, t


def warm_kernels(progress: Callable[[str], None] | None = None) -> dict[str, float]:
    """Compile (or load) every kernel of a first query; seconds per stage: {"scene": s, "forward": s, "backward": s}.

    `progress(stage)` is called as each stage starts."""
    from tracer.scene import Scene
    from tracer.simulate import Simulation

    out: dict[str, float] = {}
    t = time.perf_counter()
    scene = Scene()
    room = scene.add_instance(scene.add_geometry(*_box((0, 0, 0), (4, 4, 3))), np.eye(4))
    mirror = scene.add_instance(scene.add_geometry(*_box((3.9, 1, 0.5), (3.95, 3, 2.5))), np.eye(4))
    glass = scene.add_instance(scene.add_geometry(*_box((1, 1, 0.5), (2, 2, 1))), np.eye(4))
    scene.commit()
    out["scene"] = time.perf_counter() - t
    materials = {room: {"type": "lambertian", "reflectance": 0.5}, mirror: {"type": "mirror", "reflectance": 0.9},
                 glass: {"type": "dielectric", "ior": 1.5, "absorption_per_m": 0.1}}
    light = [{"type": "point", "position": [2, 2, 2.5], "intensity_cd": 100.0}]
    sim = Simulation(scene, materials, light)
    points, normals = np.array([[2.5, 2.5, 0.0]]), np.array([[0.0, 0.0, 1.0]])
    if progress is not None:
        progress("forward")
    t = time.perf_counter()
    sim.illuminance(points, normals, max_photons=64, estimator="forward")
    out["forward"] = time.perf_counter() - t
    if progress is not None:
        progress("backward")
    t = time.perf_counter()
    Simulation(scene, {room: materials[room]}, light, default_material={"type": "black"}).illuminance(
        points, normals, max_photons=64, estimator="backward")
    out["backward"] = time.perf_counter() - t
    return out
