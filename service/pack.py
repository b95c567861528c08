"""Packing a density element against a scene (issue 41): ``POST /elements/{id}/pack`` as a job.

The request names the scene, the element assignment that puts the element onto the light guide's face, and a grid
sensor over the lit face (its cells are the meters: illuminance, or with ``"quantity": "luminance"`` the luminance a
viewer ``distance`` m in front of each cell sees, `tracer.elements.pack.Reading`). `start` checks everything before
a job is queued (422 naming the field, nothing changed): a target outside (0, 1], an element that is not a density
layout, an assignment or a sensor the scene lacks, a scene without lights, a face that no light reaches (a short
pilot measurement reads 0 lx in every cell; with luminance, also a pilot of paths from the eye).

The job packs on a scene of its own: the scene rebuilt from the database (`Scenes.rebuilt`, timed: the full
rebuild each iteration would cost without the two levels), whose element it changes at each iteration with
`tracer.Scene.set_element` (`tracer.elements.pack`). The scene everybody queries is never touched: switching its
assignment to the result is one more call (``PUT /scenes/{id}/elements/{aid}``). The result, the chosen pattern,
is a new element in the library with its history (`ElementLibrary.keep_record`: uniformity, photons and seconds per
iteration) and ``pack.png`` (`plot`); a cancelled job keeps what it measured the same way.
"""

from __future__ import annotations

import io
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from service.errors import Invalid, NotFound
from service.sensor_kinds import kind_of, kind_of_type, types_where
from tracer.transport.query import Budget

PILOT_PHOTONS = 20_000   # the pilot that tells a face no light reaches


@dataclass
class Run:
    """What a pack (or a design loop, `service.design`) works on, checked: the library and the starting element, the
    scene of its own (`own`, rebuilt from the database in `rebuild_seconds`) with the instance that carries the
    element and `Scene.set_element`'s keywords (`assign`), the grid sensor's body (world m), how its cells are read,
    and `simulation(scene)`."""

    library: Any
    start: Any
    scene_id: str
    own: Any
    instance: int
    assign: dict[str, Any]
    sensor: dict[str, Any]
    reading: Any
    simulation: Callable[[Any], Any]
    rebuild_seconds: float
    grid: dict[str, Any]


def setup(manager: Any, hub: Any, element_id: str, req: dict[str, Any], checks: Callable[[Any], None]) -> Run:
    """Check a request that changes an element on a scene's face against a grid over the lit face, and set it up
    (see the module docstring for what is refused); `checks(start)` refuses what the caller's own fields cannot do
    (an `ElementError`, answered as a 422)."""
    from tracer.elements import ElementError
    from tracer.elements.pack import Reading

    library = manager.scenes.elements
    if library.summary(element_id)["type"] == "grating":   # 404: no such element
        raise Invalid(f"element {element_id} is a grating: packing places the features of a density layout "
                      f"(a microstructure)")
    start_model = library.get(element_id)
    reading = Reading(req.get("quantity", "illuminance"), req.get("distance", 0.5), req.get("aperture_deg", 1.0))
    try:
        checks(start_model)
        reading.check()
    except ElementError as exc:
        raise Invalid(str(exc)) from None
    scene_id = req["scene"]
    assignment = _assignment_and_sensor(manager, scene_id, element_id, req)
    t0 = time.perf_counter()
    own = manager.scenes.rebuilt(scene_id)      # a scene of its own: a full rebuild, timed
    live = manager.scenes.live_locked(own)
    if req["assignment"] not in own.element_instances:
        raise Invalid(f"assignment {req['assignment']} is not applied: {own.element_problems.get(req['assignment'])}")
    if not live.lights:
        raise Invalid(f"scene: {scene_id} has no light: no light can reach the face")
    simulation = _simulation_factory(hub, live)
    sim = simulation(own.tracer)
    rebuild_seconds = time.perf_counter() - t0
    from service.simulation import find_sensor

    sensor = kind_of(find_sensor(live, req["sensor"])).body(find_sensor(live, req["sensor"]), live)
    pilot = sim.run(sensor, max_photons=PILOT_PHOTONS, seed=int(req["seed"]), estimator="forward")
    if not float(np.max(pilot.lux)) > 0:
        raise Invalid(f"sensor: no light reaches the grid over the face ({pilot.photons} photons of a pilot, every "
                      f"cell 0 lx): check the lights, and that the grid's front side (u x v) faces the lit face",
                      sensor=req["sensor"])
    if reading.quantity == "luminance":   # what paths from the eye cannot follow here is said now, not in the job
        _luminance_pilot(sim, sensor, reading, int(req["seed"]))
    mm = own.tree.scale * 1000.0
    assign = {"facing": assignment.get("facing"), "faces": assignment.get("faces"), "mm_per_unit": mm,
              "key": req["assignment"]}
    return Run(library, start_model, scene_id, own, own.element_instances[req["assignment"]], assign, sensor,
               reading, simulation, rebuild_seconds, {k: sensor[k] for k in ("origin", "u", "v")})


def start(manager: Any, hub: Any, element_id: str, req: dict[str, Any]) -> tuple[str, int, Any, Budget, dict]:
    """Check a pack request and set it up: answers ``(scene_id, revision, work, budget, meta)`` for
    `JobRunner.submit` (see the module docstring for what is refused)."""
    from tracer.elements.pack import PackError, check

    run = setup(manager, hub, element_id, req, lambda model: check(
        model, req["target"], req["figure"], req["damping"], req["max_fill"], req.get("pitch_mm")))
    req = {**req, "grid": run.grid}   # world metres, for pack.png's axes
    options = {k: req[k] for k in ("target", "figure", "photons", "max_photons", "max_iterations", "max_seconds",
                                   "damping", "max_fill", "pitch_mm", "seed")}
    options["reading"] = run.reading

    def work(progress: Any = None, cancel: Any = None) -> dict[str, Any]:
        from tracer.elements.pack import pack

        def report(s: dict[str, Any]) -> None:
            if progress is not None:
                u = s["uniformity"]
                progress(s["photons"], math.nan, s["seconds"], iteration=s["iteration"], measured=s["measured"],
                         uniformity=u, uniformity_stderr=s["stderr"])

        try:
            result = pack(run.own.tracer, run.instance, run.start, run.sensor, run.simulation, assign=run.assign,
                          progress=report, cancel=cancel, **options)
        except PackError as exc:
            if cancel is not None and cancel():   # cancelled before anything was measured: nothing to keep
                return {"element": None, "stopped": "cancelled", "history": [], "seconds": 0.0}
            raise Invalid(str(exc)) from None
        return keep(run.library, element_id, req, result, run.rebuild_seconds)

    budget = Budget(max_seconds=float(req["max_seconds"]))
    meta = {"generation": hub.generation(run.scene_id), "sensor": req["sensor"], "element": element_id}
    return run.scene_id, int(run.own.revision), work, budget, meta


def _luminance_pilot(sim: Any, sensor: dict[str, Any], reading: Any, seed: int) -> None:
    """A few paths from the eye through the grid's meters: 422 where they cannot answer this scene (an effect paths
    from the eye do not follow) or see no light."""
    from tracer.elements.pack import read
    from tracer.errors import TracerError

    try:
        values, _, _ = read(sim, sensor, reading, PILOT_PHOTONS, seed, None, None)
    except TracerError as exc:
        raise Invalid(f"quantity: luminance cannot be read on this scene: {exc}", field="quantity") from None
    if not float(np.max(values)) > 0:
        raise Invalid(f"sensor: a viewer {reading.distance:g} m in front of the grid sees no light at any cell "
                      f"({PILOT_PHOTONS} paths of a pilot): check that the grid's front side (u x v) faces the lit "
                      f"face", field="quantity")


def _assignment_and_sensor(manager: Any, scene_id: str, element_id: str, req: dict[str, Any]) -> dict[str, Any]:
    """The element assignment a pack changes, checked with its sensor (422 for a scene, assignment or sensor that
    cannot be packed: one that does not exist, another element, a sensor no pack can be driven by)."""
    try:
        state = manager.scenes.state(scene_id)
    except NotFound:
        raise Invalid(f"scene: no scene {scene_id}") from None
    with state.lock:
        assignment = state.elements.get(req["assignment"])
        sensor_body = state.sensors.get(req["sensor"])
    if assignment is None:
        raise Invalid(f"assignment: scene {scene_id} has no element assignment {req['assignment']} (POST /scenes/"
                      f"{scene_id}/elements puts the element onto the guide's face first)")
    if assignment["element"] != element_id:
        raise Invalid(f"assignment {req['assignment']} carries element {assignment['element']}, not {element_id}: "
                      f"pack the element the face carries")
    if sensor_body is None:
        raise Invalid(f"sensor: scene {scene_id} has no sensor {req['sensor']}")
    if not kind_of_type(sensor_body.get("type")).PACKS:
        packs = types_where(lambda k: k.PACKS)
        raise Invalid(f"sensor: a pack measures a grid of cells over the lit face ({packs} sensors); sensor "
                      f"{req['sensor']} is a {sensor_body.get('type')!r} sensor")
    return assignment


def _simulation_factory(hub: Any, live: Any) -> Any:
    """``simulation(scene)``: a `tracer.simulate.Simulation` of the committed `scene` with the snapshot's materials
    and lights (instance ids are the rebuilt scene's own)."""
    from service.optics import to_spec
    from service.simulation import load_transport, transport_lights

    simulate = load_transport()
    materials = {int(k): to_spec(v) for k, v in live.materials.items()}
    lights = transport_lights(live)
    default = to_spec(live.default_material)
    backend = hub.backend()

    def make(scene: Any) -> Any:
        try:
            return simulate.Simulation(scene, materials, lights, default_material=default, backend=backend)
        except ValueError as exc:
            raise Invalid(f"the scene cannot be simulated: {exc}") from exc

    return make


def keep(library: Any, element_id: str, req: dict[str, Any], result: Any, rebuild_seconds: float) -> dict[str, Any]:
    """The chosen pattern into the library, with its history and ``pack.png``; answers the job's result."""
    summary, _ = library.create(result.element.body)
    history = [h.public() for h in result.history]
    updates = [h["update_seconds"] for h in history]
    best = result.history[result.best]
    record = {"element": summary["id"], "packed_from": element_id, "scene": req["scene"],
              "assignment": req["assignment"], "sensor": req["sensor"], "target": result.target,
              "figure": result.figure, "stopped": result.stopped, "best": result.best,
              "quantity": result.reading.quantity, "unit": result.reading.unit,
              "uniformity": best.uniformity, "uniformity_stderr": best.stderr, "min_mean": best.min_mean,
              "iterations": len(history), "seconds": result.seconds, "rebuild_seconds": rebuild_seconds,
              "update_seconds_mean": float(np.mean(updates)),
              "measure_seconds_mean": float(np.mean([h["measure_seconds"] for h in history])),
              "history": history, "fill": best.fill, "lux": best.lux, "stderr": best.lux_stderr,
              "grid": {k: [float(x) for x in np.asarray(req["grid"][k], float)] for k in ("origin", "u", "v")}
              if req.get("grid") else None,
              "start": {"uniformity": result.history[0].uniformity, "stderr": result.history[0].stderr}}
    png = plot(record, result.element.body["layout"])
    library.keep_record(summary["id"], ".pack.json", record)
    library.keep_record(summary["id"], ".pack.png", png)
    return {**{k: v for k, v in record.items() if k not in ("fill", "lux", "stderr")}, "summary": summary,
            "pack_url": f"/elements/{summary['id']}/pack", "png_url": f"/elements/{summary['id']}/pack.png"}


def _grid_frame(grid: dict[str, Any] | None, shape: tuple[int, ...]) -> tuple[tuple[float, float, float, float], str,
                                                                                  str]:
    """Extent (mm) and axis labels of a grid sensor's cells: world axes where u and v run along them (`service.maps`),
    else mm along the grid's u and v; cell indices where the record has no grid (one kept before it carried it)."""
    if grid is None:
        nv, nu = shape
        return (0.0, float(nu), 0.0, float(nv)), "sensor grid cell along its u", "sensor grid cell along its v"
    from service.maps import _axes_frame

    extent, xlabel, ylabel = _axes_frame(*(np.asarray(grid[k], float) for k in ("origin", "u", "v")))
    mm = tuple(1000.0 * e for e in extent)
    named = [f"world {x.replace(' (m)', ' (mm)')}" if x[1:] == " (m)" else f"sensor grid {x.replace('(m)', '(mm)')}"
             for x in (xlabel, ylabel)]
    return (mm[0], mm[1], mm[2], mm[3]), named[0], named[1]


def plot(record: dict[str, Any], layout: dict[str, Any]) -> bytes:
    """``pack.png``: `plot_figure` as a PNG."""
    out = io.BytesIO()
    plot_figure(record, layout).savefig(out, format="png")
    return out.getvalue()


def plot_figure(record: dict[str, Any], layout: dict[str, Any]) -> Any:
    """The figure of ``pack.png`` (a matplotlib `Figure`, constrained layout): the chosen density map over the
    support in the element's own u, v (mm), the illuminance (or luminance) it measured on the sensor grid in world mm
    (its colour scale from the smallest cell to the largest), and the figure against the iterations with its error
    bars and the target."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(14, 4.6), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    a, b, c = fig.subplots(1, 3)
    (u0, v0), (su, sv) = layout["origin_mm"], layout["size_mm"]
    im = a.imshow(np.asarray(record["fill"]), origin="lower", extent=(u0, u0 + su, v0, v0 + sv), vmin=0.0,
                  vmax=1.0, cmap="viridis", aspect="auto")
    fig.colorbar(im, ax=a, label="fill (share of sites with a dot)")
    # the element's own frame on its face (u along the node's x projected onto the face, v = n × u), not the grid's
    a.set(title=f"density map, pitch {layout.get('pitch_mm', 0):g} mm", xlabel="element u on the face (mm)",
          ylabel="element v on the face (mm)")
    lux = np.asarray(record["lux"])
    extent, xlabel, ylabel = _grid_frame(record.get("grid"), lux.shape)
    lo, hi = float(lux.min()), float(lux.max())
    im2 = b.imshow(lux, origin="lower", cmap="inferno", vmin=lo, vmax=hi if hi > lo else lo + 1.0, aspect="auto",
                   extent=extent)
    nv, nu = lux.shape
    for (j, i), x in np.ndenumerate(lux):
        b.text(extent[0] + (i + 0.5) * (extent[1] - extent[0]) / nu, extent[2] + (j + 0.5) * (extent[3] - extent[2])
               / nv, f"{x:.0f}", ha="center", va="center", color="cyan", fontsize=8)
    quantity, unit = record.get("quantity", "illuminance"), record.get("unit", "lx")
    fig.colorbar(im2, ax=b, label=f"{quantity} {'E' if unit == 'lx' else 'L'} ({unit}), min to max")
    b.set(title=f"measured on the sensor grid: {record['figure'].replace('_', '/')} {record['uniformity']:.3f} ± "
                f"{record['uniformity_stderr']:.3f}", xlabel=xlabel, ylabel=ylabel)
    h = record["history"]
    it = [x["iteration"] for x in h]
    c.errorbar(it, [x["uniformity"] for x in h], yerr=[x["stderr"] for x in h], marker="o", capsize=3,
               label="measured")
    conf = [x for x in h if x.get("confirmation")]
    if conf:   # a reading at the target, measured again with a fresh seed before the pack stops
        c.errorbar([x["iteration"] + 0.12 for x in conf], [x["confirmation"]["uniformity"] for x in conf],
                   yerr=[x["confirmation"]["stderr"] for x in conf], marker="s", ls="none", capsize=3,
                   label="fresh-seed confirmation")
    c.axhline(record["target"], color="grey", ls="--", label=f"target {record['target']:g}")
    c.set(title=f"stopped: {record['stopped']} ({sum(x['seconds'] for x in h):.1f} s)", xlabel="iteration",
          ylabel=record["figure"].replace("_", "/"), ylim=(0.0, 1.02))
    c.legend(loc="lower right")
    return fig
