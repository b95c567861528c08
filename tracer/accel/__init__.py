"""The BVH engine: bottom and top levels, their traversal, and the on-disk library of bottom levels.

- :mod:`tracer.accel.blas`: the bottom level, binned-SAH BVHs over triangles, built many at a time, packed
  into 4-wide quantised rows.
- :mod:`tracer.accel.tlas`: the top level over instance boxes (the same builder), its records and refits.
- :mod:`tracer.accel.rows8`: the solid top level's 8-wide float32 rows and their vector slab test.
- :mod:`tracer.accel.wide`: the walk of one ray through a mesh's 4-wide rows (slab tests, near-first order,
  the traversal stack, the cache hint).
- :mod:`tracer.accel.triangle`: the watertight ray-triangle test.
- :mod:`tracer.accel.traverse`: :class:`~tracer.accel.traverse.SceneArrays` and the two-level walk that light
  transport calls from jitted code (docs/CONTRACTS.md).
- :mod:`tracer.accel.lanes`: the batch kernels behind ``Scene.intersect`` / ``Scene.occluded``.
- :mod:`tracer.accel.cache`: the on-disk library of prepared bottom-level topologies.

What a bottom level can be (a mesh, a sensor shape) is :mod:`tracer.kinds`; the mesh kind walks its rows here.
This package imports nothing on import: ``import tracer.accel.blas`` loads the builder alone.
"""
