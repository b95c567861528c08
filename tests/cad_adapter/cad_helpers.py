"""Shared helpers of the CAD adapter tests: fixture paths, cached sample builds, coarse settings."""

from __future__ import annotations

import functools

import pytest
from conftest import SHARED_FIXTURES

STEP_DIR = SHARED_FIXTURES / "step"
AS1 = STEP_DIR / "as1-oc-214.stp"
STAMP = STEP_DIR / "Stamp-S3.step"
SERVO = STEP_DIR / "STS3215_03a.step"
CUBE_CYL = STEP_DIR / "red_cube_blue_cylinder.step"
S1C5 = STEP_DIR / "s1-c5-214" / "s1-c5-214.stp"

needs_fixtures = pytest.mark.skipif(not STEP_DIR.is_dir(), reason=f"shared STEP fixtures not found at {STEP_DIR}")

#: coarse tessellation for quick tests (document units: mm)
COARSE = {"linear": 1.0, "angular": 0.8}


@functools.lru_cache(maxsize=8)
def car(door_angle_deg: float = 0.0, lens_radius_mm: float = 120.0):
    """The sample car (cached: building it costs seconds). Callers must not modify it."""
    from cad_adapter.samples import car_assembly

    return car_assembly(door_angle_deg=door_angle_deg, lens_radius_mm=lens_radius_mm)
