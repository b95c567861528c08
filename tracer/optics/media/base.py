"""The medium contract: absorption and scattering between surfaces.

A medium fills the inside of a solid (a `dielectric` instance); the space outside every solid is a
vacuum of index 1. The material table carries, per instance, the medium kind (``M.medium[i]``,
`NO_MEDIUM` for a clear solid) and its parameter row ``M.mpar[i]`` (`tracer.optics.surfaces.base`).
A medium kind is one module in this folder holding:

- ``Spec`` (the fields of its body; today they live on the dielectric that holds the medium),
- ``effects(spec)``, the effects it calls for,
- jitted ``coefficients(M, mi, lam) -> (σa, σs, σf)`` in 1/m at λ nm (0 for a white photon): absorption
  is applied to the photon's weight as a continuous factor exp(−σa t) (no sampling noise, exact 0 on
  underflow); the distance to the next event is sampled with density σ exp(−σ t), σ = σs + σf;
- jitted ``event(M, mi, dx, dy, dz, lam, sig_s, sig_f, key, dim) -> (alive, dx, dy, dz, lam, f, dim)``:
  what that event does: scatter (a new unit direction), or absorb and re-emit (`fluorescence`: a new
  wavelength, the power factor f), or absorb (alive False); ``dim`` advanced past the numbers drawn.

`dispatch` lists the kinds and is the only place that switches on a medium kind.
"""
