"""What a measurement is asked, as one frozen object: checked once (`query`), then carried unchanged from
`tracer.simulate.Simulation.run` (or the service's route, which builds it from the request) through a sensor kind, the
pilots of ``physics_left_out``, the tessellation estimate and a camera's bands, to the rounds and the kernels.

A band or a pilot is the same query with a field replaced (`dataclasses.replace`): what is not replaced stays as it
was checked. What only the scene can tell (an effect forced off that something in the scene requires, a polarization
reference along a receiver's normal, an estimator the scene cannot take) is checked when the query runs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from tracer.effects import EFFECTS, EffectError, check_off
from tracer.errors import SimulationError
from tracer.sensors.base import vec3

ESTIMATORS = ("auto", "forward", "backward")
OBSERVABLES = ("spectrum", "stokes")
TARGET_SCOPES = ("worst", "lit", "mean")
DEFAULT_MAX_SECONDS = 60.0     # s: budget of a query that states none, in the tracer and through the service


@dataclass(frozen=True)
class Budget:
    """A query's stop rules: target relative error (a fraction), seconds, photons, and the target's scope
    (`TARGET_SCOPES`); None: no such rule. The one budget of the project: the tracer's rounds stop by it (a query
    that states none stops after `DEFAULT_MAX_SECONDS`: `stop_rules`), the service's jobs estimate the time left from
    it (`service.jobs`)."""

    target: float | None = None
    max_seconds: float | None = None
    max_photons: int | None = None
    scope: str = "worst"

    def stop_rules(self) -> Budget:
        """The rules the rounds stop by: these, or `DEFAULT_MAX_SECONDS` where none is stated."""
        if self.target is None and self.max_seconds is None and self.max_photons is None:
            return Budget(None, DEFAULT_MAX_SECONDS, None, self.scope)
        return self


@dataclass(frozen=True)
class Query:
    """One measurement's request (see the module docstring; `Simulation.run` says what each field does).

    budget : `Budget` (stop rules as stated, None where not).  seed : int in [0, 2**63).
    estimator : one of `ESTIMATORS`.  force_effects, force_effects_off : effect names (`tracer.effects.EFFECTS`).
    physics_left_out : effect names, or names of `LEFT_OUT_MODELS`.  observe : names of `OBSERVABLES`.
    reference : (3,) floats or None.
    tessellation_estimate : bool.
    """

    budget: Budget = Budget()
    seed: int = 0
    estimator: str = "auto"
    force_effects: tuple[str, ...] = ()
    force_effects_off: tuple[str, ...] = ()
    observe: tuple[str, ...] = ()
    reference: tuple[float, float, float] | None = None
    physics_left_out: tuple[str, ...] = ()
    tessellation_estimate: bool = False

    @property
    def observes(self) -> tuple[bool, bool]:
        """Whether the query observes the spectrum, and whether the Stokes vector."""
        return "spectrum" in self.observe, "stokes" in self.observe

    @property
    def forced(self) -> tuple[str, ...]:
        """The effects the query forces on: `force_effects`, then what its observables need (the spectrum: photons
        that carry a wavelength, `spectral`; the Stokes vector: `polarization`)."""
        spectrum, stokes = self.observes
        return (*self.force_effects, *(("spectral",) if spectrum else ()), *(("polarization",) if stokes else ()))


#: what ``physics_left_out`` measures beside the effects: a model the scene uses in place of the exact one
LEFT_OUT_MODELS = ("element_geometry",)   # the elements' micro-geometry where their tabulated BSDF stands for it


def query(target_relative_error=None, max_seconds=None, max_photons=None, seed=0, estimator="auto",
          force_effects=(), force_effects_off=(), observe=(), reference=None, physics_left_out=(),
          target_scope="worst", tessellation_estimate=False) -> Query:
    """A `Query` from the options `Simulation.run` takes, each checked here once; `SimulationError` naming the
    option and what it takes."""
    forced = _names(force_effects, EFFECTS, "force_effects", "effect")
    try:
        off = check_off(force_effects_off, forced, {})   # all but what only the scene knows (an effect it requires)
    except EffectError as exc:
        raise SimulationError(str(exc)) from None
    return Query(check_budget(target_relative_error, max_seconds, max_photons, target_scope), _seed(seed),
                 _one_of(estimator, ESTIMATORS, "estimator"), forced, off,
                 _names(observe, OBSERVABLES, "observe", "observable"),
                 _reference(reference),
                 _names(physics_left_out, (*EFFECTS, *LEFT_OUT_MODELS), "physics_left_out", "effect", once=True),
                 _flag(tessellation_estimate, "tessellation_estimate"))


def check_budget(target_relative_error, max_seconds, max_photons, scope="worst") -> Budget:
    """The stop rules checked, as stated (None stays None): `SimulationError` naming the one out of range."""
    if target_relative_error is not None:
        if isinstance(target_relative_error, bool) or not (0 < float(target_relative_error) < 1):
            raise SimulationError(f"target_relative_error must be in (0, 1), got {target_relative_error!r}")
        target_relative_error = float(target_relative_error)
    if max_seconds is not None:
        if isinstance(max_seconds, bool) or not (0 < float(max_seconds) < math.inf):
            raise SimulationError(f"max_seconds must be > 0 and finite, got {max_seconds!r}")
        max_seconds = float(max_seconds)
    if max_photons is not None:
        if isinstance(max_photons, bool) or int(max_photons) != max_photons or int(max_photons) < 1:
            raise SimulationError(f"max_photons must be a positive integer, got {max_photons!r}")
        max_photons = int(max_photons)
    if scope not in TARGET_SCOPES:
        raise SimulationError(f"target_scope must be one of {list(TARGET_SCOPES)}, got {scope!r}")
    return Budget(target_relative_error, max_seconds, max_photons, scope)


def _seed(seed: Any) -> int:
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or not 0 <= seed < 2 ** 63:
        raise SimulationError(f"seed must be an integer in [0, 2**63), got {seed!r}")
    return int(seed)


def _one_of(value: Any, allowed: tuple[str, ...], name: str) -> str:
    if value not in allowed:
        raise SimulationError(f"{name} must be one of {list(allowed)}, got {value!r}")
    return str(value)


def _names(names: Any, known: tuple[str, ...], name: str, what: str, once: bool = False) -> tuple[str, ...]:
    """A list of names from `known` (None: none); `SimulationError` for a string, another type or an unknown name."""
    if names is None:
        return ()
    if isinstance(names, str) or not isinstance(names, list | tuple):
        raise SimulationError(f"{name} must be a list of {what}s {list(known)}, got {names!r}")
    unknown = [e for e in names if e not in known]
    if unknown:
        raise SimulationError(f"{name}: unknown {what}(s) {unknown}; known: {list(known)}")
    if once and len(set(names)) != len(names):
        raise SimulationError(f"{name} lists each {what} once, got {list(names)}")
    return tuple(str(e) for e in names)


def _reference(reference: Any) -> tuple[float, float, float] | None:
    """The polarization frames' reference axis as three floats (`SimulationError` unless three finite numbers)."""
    if reference is None:
        return None
    x, y, z = (float(v) for v in vec3(reference, "reference"))
    return x, y, z


def _flag(value: Any, name: str) -> bool:
    if not isinstance(value, bool | np.bool_):
        raise SimulationError(f"{name} must be true or false, got {value!r}")
    return bool(value)
