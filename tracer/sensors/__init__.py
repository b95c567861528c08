"""Sensors: what a query measures (docs/DESIGN.md, "tracer/sensors/"): receivers at points, a disk, a grid of cells, the
model's own triangles, the far field. One module per kind beside the contract (`base`), one dispatch (`dispatch`:
the registry and `run`). `tracer.simulate.Simulation.run(sensor, ...)` answers any registered kind.
"""
