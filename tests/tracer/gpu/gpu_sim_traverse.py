"""Ray kernels of tracer/gpu/traverse.py against the CPU walk, and what a move uploads: run by
tests/tracer/gpu/test_gpu_traverse.py in a child with NUMBA_ENABLE_CUDASIM=1 (numba-cuda's simulator); prints one JSON
object with the comparisons, which the test checks.

Usage: NUMBA_ENABLE_CUDASIM=1 python tests/tracer/gpu/gpu_sim_traverse.py
"""

from __future__ import annotations

import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from tests.tracer.transport_scenes import box, icosphere  # noqa: E402
from tracer.scene import Scene  # noqa: E402


def rotation(axis, angle):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def small_scene():
    """A floor box, five spheres (one mirrored, one rotated and scaled), a disk sensor the rays must not see."""
    s = Scene()
    vb, tb = box([-4, -4, -0.2], [4, 4, 0])
    floor = s.add_geometry(np.asarray(vb, float), np.asarray(tb))
    v, t = icosphere(0.6, 2)
    ball = s.add_geometry(np.asarray(v, float), np.asarray(t))
    ids = [s.add_instance(floor, np.eye(4))]
    for k in range(5):
        m = np.eye(4)
        m[:3, 3] = [-3 + 1.5 * k, 0.5 * k - 1, 0.8]
        if k == 1:
            m[:3, :3] = np.diag([-1.0, 1.0, 1.0])           # mirrored
        if k == 3:
            m[:3, :3] = 1.3 * rotation([1, 2, 3], 0.7)      # rotated and scaled
        ids.append(s.add_instance(ball, m))
    s.add_disk_sensor([0, 0, 0.5], [0, 0, 1], 2.0)
    s.commit()
    return s, ids


def rays(n, seed):
    """Rays from a sphere of radius 7 toward random points of the scene's box, some with a short t_max."""
    rng = np.random.default_rng(seed)
    o = rng.normal(size=(n, 3))
    o = 7.0 * o / np.linalg.norm(o, axis=1)[:, None]
    target = rng.uniform([-4, -4, -0.2], [4, 4, 1.6], (n, 3))
    d = target - o
    d *= rng.uniform(0.5, 2.0, (n, 1))                    # not unit: t in units of |d|
    t_max = np.where(rng.uniform(size=n) < 0.25, rng.uniform(0.1, 1.2, n), np.inf)
    return o, d, t_max


def compare(s, ds, n, seed):
    o, d, t_max = rays(n, seed)
    ref = s.intersect(o, d, t_max)
    t, inst, prim, u, v, normal = ds.intersect(o, d, t_max)
    occ_ref = s.occluded(o, d, t_max)
    occ = ds.occluded(o, d, t_max)
    hit = inst >= 0
    return {
        "rays": n,
        "hits": int(hit.sum()),
        "instances_hit": sorted({int(i) for i in inst[hit]}),
        "inst_equal": bool(np.array_equal(inst, ref.instance)),
        "prim_equal": bool(np.array_equal(prim, ref.primitive)),
        "t_max_abs_diff": float(np.max(np.abs(t[hit] - ref.t[hit]), initial=0.0)),
        "miss_t_inf": bool(np.all(np.isinf(t[~hit])) and np.array_equal(np.isinf(t), np.isinf(ref.t))),
        "uv_max_abs_diff": float(max(np.max(np.abs(u - ref.u), initial=0.0), np.max(np.abs(v - ref.v), initial=0.0))),
        "normal_max_abs_diff": float(np.max(np.abs(normal - ref.normal), initial=0.0)),
        "occluded_equal": bool(np.array_equal(occ, occ_ref)),
        "occluded": int(occ.sum()),
    }


def main():
    from tracer.gpu.traverse import SIMULATOR, STORE_FIELDS, TOP_FIELDS, DeviceScene

    s, ids = small_scene()
    ds = DeviceScene(s.arrays())
    out = {"simulator": SIMULATOR, "first_upload": list(ds.uploaded), "fields": len(STORE_FIELDS + TOP_FIELDS)}
    out["before"] = compare(s, ds, 192, 1)
    m = s.instance_transform(ids[2]).copy()                # move one sphere: a new revision
    m[:3, 3] += [0.4, -0.3, 0.2]
    s.set_transform(ids[2], m)
    s.commit()
    ds.update(s.arrays())
    out["move_upload"] = list(ds.uploaded)
    out["after"] = compare(s, ds, 192, 2)
    vn, tn = box([0, 0, 0], [0.3, 0.3, 0.3])
    g = s.add_geometry(np.asarray(vn, float), np.asarray(tn))   # a new geometry
    s.add_instance(g, np.eye(4))
    s.commit()
    ds.update(s.arrays())
    out["add_upload"] = list(ds.uploaded)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
