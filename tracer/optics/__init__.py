"""Optics as plugins: what light sources, surfaces, media and optical elements do to a photon.

One folder per family (`lights/`, `surfaces/`, `media/`, `elements/`). In each, `base.py` states the
contract every kind of that family keeps (what its functions take and return, in which units, which
effects it declares), one module per kind implements it (its typed spec, its packing into the family's
arrays, its jitted functions), and `dispatch.py` is the registration: the one place that lists the
kinds and switches on a kind id. `frames.py` holds the vector helpers every family uses.

Every jitted function here is plain Python over floats and arrays, `@njit(cache=True)`, written so that
numba-cuda's `cuda.jit(device=True)` can compile the same source (no allocation, no exceptions, no
Python objects in kernels).
"""
