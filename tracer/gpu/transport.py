"""Photon batches on a CUDA device: one thread runs one batch, exactly as the CPU's batch loop does.

The CPU runs batches one after the other (:func:`tracer.transport.forward.forward_batches`,
:func:`tracer.transport.backward.backward_batches`); here thread ``b`` of a launch runs batch ``batch0 + b`` through
the very same njit function the CPU's loop body calls (:func:`tracer.transport.forward.trace_photons`,
:func:`tracer.transport.backward.backward_batch`), which numba-cuda compiles for the device from the same Python.
What the CPU allocates per batch (the medium stack, the sensor-crossing buffers, the traversal stacks, the Stokes
vector) is the thread's ``cuda.local.array``; the thread writes its own tally row ``values[b]`` and counter row
``counters[b]``. Same batch size and seed ⇒ the same random numbers (`tracer.rng`, keyed by (seed, batch, photon));
per-batch tallies ⇒ the estimator's error bars are unchanged. Answers agree with the CPU's within error bars, not
bit for bit (a card may contract a·b + c to one rounding).

Outputs travel in a :class:`Tallies` tuple. In numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``), which runs a
kernel as Python and the njit functions it calls as the CPU's compiled code, the tuple holds host arrays (the
simulator would wrap a top-level array in an object the CPU code cannot take); on a card, device arrays.

The kernels are cached on disk (numba-cuda's ``cache=True``, in numba's cache directory, `tracer.numba_cache_dir`):
a process compiles them once per card's compute capability, later processes load them (unmeasured on a card yet).

Importing this module imports numba-cuda (``lumenlink[gpu]``). No figure from a real GPU is measured yet.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import float64, int64

from tracer.accel.traverse import STACK_LEN
from tracer.gpu.traverse import SIMULATOR, cuda
from tracer.optics.polarization import N_POL
from tracer.transport.backward import backward_batch
from tracer.transport.forward import MEDIUM_DEPTH, SENSOR_CAP, trace_photons

__all__ = ["SIMULATOR", "THREADS", "Tallies", "backward_kernel", "backward_threads", "forward_kernel",
           "forward_threads"]

THREADS = 32   # threads per block: one batch each, a round has tens of batches


class Tallies(NamedTuple):
    """What a launch writes: values (n_batches, bins) float64, counters (n_batches, n_counters) int64."""

    values: np.ndarray
    counters: np.ndarray


def forward_threads(sa, ra, M, L, S, n_bins, seed, batch0, photons, w0, out):
    """Thread b: forward batch batch0 + b of `photons` photons of weight `w0`, into out.values[b] and
    out.counters[b] (the body of `tracer.transport.forward.forward_batches`'s loop)."""
    b = cuda.grid(1)
    if b >= out.values.shape[0]:
        return
    med = cuda.local.array(MEDIUM_DEPTH, int64)
    c_inst = cuda.local.array(SENSOR_CAP, int64)
    c_t = cuda.local.array(SENSOR_CAP, float64)
    c_u = cuda.local.array(SENSOR_CAP, float64)
    c_v = cuda.local.array(SENSOR_CAP, float64)
    c_cos = cuda.local.array(SENSOR_CAP, float64)
    stack = cuda.local.array(STACK_LEN, int64)
    tstack = cuda.local.array(STACK_LEN, float64)
    pol = cuda.local.array(N_POL, float64)
    for i in range(N_POL):
        pol[i] = 0.0
    trace_photons(sa, ra, M, L, S, n_bins, seed, batch0 + b, photons, w0, out.values[b], out.counters[b], med,
                  c_inst, c_t, c_u, c_v, c_cos, stack, tstack, pol)


def backward_threads(sa, M, L, Q, seed, batch0, paths, out):
    """Thread b: backward batch batch0 + b, `paths` paths per query patch, into out.values[b] and out.counters[b]
    (the body of `tracer.transport.backward.backward_batches`'s loop)."""
    b = cuda.grid(1)
    if b >= out.values.shape[0]:
        return
    stack = cuda.local.array(STACK_LEN, int64)
    tstack = cuda.local.array(STACK_LEN, float64)
    backward_batch(sa, M, L, Q, seed, batch0 + b, paths, out.values[b], out.counters[b], stack, tstack)


forward_kernel = cuda.jit(forward_threads, cache=True)
backward_kernel = cuda.jit(backward_threads, cache=True)
