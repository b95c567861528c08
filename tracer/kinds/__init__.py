"""Bottom-level kinds: what an instance of the top level can be.

Each kind is one module holding its integer ``KIND`` tag, whether it is a ``SENSOR`` (recorded by
:func:`tracer.accel.traverse.sensor_crossings`, invisible to closest-hit and any-hit queries), its
object-space bounds where these are fixed, and its jitted intersection routines in object space
(the contract: :mod:`tracer.kinds.base`). :mod:`tracer.kinds.dispatch` is the only place that switches
on the tag (pbrt's TaggedPointer dispatch), written out from `REGISTRY`: a new kind is one module here
plus its entry in `REGISTRY`.
"""

from tracer.kinds import disk_sensor, mesh, rect_sensor, relief

#: every registered kind module, indexed by its tag
REGISTRY = {m.KIND: m for m in (mesh, disk_sensor, rect_sensor, relief)}
SENSOR_KINDS = frozenset(k for k, m in REGISTRY.items() if m.SENSOR)

__all__ = ["REGISTRY", "SENSOR_KINDS", "disk_sensor", "mesh", "rect_sensor", "relief"]
