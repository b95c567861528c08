"""One frozen query (issue 55): `tracer.transport.query.query` checks a request's options once, and `Simulation.run`
answers the same for the object as for its options."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from tests.tracer.transport_scenes import box, scene_of
from tracer.errors import SimulationError
from tracer.simulate import Simulation
from tracer.transport.query import DEFAULT_MAX_SECONDS, Budget, Query, query


@pytest.mark.parametrize(("options", "message"), [
    ({"target_relative_error": 1.5}, "target_relative_error must be in (0, 1)"),
    ({"max_seconds": -1}, "max_seconds must be > 0"),
    ({"max_photons": 2.5}, "max_photons must be a positive integer"),
    ({"target_scope": "best"}, "target_scope must be one of"),
    ({"seed": -1}, "seed must be an integer"),
    ({"estimator": "psychic"}, "estimator must be one of"),
    ({"force_effects": ["warp_drive"]}, "force_effects: unknown effect(s) ['warp_drive']"),
    ({"force_effects": "polarization"}, "force_effects must be a list of effects"),
    ({"force_effects_off": ["lambertian"]}, "force_effects_off: ['lambertian'] cannot be forced off"),
    ({"force_effects": ["polarization"], "force_effects_off": ["polarization"]}, "also forced on"),
    ({"observe": ["stoke"]}, "observe: unknown observable(s) ['stoke']"),
    ({"physics_left_out": ["spectral", "spectral"]}, "physics_left_out lists each effect once"),
    ({"reference": [0, float("nan"), 1]}, "reference must be 3 finite numbers"),
    ({"tessellation_estimate": "yes"}, "tessellation_estimate must be true or false"),
])
def test_each_bad_option_is_refused_once_naming_it(options, message):
    with pytest.raises(SimulationError) as info:
        query(**options)
    assert message in str(info.value)


def test_a_query_keeps_what_was_asked_and_defaults_the_seconds_only_where_no_rule_is_stated():
    q = query(max_photons=1000, seed=3, observe=["stokes"], reference=[0, 1, 0], physics_left_out=["polarization"])
    assert q.budget == Budget(None, None, 1000, "worst") and q.budget.stop_rules() == q.budget
    assert (q.seed, q.observe, q.reference, q.physics_left_out) == (3, ("stokes",), (0.0, 1.0, 0.0),
                                                                  ("polarization",))
    assert q.observes == (False, True)
    assert q.forced == ("polarization",)   # what the Stokes vector needs
    assert query(force_effects=["coating"], observe=["stokes", "spectrum"]).forced == ("coating", "spectral",
                                                                                       "polarization")
    assert query().budget.stop_rules() == Budget(None, DEFAULT_MAX_SECONDS, None, "worst")
    with pytest.raises(dataclasses.FrozenInstanceError):
        q.seed = 4   # type: ignore[misc]


def test_run_answers_the_same_for_the_query_as_for_its_options():
    s, ids = scene_of(box([-2, -2, 0], [2, 2, 2.5]))
    sim = Simulation(s, {ids[0]: {"type": "lambertian", "reflectance": 0.5}},
                     [{"type": "point", "position": [0.2, -0.1, 2.0], "intensity_cd": 1000.0}])
    body = {"type": "points", "points": [[0.0, 0.0, 0.0], [1.0, 0.3, 0.0]], "normals": [[0, 0, 1], [0, 0, 1]],
            "radius": 0.3}
    options = {"max_photons": 4000, "seed": 7, "estimator": "forward"}
    a = sim.run(body, **options)
    b = sim.run(body, query=query(**options))
    assert np.array_equal(a.lux, b.lux) and np.array_equal(a.stderr, b.stderr) and a.photons == b.photons
    c = sim.run(body, query=dataclasses.replace(query(**options), seed=8))
    assert not np.array_equal(a.lux, c.lux)   # the seed it carries is the one that runs
    with pytest.raises(SimulationError, match="not both"):
        sim.run(body, query=query(**options), seed=7)
    with pytest.raises(SimulationError, match="must be a tracer.transport.query.Query"):
        sim.run(body, query={"seed": 7})
    assert isinstance(query(**options), Query)
