"""`lumenlink demo` / `make demo`: the main job end to end, as a new user first meets it.

The demo builds a car-like CAD model with cadquery and saves it as STEP, starts the service on a
free loopback port (uvicorn in a thread of this process, a SQLite file in a fresh data directory),
pushes the model through the real adapter and REST API, assigns materials, lights and a floor
sensor, and asks for illuminance. Then it edits the model as a designer would — opens a door (a
transform change), reshapes the headlamp lens (a geometry change) — pushes each edit, shows what
the service rebuilt and that every assignment survived, asks again and maps the change.

Everything printed is measured on this run; a part of LumenLink that is not built yet stops the
demo with a message naming it (`MissingPart`), never with a made-up number.

Compilation: the light transport is numba code compiled on first use and cached on disk. As under
`lumenlink serve`, two background processes compile the query kernels from the start (`tracer.warmup`) while
the demo builds and pushes the car; the demo counts the seconds numba spent compiling in its own process
(``numba:compile`` events) and says so.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import shutil
import socket
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from lumenlink.demo_car import (
    DOOR_OPEN_DEG,
    GRID,
    GRID_NU,
    GRID_NV,
    GRID_SECONDS,
    LENS_RADIUS_AFTER_MM,
    LENS_RADIUS_BEFORE_MM,
    NAMED_POINTS,
    POINT_RADIUS,
    POINTS_SECONDS,
    SCENE_NAME,
    MissingPart,
    add_sensors,
    check,
    dress,
)


def need(module: str, issue: int, *names: str) -> Any:
    """Import ``module`` and check it has ``names``, or raise `MissingPart` naming it."""
    try:
        mod = importlib.import_module(module)
    except ImportError as exc:
        raise MissingPart(module, issue, str(exc)) from exc
    for name in names:
        if not hasattr(mod, name):
            raise MissingPart(f"{module}.{name}", issue)
    return mod


class CompileClock:
    """Seconds numba spends compiling while installed (all threads: compilation holds numba's global lock)."""

    def __init__(self) -> None:
        self.seconds = 0.0
        self.functions = 0
        self._depth = 0
        self._t0 = 0.0
        self._lock = threading.Lock()
        self._listener: Any = None

    def install(self) -> None:
        try:
            from numba.core import event
        except ImportError:  # numba not importable: nothing will compile either
            return
        clock = self

        class _Listener(event.Listener):
            def on_start(self, ev: Any) -> None:
                with clock._lock:
                    if clock._depth == 0:
                        clock._t0 = time.perf_counter()
                    clock._depth += 1
                    clock.functions += 1

            def on_end(self, ev: Any) -> None:
                with clock._lock:
                    clock._depth -= 1
                    if clock._depth == 0:
                        clock.seconds += time.perf_counter() - clock._t0

        self._listener = _Listener()
        event.register("numba:compile", self._listener)

    def uninstall(self) -> None:
        if self._listener is not None:
            from numba.core import event

            event.unregister("numba:compile", self._listener)
            self._listener = None


class Narrator:
    """A short narrated log with the time since the start in the margin."""

    def __init__(self, console: Any = None) -> None:
        if console is None:
            from rich.console import Console

            console = Console(highlight=False, soft_wrap=True)
        self.console = console
        self.t0 = time.perf_counter()
        self.lines: list[str] = []

    def elapsed(self) -> float:
        return time.perf_counter() - self.t0

    def step(self, text: str) -> None:
        self._out(f"\n[bold cyan][{self.elapsed():6.1f} s] {text}[/]", text)

    def say(self, text: str) -> None:
        self._out(f"           {text}", text)

    def warn(self, text: str) -> None:
        self._out(f"[bold red]           {text}[/]", text)

    def _out(self, markup: str, plain: str) -> None:
        self.lines.append(plain)
        self.console.print(markup)


@dataclass
class PushFacts:
    """What one push cost and changed, as the service answered it."""

    revision: int
    uploaded: int
    added: int
    moved: list[str]
    geometry_changed: list[str]
    unchanged: int
    blas_built: int
    blas_reused: int
    tlas_ms: float
    seconds: float
    raw: dict[str, Any] = field(repr=False, default_factory=dict)


@dataclass
class DemoReport:
    """The facts the demo printed (checked by tests/e2e/test_demo.py)."""

    out_dir: Path
    step_files: list[Path] = field(default_factory=list)
    maps: dict[str, Path] = field(default_factory=dict)
    pushes: dict[str, PushFacts] = field(default_factory=dict)
    assignments_before: dict[str, Any] = field(default_factory=dict)
    assignments_after: dict[str, Any] = field(default_factory=dict)
    points_before: dict[str, Any] = field(default_factory=dict)
    points_after: dict[str, Any] = field(default_factory=dict)
    grid_before: dict[str, Any] = field(default_factory=dict)
    grid_after: dict[str, Any] = field(default_factory=dict)
    surface_after: dict[str, Any] = field(default_factory=dict)
    change: Any = None
    compile_seconds: float = 0.0
    seconds: float = 0.0
    view_url: str | None = None


def free_port() -> int:
    """A TCP port free on loopback right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextlib.contextmanager
def running_service(data_dir: Path, warm_kernels: bool = True) -> Iterator[str]:
    """The real service app under uvicorn in a daemon thread on a free loopback port; yields its URL (stopped on
    leaving, 15 s to finish; raises where it has not started in 60 s). `warm_kernels` False: no background compile
    (a benchmark that times the first queries itself)."""
    app_mod = need("service.app", 5, "create_app")
    config_mod = need("service.config", 5, "Settings")
    import uvicorn

    # the query kernels compile in two background processes from the start (tracer.warmup), as under
    # `lumenlink serve`, while this process builds the car, tessellates and pushes it
    settings = config_mod.Settings(data_dir=data_dir, log_requests=False, warm_kernels=warm_kernels)
    app = app_mod.create_app(settings)
    port = free_port()
    server = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=port, log_level="warning"))
    thread = threading.Thread(target=server.run, name="lumenlink-demo-service", daemon=True)
    thread.start()
    deadline = time.monotonic() + 60.0
    while not server.started:
        if not thread.is_alive() or time.monotonic() > deadline:
            raise RuntimeError("the service did not start (see the log above)")
        time.sleep(0.02)
    try:
        yield f"http://127.0.0.1:{port}"
    finally:
        events = getattr(app.state, "events", None)
        if events is not None:   # a browser's event stream would hold uvicorn's shutdown up
            events.close()
        server.should_exit = True
        thread.join(timeout=15.0)


def _fmt_lux(value: float, stderr: float) -> str:
    return f"{value:9.2f} ± {stderr:6.2f} lx"


def run_demo(out_dir: Path, photons: int = 2_000_000, *, narrator: Narrator | None = None,
             keep_data: bool = False, serve: Callable[[str], None] | None = None) -> DemoReport:
    """Run the demo; returns the facts it printed. Raises `MissingPart` if a part is not built yet.

    Parameters
    ----------
    out_dir : Path
        Where the STEP files, maps and the service's data directory go (created; earlier demo
        outputs in it are replaced).
    photons : int
        Photon budget of each illuminance query (each also stops after `GRID_SECONDS` / `POINTS_SECONDS`).
    narrator : Narrator, optional
        Where the log goes (default: a rich console on stdout).
    keep_data : bool
        Keep the service's data directory (``out_dir/var``) after the run.
    serve : callable(view_url), optional
        After the demo, with the service still running: called with the address of the scene's page (its 3D view);
        the service stops when it returns (`run` waits for Ctrl-C there).
    """
    if photons < 1000:
        raise ValueError(f"photons must be at least 1000, got {photons}")
    n = narrator or Narrator()
    clock = CompileClock()
    clock.install()
    report = DemoReport(out_dir=Path(out_dir))
    try:
        _run(report, n, int(photons), keep_data, clock, serve)
    finally:
        clock.uninstall()
        report.compile_seconds = clock.seconds
        report.seconds = n.elapsed()
    return report


def _push_facts(result: Any) -> PushFacts:
    a = result.answer
    return PushFacts(revision=int(a["revision"]), uploaded=int(result.uploaded), added=len(a["added"]),
                     moved=list(a["moved"]), geometry_changed=list(a["geometry_changed"]),
                     unchanged=int(a["unchanged"]), blas_built=int(a["blas_built"]),
                     blas_reused=int(a["blas_reused"]), tlas_ms=1000.0 * float(a["seconds"].get("tlas", 0.0)),
                     seconds=float(a["seconds"].get("total", 0.0)), raw=a)


def _assignments(http: Any, scene_id: str) -> dict[str, Any]:
    """Every assignment of the scene, keyed so that two snapshots compare field by field."""
    out: dict[str, Any] = {}
    for m in check(http.get(f"/scenes/{scene_id}/materials"), "listing materials"):
        out[f"material:{m['node']}"] = (m["material"], m["orphaned"])
    for kind in ("lights", "sensors", "objects"):
        for a in check(http.get(f"/scenes/{scene_id}/{kind}"), f"listing {kind}"):
            out[f"{kind[:-1]}:{a['id']}"] = (a["body"], a["orphaned"])
    return out


def _run(report: DemoReport, n: Narrator, photons: int, keep_data: bool, clock: CompileClock,
         serve: Callable[[str], None] | None = None) -> None:
    import httpx

    out = report.out_dir
    out.mkdir(parents=True, exist_ok=True)
    for old in ("car.step", "car.step.lumenlink.json", "car.lumenlink.json"):
        (out / old).unlink(missing_ok=True)
    data_dir = out / "var"
    shutil.rmtree(data_dir, ignore_errors=True)

    # 1 -------------------------------------------------------------------------------- service + CAD model
    n.step("1. Starting the service (its kernels compile in the background) and building the car in cadquery, as STEP")
    token = os.environ.get("LUMENLINK_TOKEN")   # the in-process service reads it too (Settings)
    headers = {"Authorization": f"Bearer {token}"} if token else {}
    with running_service(data_dir) as base, httpx.Client(base_url=base, timeout=300.0, headers=headers) as http:
        samples = need("cad_adapter.samples", 4, "car_assembly")
        adapter = need("cad_adapter", 4, "read_document", "tessellate", "TessellationCache")
        writer = need("cad_adapter.step_uuid", 4, "write_step")
        step = out / "car.step"
        sidecar = out / "car.lumenlink.json"  # remembers the UUIDs of the cadquery nodes by occurrence path
        tess_cache = adapter.TessellationCache()

        def export(door_deg: float, lens_mm: float) -> tuple[Any, Any]:
            """Build the assembly, save it as STEP (UUIDs carried in the file), read the STEP back, tessellate."""
            built = adapter.read_document(samples.car_assembly(door_deg, lens_mm), sidecar=sidecar)
            writer.write_step(built, step)
            doc = adapter.read_document(step)
            return doc, adapter.tessellate(doc, cache=tess_cache)

        doc, tess = export(0.0, LENS_RADIUS_BEFORE_MM)
        report.step_files.append(step)
        parts = {node.part for node in doc.nodes if node.part is not None}
        triangles = sum(len(m.triangles) for m in tess.meshes.values())
        n.say(f"{len(doc.nodes)} nodes, {len(parts)} distinct parts (the four wheels are one part), "
              f"{triangles:,} triangles; {step} ({step.stat().st_size / 1024:.0f} KiB, unit {doc.length_unit})")
        uuid_of = {node.name: node.uuid for node in doc.nodes}

        # 2 ---------------------------------------------------------------------------- push
        n.step("2. Pushing the model through the adapter and the REST API")
        n.say(f"service at {base} (SQLite and BLAS cache in {data_dir})")
        scene_id = _first_push(report, n, clock, adapter, base, doc, tess)

        dress(http, scene_id, uuid_of)
        sensor, surface = add_sensors(http, scene_id, uuid_of)
        n.say("materials: paint on the car (inherited by body and doors), glass (n = 1.5) in the windscreen "
              "and the headlamp lens, a chrome reflector, black tyres")
        n.say("a 30 m × 30 m concrete floor (ρ = 0.25), owned by the simulation: pushes never touch it")
        n.say("lights: a 5000 cd spot inside the left headlamp, attached to its node, shining through the lens; "
              "a 532 lm downlight from a real IES file, 3 m up")
        n.say(f"sensors: {GRID_NU}×{GRID_NV} cells on the floor, {GRID['u'][0]:g} m × {GRID['v'][1]:g} m in front "
              "of the car; the car's own surfaces, triangle by triangle (a surface sensor on its node)")
        report.assignments_before = _assignments(http, scene_id)

        # 3 ---------------------------------------------------------------------------- first query
        _first_query(report, n, clock, http, scene_id, sensor, photons)

        # 4 ---------------------------------------------------------------------------- edits
        _edits(report, n, clock, adapter, base, scene_id, export, http)

        # 5 ---------------------------------------------------------------------------- second query
        n.step("5. Illuminance again, with the doors open and the new lens")
        report.grid_after = _simulate(http, scene_id, sensor, photons, n)
        report.maps["after"] = _save_map(http, scene_id, sensor, out / "floor_after.png")
        report.points_after = _points(http, scene_id, photons, n, before=report.points_before)
        report.maps["difference"] = _save_difference(report, out / "floor_difference.png", n)
        report.surface_after = _simulate_surface(http, scene_id, surface, photons, n)
        report.view_url = f"{base}/scenes/{scene_id}/view"
        if serve is not None:
            _outputs(report, step, n, base)
            n.step("7. Serving: the model in 3D, the car and the floor grid in false colour, live after each push")
            n.say(f"open {report.view_url} in a browser (all scenes: {base}/, API docs: {base}/docs)")
            serve(report.view_url)

    if not keep_data:
        shutil.rmtree(data_dir, ignore_errors=True)
    if serve is None:
        _outputs(report, step, n, None)


def _first_push(report: DemoReport, n: Narrator, clock: CompileClock, adapter: Any, base: str, doc: Any,
                tess: Any) -> str:
    """2. The first push, and what it cost; the scene's id."""
    compiled = clock.seconds
    with adapter.Pusher(base) as pusher:
        first = pusher.push(doc, tess, scene=SCENE_NAME)
    facts = report.pushes["initial"] = _push_facts(first)
    scene_id = first.scene_id
    n.say(f"pushed revision {facts.revision}: {facts.added} nodes added, {first.uploaded} of "
          f"{first.geometries} distinct geometries uploaded (each once), {facts.blas_built} bottom levels "
          f"built, top level {facts.tlas_ms:.1f} ms")
    if clock.seconds - compiled > 0.5:
        n.say(f"(this first push included {clock.seconds - compiled:.1f} s of numba compilation of the tracer's "
              "builders, once per installation)")
    return scene_id


def _first_query(report: DemoReport, n: Narrator, clock: CompileClock, http: Any, scene_id: str, sensor: str,
                 photons: int) -> None:
    """3. The kernel of the scene's effect set, then the floor grid and the named points."""
    out = report.out_dir
    effects = check(http.get(f"/scenes/{scene_id}"), "reading the scene")["effects"]
    n.step(f"3a. Compiling the photon-tracing kernel for this scene's effect set {{{', '.join(effects)}}}")
    compiled = clock.seconds
    t = time.perf_counter()
    check(http.post(f"/scenes/{scene_id}/illuminance",
                     json={"points": [[5.0, 0.0, 0.0]], "normals": [[0.0, 0.0, 1.0]], "max_photons": 1000}),
           "the warm-up query")
    n.say(f"ready in {time.perf_counter() - t:.1f} s, of which numba compilation here "
          f"{clock.seconds - compiled:.1f} s (the kernels compile in two background processes from the start and "
          "are cached on disk: the next run loads them)")
    n.step(f"3b. Illuminance on the floor grid and at named points (up to {photons:,} photons, "
           f"{GRID_SECONDS:g} s / {POINTS_SECONDS:g} s a query)")
    report.grid_before = _simulate(http, scene_id, sensor, photons, n)
    report.maps["before"] = _save_map(http, scene_id, sensor, out / "floor_before.png")
    n.say(f"map: {report.maps['before']}")
    report.points_before = _points(http, scene_id, photons, n)


def _edits(report: DemoReport, n: Narrator, clock: CompileClock, adapter: Any, base: str, scene_id: str,
           export: Callable[[float, float], tuple[Any, Any]], http: Any) -> None:
    """4. The designer's two edits, each pushed; every assignment must survive both."""
    n.step(f"4a. The designer opens both doors by {DOOR_OPEN_DEG:g}° (a transform change) and re-saves the STEP")
    doc, tess = export(DOOR_OPEN_DEG, LENS_RADIUS_BEFORE_MM)
    compiled = clock.seconds
    with adapter.Pusher(base) as pusher:
        door = pusher.push(doc, tess, scene=SCENE_NAME)
    report.pushes["doors"] = _say_push(door, doc, n, clock.seconds - compiled)

    n.step(f"4b. The designer changes the lens' radius of curvature {LENS_RADIUS_BEFORE_MM:g} → "
           f"{LENS_RADIUS_AFTER_MM:g} mm (a geometry change) and re-saves")
    doc, tess = export(DOOR_OPEN_DEG, LENS_RADIUS_AFTER_MM)
    compiled = clock.seconds
    with adapter.Pusher(base) as pusher:
        lens = pusher.push(doc, tess, scene=SCENE_NAME)
    report.pushes["lens"] = _say_push(lens, doc, n, clock.seconds - compiled)

    report.assignments_after = _assignments(http, scene_id)
    kept = [k for k, v in report.assignments_before.items() if report.assignments_after.get(k) == v]
    lost = sorted(set(report.assignments_before) - set(kept))
    counts = {kind: sum(1 for k in kept if k.startswith(kind)) for kind in ("material", "light", "sensor",
                                                                            "object")}
    n.say(f"assignments after both pushes: {counts['material']} materials, {counts['light']} lights, "
          f"{counts['sensor']} sensors, {counts['object']} floor object — "
          + ("all kept, none orphaned" if not lost else f"LOST: {lost}"))
    if lost:
        raise RuntimeError(f"assignments did not survive the pushes: {lost}")


def _outputs(report: DemoReport, step: Path, n: Narrator, base: str | None) -> None:
    """6. Where the demo's files are (and, while it serves, its pages)."""
    n.step("6. Outputs")
    for key in ("before", "after", "difference"):
        n.say(f"{key:>10}: {report.maps[key]}")
    n.say(f"{'STEP':>10}: {step} (the edited model; node UUIDs are carried in the file)")
    if base is None:
        n.say("API docs and the model in 3D: run `lumenlink demo --serve` (the demo then keeps serving), or "
              "`lumenlink serve` (`make serve`) and open http://127.0.0.1:8000/ and http://127.0.0.1:8000/docs")


def _simulate(http: Any, scene_id: str, sensor: str, photons: int, n: Narrator) -> dict[str, Any]:
    a = check(http.post(f"/scenes/{scene_id}/sensors/{sensor}/simulate",
                         json={"max_photons": photons, "max_seconds": GRID_SECONDS, "seed": 1}),
               "simulating the floor sensor")
    maps = need("service.maps", 6, "median_relative_error")
    rel = maps.median_relative_error(a["lux"], a["stderr"])
    n.say(f"floor grid: {a['min_lux']:.1f}–{a['max_lux']:.1f} lx (mean {a['mean_lux']:.1f} lx), median standard "
          f"error {100 * rel:.1f} % (lit cells); {a['photons']:,} photons in {a['seconds']:.1f} s "
          f"(stopped by {a['stop_reason']}), {a['estimator']} estimator, effects {{{', '.join(a['effects'])}}}, "
          f"revision {a['revision']}")
    return a


def _simulate_surface(http: Any, scene_id: str, sensor: str, photons: int, n: Narrator) -> dict[str, Any]:
    """The car's own surfaces in lux (what its page colours the model by)."""
    a = check(http.post(f"/scenes/{scene_id}/sensors/{sensor}/simulate",
                         json={"max_photons": photons, "max_seconds": POINTS_SECONDS, "seed": 1}),
               "simulating the car's surface sensor")
    triangles = sum(len(i["lux"]) for i in a["instances"])
    n.say(f"the car's surfaces: {triangles:,} triangles on {len(a['instances'])} parts, {a['min_lux']:.1f}–"
          f"{a['max_lux']:.1f} ± {a['max_lux_stderr']:.1f} lx (the largest on a triangle of "
          f"{a['max_lux_area'] * 1e6:.3g} mm²; 99 % of the area at or below {a['max_lux_p99']:.1f} lx), "
          f"area-weighted mean {a['mean_lux']:.1f} lx; {a['photons']:,} photons in {a['seconds']:.1f} s")
    return a


def _points(http: Any, scene_id: str, photons: int, n: Narrator,
            before: dict[str, Any] | None = None) -> dict[str, Any]:
    names = list(NAMED_POINTS)
    body = {"points": [list(NAMED_POINTS[k]) for k in names], "normals": [[0.0, 0.0, 1.0]] * len(names),
            "radius": POINT_RADIUS, "max_photons": photons, "max_seconds": POINTS_SECONDS, "seed": 2}
    a = check(http.post(f"/scenes/{scene_id}/illuminance", json=body), "the illuminance query")
    n.say(f"named points ({a['photons']:,} photons, {a['seconds']:.1f} s, {a['estimator']}, stopped by "
          f"{a['stop_reason']}, disks of radius {POINT_RADIUS:g} m):")
    for k, name in enumerate(names):
        line = f"  {name:<38} {_fmt_lux(a['lux'][k], a['stderr'][k])}"
        if before is not None:
            d = a["lux"][k] - before["lux"][k]
            sigma = (a["stderr"][k] ** 2 + before["stderr"][k] ** 2) ** 0.5
            verdict = "changed" if abs(d) > 2 * sigma else "within noise"
            line += f"   Δ {d:+8.2f} lx ({verdict})"
        n.say(line)
    return a


def _save_map(http: Any, scene_id: str, sensor: str, path: Path) -> Path:
    r = http.get(f"/scenes/{scene_id}/sensors/{sensor}/map.png")
    if r.status_code != 200:
        check(r, "fetching the map")
    path.write_bytes(r.content)
    return path


def _save_difference(report: DemoReport, path: Path, n: Narrator) -> Path:
    maps = need("service.maps", 6, "difference_map_png", "summarize_change")
    b, a = report.grid_before, report.grid_after
    frame = (a["origin"], a["u"], a["v"])
    path.write_bytes(maps.difference_map_png(b["lux"], a["lux"], *frame, stderr_before=b["stderr"],
                                             stderr_after=a["stderr"],
                                             title=f"Floor: revision {b['revision']} → {a['revision']}"))
    s = report.change = maps.summarize_change(b["lux"], a["lux"], *frame, stderr_before=b["stderr"],
                                              stderr_after=a["stderr"])
    n.say(f"difference map: {path}")
    n.say(f"{s.significant} of {s.cells} cells changed beyond 2σ ({s.increased} brighter, {s.decreased} darker); "
          f"mean {s.mean_before_lux:.1f} → {s.mean_after_lux:.1f} lx")
    if s.max_increase_lux > 0:
        x, y, _ = s.max_increase_at
        n.say(f"largest rise {s.max_increase_lux:+.1f} lx at ({x:.2f}, {y:.2f}) m")
    if s.max_decrease_lux > 0:
        x, y, _ = s.max_decrease_at
        n.say(f"largest fall {-s.max_decrease_lux:+.1f} lx at ({x:.2f}, {y:.2f}) m")
    return path


def _say_push(result: Any, doc: Any, n: Narrator, compile_seconds: float = 0.0) -> PushFacts:
    facts = _push_facts(result)
    name_of = {node.uuid: node.name for node in doc.nodes}

    def names(uuids: list[str]) -> str:
        return ", ".join(f"{name_of.get(u, '?')} ({u[:8]}…)" for u in uuids) or "none"

    n.say(f"revision {facts.revision}: moved {names(facts.moved)}; geometry changed "
          f"{names(facts.geometry_changed)}; {facts.unchanged} unchanged")
    n.say(f"uploaded {facts.uploaded} mesh(es); bottom levels built: {facts.blas_built}, reused "
          f"{facts.blas_reused}; top level rebuilt in {facts.tlas_ms:.2f} ms; push {1000 * facts.seconds:.1f} ms "
          "on the service")
    if compile_seconds > 0.05:
        n.say(f"(these times include {compile_seconds:.2f} s of numba compiling code used for the first time in this "
              "process; the next push of this kind does not pay it)")
    return facts


def wait_for_ctrl_c(view_url: str) -> None:
    """Serve until Ctrl-C or SIGTERM (the demo's service runs in a thread of this process)."""
    import signal

    def stop(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt

    print(f"Serving {view_url} — press Ctrl-C to stop.", flush=True)
    previous = signal.signal(signal.SIGTERM, stop)
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        print("\nstopping the service", flush=True)
    finally:
        signal.signal(signal.SIGTERM, previous)


def run(out_dir: Path = Path("demo-output"), photons: int = 2_000_000, serve: bool = False) -> int:
    """Entry point of `lumenlink demo`: run the demo, print the facts; 0 on success, 2 if a part is missing.
    `serve`: keep the service running afterwards (until Ctrl-C) and print the address of the model's page."""
    n = Narrator()
    try:
        report = run_demo(Path(out_dir), photons, narrator=n, serve=wait_for_ctrl_c if serve else None)
    except MissingPart as exc:
        n.warn(f"The demo stops here: {exc}.")
        n.warn("Nothing after this point was computed; no result above was made up.")
        return 2
    except RuntimeError as exc:  # a call the service refused, or the service did not start
        n.warn(f"The demo failed: {exc}")
        return 1
    n.say(f"Done in {report.seconds:.1f} s, of which numba compilation in this process {report.compile_seconds:.1f} s "
          "(the query kernels compiled in the background meanwhile).")
    return 0


# Keep the names the tests and the CLI use in one place.
__all__ = ["DemoReport", "MissingPart", "Narrator", "run", "run_demo", "running_service"]
