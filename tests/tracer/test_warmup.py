"""The background compile of a first query's kernels (`tracer.warmup`)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numba
import numpy as np
import pytest

from tests.warmup_report import WARM_UP_REPORT
from tracer import warmup
from tracer.accel.traverse import empty_scene_arrays
from tracer.scene import Scene

ROOT = Path(__file__).resolve().parents[2]

#: the tracer's compiled overloads in this process, "module.function(signature)": those compiled and those loaded
#: from numba's cache alike (what a process holds ready, whichever way it got there)
OVERLOADS = """
import gc
from numba.core.dispatcher import Dispatcher

def overloads():
    return {f"{d.py_func.__module__}.{d.py_func.__qualname__}{tuple(sig)}" for d in gc.get_objects()
            if isinstance(d, Dispatcher) and d.py_func.__module__.startswith("tracer.") for sig in d.overloads}
"""

#: one warm-up child (`warmup.CHILDREN[i]`, as `warmup.Background` runs it): the overloads each stage added
CHILD = OVERLOADS + """
import json, sys
from tracer.warmup import CHILDREN, compile_query_kernels

stages, reverse = CHILDREN[int(sys.argv[1])]
added, held = {}, overloads()

def report(line):
    global held
    now = overloads()
    added[line.split()[0]] = sorted(now - held)
    held = now

compile_query_kernels(report=report, stages=stages, reverse=reverse)
print(json.dumps(added))
"""

FIRST_QUERY = OVERLOADS + """
import json
import numpy as np
from numba.core import event
compiled = []

class Compiles(event.Listener):
    def on_start(self, e):
        f = e.data["dispatcher"].py_func
        compiled.append(f.__module__ + "." + f.__qualname__)

    def on_end(self, e):
        pass

from tracer.scene import Scene
from tracer.simulate import Simulation
from tracer.warmup import box

scene = Scene()
room = scene.add_instance(scene.add_geometry(*box((0, 0, 0), (4, 4, 3))), np.eye(4))
mirror = scene.add_instance(scene.add_geometry(*box((3.9, 1, 0.5), (3.95, 3, 2.5))), np.eye(4))
glass = scene.add_instance(scene.add_geometry(*box((1, 1, 0.5), (2, 2, 1))), np.eye(4))
scene.commit()
event.register("numba:compile", Compiles())   # the push is the service's to compile: from the query on
pushed = overloads()
materials = {room: {"type": "lambertian", "reflectance": 0.5}, mirror: {"type": "mirror", "reflectance": 0.9},
             glass: {"type": "dielectric", "ior": 1.5}}
sim = Simulation(scene, materials, [{"type": "point", "position": [2, 2, 2.5], "intensity_cd": 1000.0}])
pts, nrm = np.array([[2.5, 2.5, 0.0], [3.0, 1.5, 0.0]]), np.array([[0, 0, 1.0], [0, 0, 1.0]])
forward = sim.illuminance(pts, nrm, max_photons=20_000, estimator="forward")
meter = sim.run({"type": "luminance", "position": [3.5, 3.5, 1.5], "direction": [-1, -1, -1]}, max_photons=2000)
camera = sim.run({"type": "camera", "position": [3.5, 3.5, 1.5], "look_at": [2, 2, 0.5], "fov_deg": 40.0,
                  "width": 8, "height": 6}, max_photons=2000)
print(json.dumps({"compiled": sorted(set(c for c in compiled if c.startswith("tracer."))),
                  "used": sorted(overloads() - pushed),
                  "lux": forward.lux.tolist(),
                  "cd_m2": [float(np.max(meter.luminance)), float(np.max(camera.luminance))]}))
"""


def _run(script: str, *args: str) -> dict:
    r = subprocess.run([sys.executable, "-c", script, *args], cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


def _function(overload: str) -> str:
    return overload.split("(", 1)[0]


def test_a_scene_of_receivers_has_the_array_types_of_any_scene():
    """The warm-up compiles the query kernels for the types of empty arrays (and `receivers_only`): that compiles
    the kernels a real scene runs only if every array has the same type (dtype, dimensions, layout)."""
    scene = Scene()
    scene.add_instance(scene.add_geometry(*warmup.box((0, 0, 0), (1, 2, 3))), np.eye(4))
    scene.add_instance(scene.add_geometry(*warmup.box((2, 0, 0), (3, 1, 1))), np.eye(4))
    scene.commit()
    assert numba.typeof(warmup.receivers_only()) == numba.typeof(scene.arrays())
    assert numba.typeof(empty_scene_arrays()) == numba.typeof(scene.arrays())


def test_after_the_children_a_first_query_compiles_nothing():
    """The warm-up children hold ready (compiled, or loaded from numba's cache) every overload a first query uses:
    a first forward query, a first luminance meter and a first camera in a new process (a Lambertian room, a
    mirror, a glass block, a point light) use only overloads that one of the two children (`warmup.CHILDREN`)
    compiled or loaded, and compile none. In child 1 the forward stage, after the probe and the optics, adds the
    forward kernel alone. This holds whatever the cache held before, so it runs in the test session's cache, which
    the controller's children and the earlier tests have filled (a cold cache of its own cost about 160 s of a
    core); what the children compile from an empty cache is the next test's. The children as the service runs them
    (`warmup.Background`) report every stage and end well; at the service's priority here: under a busy test run a
    lowered one could wait minutes for a core."""
    background = warmup.Background(nice=0)
    try:
        for stage in warmup.STAGES:
            assert background.wait(stage, timeout=600)
        assert background.join(timeout=60) == 0
        status = background.status()
        assert status["state"] == "ready", status
        assert set(status["seconds"]) == set(warmup.STAGES)
        assert all(s >= 0 for s in status["seconds"].values())
    finally:
        background.stop()
    children = [_run(CHILD, str(i)) for i in range(len(warmup.CHILDREN))]
    assert all(set(child) == set(stages) for child, (stages, _) in zip(children, warmup.CHILDREN, strict=True))
    forward = {_function(o) for o in children[0]["forward"]}   # its callee too where it was compiled, not loaded
    assert "tracer.transport.forward.forward_batches" in forward, forward
    assert forward <= {"tracer.transport.forward.forward_batches", "tracer.transport.forward.trace_photons"}, forward
    kinds = {_function(o) for child in children for o in child["kinds"]}
    assert "tracer.optics.surfaces.mirror.scatter" in kinds, kinds   # every kind, in one child or the other
    assert not any(".surfaces.mirror." in _function(o) for child in children for o in child["optics"])
    held = {o for child in children for added in child.values() for o in added}
    out = _run(FIRST_QUERY)
    assert out["compiled"] == [], out["compiled"]
    assert out["used"], "the first query used no tracer kernel at all: the overloads are not being seen"
    assert sorted(set(out["used"]) - held) == []
    assert all(lux > 0 for lux in out["lux"])
    assert all(cd > 0 for cd in out["cd_m2"])


def test_from_an_empty_cache_the_children_compile_the_forward_kernel_alone_after_the_optics():
    """Under ``make test`` the controller's warm-up children (tests/conftest.py) start on the session's numba cache,
    empty on a fresh machine (CI): they end well, and the forward stage, after the probe and the optics, compiles
    the forward kernel alone: the optics stage compiled the very signatures the forward kernel calls (a kernel of
    its left out of `forward_callees`, or a type that differs, would be compiled there again, after the optics that
    the two children share). From a warm cache nothing is compiled and there is nothing to check: skipped."""
    path = os.environ.get(WARM_UP_REPORT)
    if not path:
        pytest.skip("runs under make test's workers (pytest -n): the controller's warm-up children report there")
    report_file = Path(path)
    deadline = time.monotonic() + 900
    while not report_file.exists():
        assert time.monotonic() < deadline, "the controller's warm-up children did not report within 900 s"
        time.sleep(1.0)
    report = json.loads(report_file.read_text())
    assert report["status"]["state"] == "ready", report["status"]
    assert set(report["status"]["seconds"]) == set(warmup.STAGES)
    if not report["cold"]:
        pytest.skip("the session's numba cache was not empty when its warm-up started: nothing was compiled to "
                    "check (an empty XDG_CACHE_HOME or NUMBA_CACHE_DIR runs it)")
    forward = [k for k in report["compiled"]["forward"] if k.startswith("tracer.")]
    assert forward == [
        "tracer.transport.forward.forward_batches", "tracer.transport.forward.trace_photons"], forward


def test_two_processes_that_need_the_same_kernel_at_once_compile_it_once(tmp_path):
    """Two warm-up children started together on an empty cache, both for the probe's walk: one compiles it, the other
    waits on its compile lock (`warmup.compiling`) and loads it from numba's cache (without the lock both compile
    it: a minute of a core each for the forward kernel, in a test suite's workers or a service's replicas)."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path), "PYTHONPATH": str(ROOT)}
    children = [subprocess.Popen([sys.executable, "-m", "tracer.warmup", "probe"], cwd=ROOT, env=env,
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    reports = []
    for child in children:
        out, err = child.communicate(timeout=600)
        assert child.returncode == 0, err[-3000:]
        stage, seconds, *compiled = out.split()
        assert stage == "probe" and float(seconds) >= 0
        reports.append(compiled)
    walk = "tracer.accel.traverse.closest_each"
    assert sorted(walk in compiled for compiled in reports) == [False, True], reports


def test_a_held_compile_lock_is_waited_for_then_given_up_on_with_a_warning(tmp_path, monkeypatch, caplog):
    import fcntl

    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path))
    with open(tmp_path / "compiling-forward.lock", "a") as other:   # another process's hold, as flock sees it
        fcntl.flock(other, fcntl.LOCK_EX)
        t = time.perf_counter()
        with warmup.compiling("forward", timeout=0.3, poll=0.05):
            waited = time.perf_counter() - t
    assert 0.3 <= waited < 5.0
    assert "still held after" in caplog.text
    with warmup.compiling("forward", timeout=0.3):   # released: taken at once
        pass


def test_without_a_usable_cache_directory_there_is_no_lock_and_no_error(tmp_path, monkeypatch):
    blocker = tmp_path / "a-file"
    blocker.write_text("not a directory")
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(blocker / "cache"))
    t = time.perf_counter()
    with warmup.compiling("forward", timeout=30):
        pass
    assert time.perf_counter() - t < 1.0


def _running(pid: int) -> bool:
    """Whether process `pid` exists and is not a zombie (an ended child its new parent has not reaped yet)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return False
    return state not in ("Z", "X")


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads process states from /proc (Linux)")
def test_the_children_end_when_the_process_that_started_them_is_killed(tmp_path):
    """A service killed outright (SIGKILL: nothing of it runs to stop them) leaves no child compiling: each sees
    its parent gone within a second and ends, so a service started next has the cores to itself."""
    code = ("import time\nfrom tracer.warmup import Background\nb = Background()\n"
            "print(' '.join(str(p.pid) for p in b._procs), flush=True)\ntime.sleep(120)\n")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path), "PYTHONPATH": str(ROOT)}
    parent = subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, env=env, stdout=subprocess.PIPE, text=True)
    try:
        assert parent.stdout is not None
        pids = [int(p) for p in parent.stdout.readline().split()]
        assert len(pids) == len(warmup.CHILDREN) and all(_running(p) for p in pids)
        time.sleep(1.0)   # the children are importing or compiling
        assert all(_running(p) for p in pids)
    finally:
        parent.kill()
        parent.wait()
    deadline = time.monotonic() + 10.0
    while any(_running(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(_running(p) for p in pids), [p for p in pids if _running(p)]
