"""Counter-based random numbers for the transport kernels.

A random number is a pure function of (seed, batch, path, dimension): no state is carried between
paths, so a batch gives the same numbers whatever thread runs it, in whatever order, on whatever
machine. The hash is SplitMix64's finaliser (Stafford's "Mix13"), a bijection of 64-bit words with
full avalanche; keys are chained through it, so neighbouring counters give unrelated streams.

Use: ``key = path_key(seed, batch, path)``, then ``uniform(key, d)`` for d = 0, 1, 2, … along the
path (a path keeps its own dimension counter).
"""

from __future__ import annotations

import numpy as np

from tracer.jit import njit

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S11 = np.uint64(11)
_INV53 = 1.0 / 9007199254740992.0  # 2**-53


@njit(cache=True, inline="always")
def mix64(z):
    """SplitMix64 finaliser: a bijective 64-bit mixer (uint64 → uint64).

    Compiled lazily, not with an explicit ``uint64(uint64)`` signature: numba-cuda refuses to compile for the GPU
    a CPU dispatcher whose signatures were fixed in advance ("its compilation is disabled"), and the same source
    serves both targets (tracer/gpu). Every caller passes a uint64; the cast keeps it so for any other."""
    z = np.uint64(z)
    z = (z ^ (z >> _S30)) * _M1
    z = (z ^ (z >> _S27)) * _M2
    return z ^ (z >> _S31)


@njit(cache=True)
def path_key(seed, batch, path):
    """Key of one path: a hash of (seed, batch index, path index within the batch), each an integer ≥ 0."""
    k = mix64(np.uint64(seed) + _GOLDEN)
    k = mix64(k ^ (np.uint64(batch) * _GOLDEN + np.uint64(0x632BE59BD9B4E019)))
    return mix64(k ^ (np.uint64(path) * _M1 + _GOLDEN))


@njit(cache=True)
def uniform(key, dim):
    """The `dim`-th uniform number of a path, in [0, 1) with 53 random bits."""
    z = mix64(key + (np.uint64(dim) + np.uint64(1)) * _GOLDEN)
    return float(z >> _S11) * _INV53


def uniforms(seed: int, batch: int, path: int, n: int) -> np.ndarray:
    """The first `n` uniforms of one path, as a float64 array (n,) (for tests and Python-side sampling)."""
    if seed < 0 or batch < 0 or path < 0 or n < 0:
        raise ValueError(f"seed, batch, path and n must be >= 0, got {seed}, {batch}, {path}, {n}")
    return _uniforms(seed, batch, path, n)


@njit(cache=True)
def _uniforms(seed, batch, path, n):
    key = path_key(seed, batch, path)
    out = np.empty(n, np.float64)
    for d in range(n):
        out[d] = uniform(key, d)
    return out
