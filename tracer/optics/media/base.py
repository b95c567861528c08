"""The medium contract: absorption and scattering between surfaces.

A medium fills the inside of a solid (a `dielectric` instance); the space outside every solid is a
vacuum of index 1. The material table carries, per instance, the medium kind (``M.medium[i]``,
`NO_MEDIUM` for a clear solid) and its parameter row ``M.mpar[i]`` (`tracer.optics.surfaces.base`).
A medium kind is one module in this folder holding:

- ``Spec`` (the fields of its body; today they live on the dielectric that holds the medium),
- ``effects(spec)``, the effects it calls for,
- jitted ``coefficients(M, mi) -> (σa, σs)`` in 1/m: absorption is applied to the photon's weight as a
  continuous factor exp(−σa t) (no sampling noise, exact 0 on underflow), scattering distances are
  sampled with density σs exp(−σs t);
- jitted ``scatter(M, mi, dx, dy, dz, u1, u2) -> (dx, dy, dz)``: the unit direction after a scattering
  event, from two uniform numbers in [0, 1).

`dispatch` lists the kinds and is the only place that switches on a medium kind.
"""
