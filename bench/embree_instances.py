"""Embree with instancing: the peer for our two-level scenes.

embreex binds triangle meshes only, so a two-level scene could be compared only with Embree's
single flattened BVH, which has no instancing cost at all. This module calls the Embree 4 library
that embreex ships (``embreex.libs/libembree4*.so``) through ctypes: one Embree scene per unique
geometry, one ``RTC_GEOMETRY_TYPE_INSTANCE`` per instance with its 3x4 transform, and a top scene
over them. Rays are traced one at a time with ``rtcIntersect1`` from a numba loop (a plain C call
per ray, as embreex's own loop makes), on one thread.
"""

from __future__ import annotations

import ctypes
import glob
import os
from ctypes import c_char_p, c_size_t, c_uint, c_uint64, c_void_p

import numpy as np
from numba import njit

# rtcore_common.h / rtcore_geometry.h / rtcore_buffer.h (Embree 4)
GEOMETRY_TRIANGLE = 0
GEOMETRY_INSTANCE = 121
BUFFER_INDEX = 0
BUFFER_VERTEX = 1
FORMAT_UINT3 = 0x5003
FORMAT_FLOAT3 = 0x9003
FORMAT_FLOAT3X4_ROW_MAJOR = 0x9134
INVALID_ID = 0xFFFFFFFF
#: bytes per RTCRayHit record, with room for the optional instPrimID field; 16-byte aligned
RECORD = 96


def _library() -> ctypes.CDLL | None:
    try:
        import embreex
    except ImportError:
        return None
    libs = glob.glob(os.path.join(os.path.dirname(os.path.dirname(embreex.__file__)), "embreex.libs",
                                  "libembree4*.so*"))
    if not libs:
        return None
    lib = ctypes.CDLL(libs[0])
    sig = {
        "rtcNewDevice": (c_void_p, [c_char_p]),
        "rtcNewScene": (c_void_p, [c_void_p]),
        "rtcNewGeometry": (c_void_p, [c_void_p, c_uint]),
        "rtcSetNewGeometryBuffer": (c_void_p, [c_void_p, c_uint, c_uint, c_uint, c_size_t, c_size_t]),
        "rtcSetGeometryInstancedScene": (None, [c_void_p, c_void_p]),
        "rtcSetGeometryTransform": (None, [c_void_p, c_uint, c_uint, c_void_p]),
        "rtcCommitGeometry": (None, [c_void_p]),
        "rtcAttachGeometry": (c_uint, [c_void_p, c_void_p]),
        "rtcReleaseGeometry": (None, [c_void_p]),
        "rtcCommitScene": (None, [c_void_p]),
        "rtcReleaseScene": (None, [c_void_p]),
        "rtcReleaseDevice": (None, [c_void_p]),
        "rtcGetDeviceError": (c_uint, [c_void_p]),
        # pointers as 64-bit integers, so the numba loop can pass addresses it computes
        "rtcIntersect1": (None, [c_uint64, c_uint64, c_uint64]),
    }
    for name, (res, args) in sig.items():
        fn = getattr(lib, name)
        fn.restype = res
        fn.argtypes = args
    return lib


_LIB = _library()


def available() -> bool:
    return _LIB is not None


class InstancedScene:
    """An Embree top scene over instances of per-geometry scenes (built on construction).

    ``geometries``: list of ``(vertices (n, 3), triangles (m, 3))``; ``instances``: list of
    ``(geometry index, 4x4 world-from-object transform)``.
    """

    def __init__(self, geometries: list, instances: list) -> None:
        if _LIB is None:
            raise RuntimeError("embreex (and its Embree 4 library) is not installed")
        lib = _LIB
        self._dev = lib.rtcNewDevice(b"")
        self._scenes = []
        for v, f in geometries:
            s = lib.rtcNewScene(self._dev)
            g = lib.rtcNewGeometry(self._dev, GEOMETRY_TRIANGLE)
            v32 = np.ascontiguousarray(v, np.float32)
            f32 = np.ascontiguousarray(f, np.uint32)
            # Embree reads vertices 16 bytes at a time: its own buffer carries the padding
            ctypes.memmove(lib.rtcSetNewGeometryBuffer(g, BUFFER_VERTEX, 0, FORMAT_FLOAT3, 12, len(v32)),
                           v32.ctypes.data, v32.nbytes)
            ctypes.memmove(lib.rtcSetNewGeometryBuffer(g, BUFFER_INDEX, 0, FORMAT_UINT3, 12, len(f32)),
                           f32.ctypes.data, f32.nbytes)
            lib.rtcCommitGeometry(g)
            lib.rtcAttachGeometry(s, g)
            lib.rtcReleaseGeometry(g)
            lib.rtcCommitScene(s)
            self._scenes.append(s)
        self._top = lib.rtcNewScene(self._dev)
        for gi, m in instances:
            g = lib.rtcNewGeometry(self._dev, GEOMETRY_INSTANCE)
            lib.rtcSetGeometryInstancedScene(g, self._scenes[gi])
            xf = np.ascontiguousarray(np.asarray(m, np.float64)[:3, :4], np.float32)
            lib.rtcSetGeometryTransform(g, 0, FORMAT_FLOAT3X4_ROW_MAJOR, xf.ctypes.data)
            lib.rtcCommitGeometry(g)
            lib.rtcAttachGeometry(self._top, g)
            lib.rtcReleaseGeometry(g)
        lib.rtcCommitScene(self._top)
        err = lib.rtcGetDeviceError(self._dev)
        if err:
            raise RuntimeError(f"Embree error {err} while building the scene")

    def intersect(self, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Closest hit of each ray: ``(t, instance)``, ``inf`` and -1 on a miss (one thread)."""
        o32 = np.ascontiguousarray(o, np.float32)
        d32 = np.ascontiguousarray(d, np.float32)
        t = np.empty(len(o32), np.float32)
        inst = np.empty(len(o32), np.int64)
        raw = np.zeros(RECORD + 16, np.uint8)
        rec = raw[(-raw.ctypes.data) % 16:][:RECORD]
        _trace(self._top, o32, d32, rec.view(np.float32), rec.view(np.uint32), rec.ctypes.data, t, inst)
        return t, inst

    def close(self) -> None:
        for s in self._scenes + [self._top]:
            _LIB.rtcReleaseScene(s)
        _LIB.rtcReleaseDevice(self._dev)
        self._scenes = []


_intersect1 = _LIB.rtcIntersect1 if _LIB is not None else None


@njit(cache=False)   # it calls a ctypes function, which numba cannot cache
def _trace(scene, o, d, rf, ru, addr, out_t, out_inst):
    """One ``rtcIntersect1`` per ray through the record at ``addr`` (``rf``/``ru``: its float and
    unsigned views; field offsets of ``RTCRayHit`` in 4-byte words)."""
    for i in range(o.shape[0]):
        rf[0] = o[i, 0]
        rf[1] = o[i, 1]
        rf[2] = o[i, 2]
        rf[3] = 0.0            # tnear
        rf[4] = d[i, 0]
        rf[5] = d[i, 1]
        rf[6] = d[i, 2]
        rf[7] = 0.0            # time
        rf[8] = np.inf         # tfar
        ru[9] = INVALID_ID     # mask: all
        ru[10] = 0             # id
        ru[11] = 0             # flags
        ru[18] = INVALID_ID    # geomID
        ru[19] = INVALID_ID    # instID[0]
        _intersect1(scene, addr, 0)
        if ru[18] == INVALID_ID:
            out_t[i] = np.inf
            out_inst[i] = -1
        else:
            out_t[i] = rf[8]
            out_inst[i] = ru[19]
