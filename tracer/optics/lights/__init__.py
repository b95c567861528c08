"""Light sources as plugins: one module per kind, `base` the contract, `dispatch` the registration.

Kinds (body ``"type"``): ``point``, ``spot``, ``collimated``, ``goniometric``, ``area``; each module's
docstring lists its fields. Bodies may also carry `id`, `name` and `attached_to` (kept by the service,
ignored here); any other field is rejected. Units: m, lm, cd, lx, lm/m².
"""

from tracer.optics.lights.base import LightArrays, LightError, pick_light
from tracer.optics.lights.dispatch import connectable, light_connect, pack_lights, sample_emission
from tracer.optics.lights.spot import spot_solid_angle

__all__ = ["LightArrays", "LightError", "connectable", "light_connect", "pack_lights", "pick_light",
           "sample_emission", "spot_solid_angle"]
