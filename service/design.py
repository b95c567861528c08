"""The design loop over an element's parameters against a scene (issue 53): ``POST /elements/{id}/design`` as a job.

The request is a pack's (`service.pack`: the scene, the element assignment on the guide's face, a grid sensor over the
lit face, what its cells read) with the parameters to vary (``[{"name": "feature.height_mm", "values": [...]} | {"name",
"lo", "hi", "steps"}]``, one to three), the ``objective`` (``min_max``, ``min_mean``, ``mean`` or the viewing-angle
spread ``half_angle``), its ``goal`` (``max`` or ``min``) and ``pack_map`` (pack the density map before and after the
sweep with the pack's fields: target, figure, iterations). Everything is checked before a job is queued (422 naming the
field, nothing changed), as a pack is. The job works on a scene of its own (`tracer.elements.design.design`); the chosen
element goes into the library with its record (``GET /elements/{id}/design``: every candidate, the baseline, the
confirmation on a fresh seed; ``design.png``, its picture), and the scene everybody queries is switched to it by ``PUT
/scenes/{id}/elements/{aid}``, as after a pack.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from service.errors import Invalid
from tracer.transport.query import Budget


def start(manager: Any, hub: Any, element_id: str, req: dict[str, Any]) -> tuple[str, int, Any, Budget, dict]:
    """Check a design request and set it up: ``(scene_id, revision, work, budget, meta)`` for `JobRunner.submit`."""
    from service import pack
    from tracer.elements import ElementError
    from tracer.elements.design import Parameter, check
    from tracer.elements.pack import check as check_pack

    try:
        parameters = [Parameter.from_body(p, k) for k, p in enumerate(req["parameters"])]
    except ElementError as exc:
        raise Invalid(str(exc)) from None

    def checks(model: Any) -> None:
        check(model, parameters, req["objective"], req.get("goal", "max"))
        if req["pack_map"]:
            check_pack(model, req["target"], req["figure"], req["damping"], req["max_fill"], req.get("pitch_mm"))

    run = pack.setup(manager, hub, element_id, req, checks)
    pack_options = {k: req[k] for k in ("target", "figure", "photons", "max_photons", "max_iterations", "damping",
                                        "max_fill", "pitch_mm")} if req["pack_map"] else None

    def work(progress: Any = None, cancel: Any = None) -> dict[str, Any]:
        from tracer.elements.design import design

        def report(s: dict[str, Any]) -> None:
            if progress is not None:
                progress(s["photons"], math.nan, s["seconds"], stage=s["stage"], candidate=s["candidate"],
                         candidates=s["candidates"], objective=s["objective"], objective_stderr=s["stderr"])

        try:
            result = design(run.own.tracer, run.instance, run.start, run.sensor, run.simulation, assign=run.assign,
                            parameters=parameters, objective=req["objective"], goal=req.get("goal", "max"),
                            photons=req["photons"], seed=req["seed"], reading=run.reading, pack_options=pack_options,
                            max_seconds=req["max_seconds"], progress=report, cancel=cancel)
        except ElementError as exc:
            raise Invalid(str(exc)) from None
        return keep(run.library, element_id, req, result)

    budget = Budget(max_seconds=float(req["max_seconds"]))
    meta = {"generation": hub.generation(run.scene_id), "sensor": req["sensor"], "element": element_id}
    return run.scene_id, int(run.own.revision), work, budget, meta


def keep(library: Any, element_id: str, req: dict[str, Any], result: Any) -> dict[str, Any]:
    """The chosen element into the library with its record (``<id>.design.json``); answers the job's result."""
    summary, _ = library.create(result.element.body)
    record = {"element": summary["id"], "designed_from": element_id, "scene": req["scene"],
              "assignment": req["assignment"], "sensor": req["sensor"], "objective": result.objective,
              "goal": result.goal, **_measured(result), "stopped": result.stopped,
              "values": result.values, "baseline": result.baseline, "confirmation": result.confirmation,
              "candidates": [c.public() for c in result.candidates],
              "packs": [{"stopped": p.stopped, "iterations": len(p.history), "uniformity": p.history[p.best].uniformity,
                         "uniformity_stderr": p.history[p.best].stderr} for p in result.packs],
              "seconds": result.seconds}
    if summary["id"] == element_id:   # no candidate read better than the start: the start stays, no record
        return {**record, "summary": summary, "design_url": None, "png_url": None}
    library.keep_record(summary["id"], ".design.json", record)
    library.keep_record(summary["id"], ".design.png", plot(record))
    return {**record, "summary": summary, "design_url": f"/elements/{summary['id']}/design",
            "png_url": f"/elements/{summary['id']}/design.png"}


def _measured(result: Any) -> dict[str, str]:
    """What the objective was read as: ``quantity`` and ``unit`` (a conoscopic view's angle for ``half_angle``)."""
    if result.objective == "half_angle":
        return {"quantity": "luminance", "unit": "deg"}
    return {"quantity": result.reading.quantity, "unit": result.reading.unit}


def plot(record: dict[str, Any]) -> bytes:
    """``design.png``: `plot_figure` as a PNG."""
    import io

    out = io.BytesIO()
    plot_figure(record).savefig(out, format="png")
    return out.getvalue()


def plot_figure(record: dict[str, Any]) -> Any:
    """The figure of ``design.png`` (a matplotlib `Figure`): every candidate's objective with its error bar (the same
    seed for all), the start's reading beside them, the chosen one starred, the confirmation on a fresh seed in the
    title."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 4.8), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    read = [c for c in record["candidates"] if c["objective"] is not None]
    names = list(record["values"])
    labels = [", ".join(f"{c['values'][n]:g}" for n in names) for c in read]
    x = np.arange(len(read))
    ax.errorbar(x, [c["objective"] for c in read], yerr=[c["stderr"] for c in read], marker="o", ls="none",
                capsize=3, label="candidates (one seed for all)")
    b = record["baseline"]
    ax.axhline(b["objective"], color="grey", ls="--", label=f"start {b['objective']:.4g} ± {b['stderr']:.2g}")
    chosen = [k for k, c in enumerate(read) if c["values"] == record["values"]]
    if chosen:
        ax.plot(x[chosen], [read[k]["objective"] for k in chosen], marker="*", ms=16, ls="none", color="tab:red",
                label="chosen")
    ax.set_xticks(x, labels, rotation=30 if len(read) > 6 else 0)
    unit = record.get("unit", "lx")
    what = {"mean": f"mean {record.get('quantity', 'illuminance')} ({unit})",
            "half_angle": "half-luminance viewing angle (°)"}.get(record["objective"],
                                                                  record["objective"].replace("_", "/"))
    what += " · lower is better" if record.get("goal") == "min" else ""
    c = record.get("confirmation")
    title = f"{record['stopped']}: {record['values']}"
    if c:
        title += (f"\nfresh seed: {c['baseline']:.4g} ± {c['baseline_stderr']:.2g} → {c['objective']:.4g} ± "
                  f"{c['stderr']:.2g} (gain {c['improvement']:.3g} ± {c['improvement_stderr']:.2g})")
    ax.set(title=title, xlabel=", ".join(names), ylabel=what)
    ax.legend(loc="best")
    return fig
