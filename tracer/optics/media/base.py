"""The medium contract: absorption and scattering between surfaces.

A medium fills the inside of a solid (a `dielectric` instance: its ``medium``, ``{"type": NAME, ...}``); the space
outside every solid is a vacuum of index 1. The material table carries, per instance, the medium kind
(``M.medium[i]``, `NO_MEDIUM` for a clear solid) and its parameter row ``M.mpar[i]``
(`tracer.optics.surfaces.base`). A medium kind is one module in this folder holding:

- ``NAME``, the wire `type`, and ``Spec``, a frozen dataclass of its body's fields (``bounds(...)`` and
  ``optional(...)`` metadata as a surface's; ``check()`` for rules across fields): the service's wire model is made
  from it (`service.optics`);
- ``host_check(spec, host_ior) -> str | None``: what is wrong with it inside a solid of that index (Mie particles
  are relative to their host);
- ``row(spec, host_ior) -> (N_MPAR,)``, ``tables(spec, host_ior) -> {column: (GRID_N,) values}``,
  ``phase(spec, host_ior) -> rows or None`` (a Mie table) and ``clear(spec)``: what `dispatch.pack_medium` packs (a
  field whose metadata names an ``mcolumn`` and varies with λ gets its table there by itself);
- ``effects(spec)`` and ``polarizing(spec) -> (interactions, largest diattenuation)`` (`tracer.effects`);
- jitted ``coefficients(M, mi, lam) -> (σa, σs, σf)`` in 1/m at λ nm (0 for a white photon): absorption
  is applied to the photon's weight as a continuous factor exp(−σa t) (no sampling noise, exact 0 on
  underflow); the distance to the next event is sampled with density σ exp(−σ t), σ = σs + σf;
- jitted ``event(M, mi, dx, dy, dz, lam, sig_s, sig_f, key, dim, pol) -> (alive, dx, dy, dz, lam, f, dim)``:
  what that event does: scatter (a new unit direction), or absorb and re-emit (`fluorescence`: a new
  wavelength, the power factor f), or absorb (alive False); ``dim`` advanced past the numbers drawn.

`dispatch` lists the kinds (``KINDS``: a new kind is its module and one entry there) and is the only place that
switches on a medium kind.
"""
