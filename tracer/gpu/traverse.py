"""Ray queries on a CUDA device: the committed scene's arrays on the card and closest-hit / any-hit kernels.

The device holds the very :class:`tracer.accel.traverse.SceneArrays` the CPU walks (one layout, one builder), uploaded
by :class:`DeviceScene` once per revision: the geometry store (bottom levels, triangles, normals) only when it
changed, the instances and top levels every time (a move changes those alone). The kernels call the CPU's own
traversal (:func:`tracer.accel.traverse.closest_with_stacks`, :func:`tracer.accel.traverse.any_with_stacks`), which
numba-cuda compiles for the device from the same Python; each thread's traversal stacks are ``cuda.local.array``\\ s.

Importing this module imports numba-cuda (``lumenlink[gpu]``). Tests run it in numba-cuda's simulator
(``NUMBA_ENABLE_CUDASIM=1``, tests/tracer/gpu/test_gpu_traverse.py); no figure from a real GPU is measured yet.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import float64, int64
from numba.core import config

from tracer.accel.traverse import STACK_LEN, SceneArrays, any_with_stacks, closest_with_stacks
from tracer.gpu import cuda as _cuda

cuda = _cuda()
#: numba-cuda's simulator (NUMBA_ENABLE_CUDASIM=1): kernels run as Python threads on the CPU
SIMULATOR = bool(config.ENABLE_CUDASIM)

#: SceneArrays fields of the geometry store (append-only): uploaded only when they changed
STORE_FIELDS = ("bvh_f", "bvh_i", "tri_v", "tri_prim", "prim_slot", "tri_n", "geom_node0", "geom_tri0", "geom_ntri",
                "geom_has_normals")
#: the instances and the top levels: what a move changes, uploaded with every revision
TOP_FIELDS = tuple(f for f in SceneArrays._fields if f not in STORE_FIELDS)

THREADS = 128   # threads per block of the ray kernels


def array_identity(a: np.ndarray) -> tuple:
    """What tells a host array apart from a changed one without reading it: its memory, shape and type (the store
    is append-only: a geometry added or rebuilt moves or grows it)."""
    return a.__array_interface__["data"][0], a.shape, a.dtype.str


class DeviceScene:
    """A scene's committed arrays on the device; :meth:`update` with each new revision's ``scene.arrays()``."""

    def __init__(self, sa: SceneArrays):
        self._dev: dict[str, Any] = {}   # numba-cuda device arrays by field
        self._ids: dict[str, tuple] = {}
        #: fields sent by the last :meth:`update` (tests check that a move sends only the top level)
        self.uploaded: tuple[str, ...] = ()
        self.uploaded_bytes = 0
        self.update(sa)

    def update(self, sa: SceneArrays) -> tuple[str, ...]:
        sent = []
        nbytes = 0
        for name in SceneArrays._fields:
            host = np.ascontiguousarray(getattr(sa, name))
            ident = array_identity(getattr(sa, name))
            if name in STORE_FIELDS and self._ids.get(name) == ident:
                continue
            self._dev[name] = cuda.to_device(host)
            self._ids[name] = ident
            sent.append(name)
            nbytes += host.nbytes
        self.uploaded = tuple(sent)
        self.uploaded_bytes = nbytes
        self.arrays = SceneArrays(**{name: self._dev[name] for name in SceneArrays._fields})
        return self.uploaded

    def _kernel_arrays(self) -> SceneArrays:
        """The tuple a kernel takes: the device arrays; in numba-cuda's simulator, which runs a kernel as Python and
        the traversal it calls as the CPU's compiled code (that cannot take the simulator's array wrappers), what
        those device arrays hold, read back from them."""
        if SIMULATOR:
            return SceneArrays(*(self._dev[name].copy_to_host() for name in SceneArrays._fields))
        return self.arrays

    def intersect(self, origins, directions, t_max=np.inf):
        """Closest hits, as :meth:`tracer.Scene.intersect`: (t, instance, primitive, u, v, normal (k, 3))."""
        o, d, tm = _rays(origins, directions, t_max)
        k = len(o)
        out_t, out_i, out_p = (cuda.device_array(k, np.float64), cuda.device_array(k, np.int64),
                               cuda.device_array(k, np.int64))
        out_u, out_v, out_n = (cuda.device_array(k, np.float64), cuda.device_array(k, np.float64),
                               cuda.device_array((k, 3), np.float64))
        if k:
            closest_kernel[(k + THREADS - 1) // THREADS, THREADS](
                self._kernel_arrays(), cuda.to_device(o), cuda.to_device(d), cuda.to_device(tm), out_t, out_i, out_p,
                out_u, out_v, out_n)
        return (out_t.copy_to_host(), out_i.copy_to_host(), out_p.copy_to_host(), out_u.copy_to_host(),
                out_v.copy_to_host(), out_n.copy_to_host())

    def occluded(self, origins, directions, t_max=np.inf) -> np.ndarray:
        """(k,) bool, as :meth:`tracer.Scene.occluded`."""
        o, d, tm = _rays(origins, directions, t_max)
        k = len(o)
        out = cuda.device_array(k, np.bool_)
        if k:
            any_kernel[(k + THREADS - 1) // THREADS, THREADS](
                self._kernel_arrays(), cuda.to_device(o), cuda.to_device(d), cuda.to_device(tm), out)
        return out.copy_to_host()


def _rays(origins, directions, t_max):
    o = np.ascontiguousarray(origins, np.float64).reshape(-1, 3)
    d = np.ascontiguousarray(directions, np.float64).reshape(-1, 3)
    tm = np.ascontiguousarray(np.broadcast_to(np.asarray(t_max, np.float64), (len(o),)))
    if d.shape != o.shape:
        raise ValueError(f"origins and directions must both be (k, 3), got {o.shape} and {d.shape}")
    return o, d, tm


def closest_rays(sa, o, d, t_max, out_t, out_inst, out_prim, out_u, out_v, out_n):
    """One thread per ray: its closest hit through the CPU's own walk, with stacks in the thread's local memory."""
    i = cuda.grid(1)
    if i >= o.shape[0]:
        return
    stack = cuda.local.array(STACK_LEN, int64)
    tstack = cuda.local.array(STACK_LEN, float64)
    t, inst, prim, u, v, nx, ny, nz = closest_with_stacks(sa, o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1], d[i, 2],
                                                          t_max[i], stack, tstack)
    out_t[i] = t
    out_inst[i] = inst
    out_prim[i] = prim
    out_u[i] = u
    out_v[i] = v
    out_n[i, 0] = nx
    out_n[i, 1] = ny
    out_n[i, 2] = nz


def any_rays(sa, o, d, t_max, out):
    """One thread per ray: is anything hit before t_max (sensors ignored)?"""
    i = cuda.grid(1)
    if i >= o.shape[0]:
        return
    stack = cuda.local.array(STACK_LEN, int64)
    tstack = cuda.local.array(STACK_LEN, float64)
    out[i] = any_with_stacks(sa, o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1], d[i, 2], t_max[i], stack, tstack)


closest_kernel = cuda.jit(closest_rays, cache=True)
any_kernel = cuda.jit(any_rays, cache=True)
