"""A query reads the scene and changes nothing: its receivers live in a structure of their own."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from tracer.scene import Scene
from tracer.simulate import Simulation
from tracer.warmup import box


def test_concurrent_queries_neither_change_the_scene_nor_each_other():
    scene = Scene()
    room = scene.add_instance(scene.add_geometry(*box((0, 0, 0), (4, 4, 3))), np.eye(4))
    glass = scene.add_instance(scene.add_geometry(*box((1, 1, 0.5), (2, 2, 1))), np.eye(4))
    scene.commit()
    arrays, ids = scene.arrays(), scene.instances()
    materials = {room: {"type": "lambertian", "reflectance": 0.5}, glass: {"type": "dielectric", "ior": 1.5}}
    sim = Simulation(scene, materials, [{"type": "point", "position": [2, 2, 2.5], "intensity_cd": 100.0}])
    pts, nrm = np.array([[1.5, 1.5, 0.0], [3.0, 3.0, 0.0]]), np.array([[0, 0, 1.0], [0, 0, 1.0]])

    def point_query(seed):
        return sim.illuminance(pts, nrm, max_photons=40_000, seed=seed, estimator="forward").lux

    def grid_query(seed):
        return sim.grid([0, 0, 0], [4, 0, 0], [0, 4, 0], 4, 4, max_photons=40_000, seed=seed).lux

    alone = [point_query(1), grid_query(2)]
    with ThreadPoolExecutor(4) as pool:
        together = list(pool.map(lambda job: job[0](job[1]), [(point_query, 1), (grid_query, 2)] * 2))
    for i, lux in enumerate(together):   # the same seed gives the same answer, whatever runs beside it
        np.testing.assert_array_equal(lux, alone[i % 2])
    assert scene.arrays() is arrays and scene.instances() == ids and not scene.dirty
