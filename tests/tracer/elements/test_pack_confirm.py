"""A pack stops on its target only once a fresh seed confirms it (issue 53): the best of several noisy readings is
biased upwards, so a reading at the target is measured again with a seed none of the pack's measurements takes; where
the confirmation falls short, the two readings, pooled, correct the map, the photons rise, and the pack goes on.

The measurements here are scripted (a stand-in for `tracer.simulate.Simulation` that answers set maps), so that which
reading reaches the target is known; the scene, the element and the update are the real ones."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from tests.tracer.transport_scenes import box, scene_of
from tracer.elements import prepare
from tracer.elements.pack import confirmation_seed, pack

START = {"type": "microstructure", "feature": {"shape": "dome", "radius_mm": 0.25, "height_mm": 0.1},
         "layout": {"type": "density", "origin_mm": [0.0, 0.0], "size_mm": [30.0, 20.0], "fill": [[0.5] * 3] * 2,
                    "seed": 1, "pitch_mm": 0.6}}
SENSOR = {"type": "grid", "origin": [0.0, 0.0, 0.004], "u": [0.03, 0.0, 0.0], "v": [0.0, 0.02, 0.0], "nu": 3, "nv": 2}


def reading(min_max: float) -> np.ndarray:
    """A 2 x 3 map of 100 lx whose smallest cell is `min_max` of its largest."""
    lux = np.full((2, 3), 100.0)
    lux[0, 0] = 100.0 * min_max
    return lux


class Scripted:
    """Answers the maps of `script` in turn (1 % standard errors), and keeps the seeds and photons it was asked for."""

    def __init__(self, script: list[float]) -> None:
        self.script = list(script)
        self.asked: list[tuple[int, int]] = []

    def __call__(self, scene):   # `simulation(scene)`: the pack makes one per iteration
        return self

    def run(self, sensor, max_photons, seed, estimator, progress=None, cancel=None):
        self.asked.append((int(seed), int(max_photons)))
        lux = reading(self.script.pop(0))
        return SimpleNamespace(lux=lux, stderr=0.01 * lux, photons=int(max_photons))


def test_a_reading_at_the_target_is_confirmed_with_a_fresh_seed_before_the_pack_stops() -> None:
    s, (plate,) = scene_of(box([0.0, 0.0, 0.0], [0.03, 0.02, 0.003]))
    sim = Scripted([0.5,            # iteration 0: far from the target
                    0.85, 0.70,     # iteration 1 reaches 0.8; its confirmation does not: go on
                    0.84, 0.83])    # iteration 2 and its confirmation both reach it: stop
    res = pack(s, plate, prepare(START), SENSOR, sim, assign={"facing": [0, 0, -1], "mm_per_unit": 1000.0},
               target=0.8, photons=10_000, max_photons=1_000_000, max_iterations=6, seed=7)
    assert res.stopped == "target" and len(res.history) == 3 and res.best == 2
    h0, h1, h2 = res.history
    assert h0.confirmation is None
    assert h1.confirmation["confirmed"] is False and h1.confirmation["uniformity"] == 0.70
    assert h2.confirmation["confirmed"] is True and h2.confirmation["uniformity"] == 0.83
    seeds = [seed for seed, _ in sim.asked]
    assert seeds == [7 * 1009 + 0, 7 * 1009 + 1, confirmation_seed(7, 1), 7 * 1009 + 2, confirmation_seed(7, 2)]
    assert len(set(seeds)) == len(seeds)   # every reading its own photons
    # after the failed confirmation the next iteration takes four times the photons (the noise decides near the target)
    assert sim.asked[3][1] == 4 * sim.asked[1][1]
    assert not sim.script


def test_a_pack_that_never_confirms_keeps_the_best_pooled_reading_not_its_luckiest() -> None:
    s, (plate,) = scene_of(box([0.0, 0.0, 0.0], [0.03, 0.02, 0.003]))
    sim = Scripted([0.78, 0.90, 0.60, 0.79])   # iteration 1 read 0.90 once, 0.60 again: pooled 0.75 < 0.78, 0.79
    res = pack(s, plate, prepare(START), SENSOR, sim, assign={"facing": [0, 0, -1], "mm_per_unit": 1000.0},
               target=0.8, photons=10_000, max_photons=1_000_000, max_iterations=3, seed=3)
    assert res.stopped == "iterations" and len(res.history) == 3
    assert res.history[1].pooled()[0] == 0.75
    assert res.best == 2   # 0.79 read once beats 0.90 unconfirmed (pooled 0.75)
