"""The service's side of each sensor kind: one class per kind, one registry (`KINDS`), no switch on a kind elsewhere
in `service.simulation`.

A kind here says what the service needs beyond the tracer's sensor kind (`tracer.sensors`); a tracer kind with no
class here is answered by `Measured` (its body from its declared fields, its lux summarised, kept in the result
store), so a new sensor kind needs a class only where it stores or renders something of its own:

- ``TYPE``: the wire's ``type``, the same as the tracer kind it runs;
- ``KEEP``: where its latest result is kept: ``"map"`` (in memory while the scene is unchanged, for ``map.png`` and
  the page, and in the result store), ``"image"`` (in memory for a camera's images, and in the result store:
  `service.view_kinds`), ``"store"`` (the result store only), ``"far"`` (the far-field store: its
  export outlives a restart and an edit);
- ``check(sensor, query, limits, live)``: refuse (422 `Invalid`, 413 `TooLarge`) what it cannot answer, before anything
  runs;
- ``body(sensor, live)``: the tracer sensor body of a stored sensor (world metres);
- ``payload(result, sensor, live)``: the answer's JSON, ``lux`` (or ``candela``) and the kind's own fields, with
  ``min_lux``/``mean_lux``/``max_lux`` where it answers lux.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from service import kind_wire
from service.errors import Invalid, TooLarge
from service.payloads import finite_list, result_payload
from service.view_kinds import Camera, Luminance
from tracer.transport.query import Query


def summary(payload: dict[str, Any], lux: np.ndarray, weights: np.ndarray | None = None) -> dict[str, Any]:
    """``min_lux``, ``mean_lux`` (weighted by `weights`, e.g. triangle areas: total flux / total area) and
    ``max_lux`` added to `payload`."""
    if weights is None:
        mean = float(lux.mean())
    else:
        mean = float(lux @ weights / weights.sum()) if weights.sum() > 0 else 0.0
    payload.update(min_lux=float(lux.min()), mean_lux=mean, max_lux=float(lux.max()))
    return payload


ROBUST_QUANTILE = 0.99   # a surface's robust maximum: the illuminance this share of its area is at or below


def robust_max(payload: dict[str, Any], lux: np.ndarray, stderr: np.ndarray, area: np.ndarray) -> dict[str, Any]:
    """Beside ``max_lux`` (lx) of a surface (one value per triangle, `area` m² each): ``max_lux_stderr`` (that
    triangle's standard error, lx), ``max_lux_area`` (its area, m²) and ``max_lux_p99`` (lx): the illuminance 99 %
    of the area is at or below, which a tiny triangle with few photons does not move. Added to `payload`."""
    k = int(np.argmax(lux))
    order = np.argsort(lux, kind="stable")
    w = area[order] if area.sum() > 0 else np.ones(len(lux))
    i = int(np.searchsorted(np.cumsum(w), ROBUST_QUANTILE * w.sum()))
    payload.update(max_lux_stderr=float(stderr[k]), max_lux_area=float(area[k]),
                   max_lux_p99=float(lux[order[min(i, len(lux) - 1)]]))
    return payload


def refuse_for_tally(sid: Any, kind: str, unit: str, query: Query) -> None:
    """Surface and far-field sensors are forward tallies of every `unit` (triangle, bin): refuse (422) what they
    cannot answer — observables, a target scope other than "worst", the backward estimator."""
    for field, given in (("observe", query.observe), ("reference", query.reference),
                         ("physics_left_out", query.physics_left_out)):
        if given:
            raise Invalid(f"sensor {sid!r} is a {kind} sensor: {field} is not available for it")
    if query.budget.scope != "worst":
        raise Invalid(f"sensor {sid!r} is a {kind} sensor: its target holds every {unit} (target_scope "
                      f"'worst'); give it a photon or time budget instead")
    if query.estimator == "backward":
        raise Invalid(f"sensor {sid!r} is a {kind} sensor: the backward estimator cannot answer it; use "
                      f"'forward' or 'auto'")


def _flat(result: Any, lux: Any, stderr: Any) -> SimpleNamespace:
    """A result's common fields with `lux` and `stderr` in place of its own (for `result_payload`)."""
    flat = SimpleNamespace(**{name: getattr(result, name) for name in (
        "photons", "seconds", "effects", "estimator", "stop_reason", "compile_seconds", "backend",
        "effect_reasons")})
    flat.lux, flat.stderr = lux, stderr
    return flat


class Grid:
    """A rectangle of nu × nv cells, each answering its mean illuminance (lx)."""

    TYPE = "grid"
    KEEP = "map"

    @staticmethod
    def check(sensor: dict, query: Query, limits: Any, live: Any) -> None:
        nu, nv = int(sensor["nu"]), int(sensor["nv"])
        if nu * nv > limits.max_points:
            raise TooLarge(f"sensor {sensor['id']!r} has {nu * nv} cells; this service answers "
                           f"at most {limits.max_points} points per query", limit=limits.max_points)

    @staticmethod
    def body(sensor: dict, live: Any) -> dict:
        return {"type": "grid", "nu": int(sensor["nu"]), "nv": int(sensor["nv"]),
                **{k: np.asarray(sensor[k], float) for k in ("origin", "u", "v")}}

    @staticmethod
    def payload(result: Any, sensor: dict, live: Any) -> dict:
        payload = result_payload(result, live.revision)
        payload.update(sensor=str(sensor["id"]), type="grid", nu=int(sensor["nu"]), nv=int(sensor["nv"]),
                       origin=list(map(float, sensor["origin"])), u=list(map(float, sensor["u"])),
                       v=list(map(float, sensor["v"])))
        return summary(payload, np.asarray(payload["lux"], float))


class Measured:
    """Any sensor kind the service has no class of its own for (the disk among them): its tracer body made from its
    declared fields (`tracer.optics.fields`), its answer the tracer's lux with ``min_lux``/``mean_lux``/``max_lux``,
    kept in the result store."""

    TYPE = ""   # every wire sensor kind not in `KINDS`
    KEEP = "store"

    @staticmethod
    def check(sensor: dict, query: Query, limits: Any, live: Any) -> None:
        pass

    @staticmethod
    def body(sensor: dict, live: Any) -> dict:
        out: dict[str, Any] = {"type": sensor["type"]}
        for f in kind_wire.fields_of("sensor", sensor).values():
            v = sensor.get(f.name)
            if f.value == "node":
                out["instances"] = [int(i) for i in sensor.get("instances", [])]
            elif v is None:
                continue
            elif f.value == "direction":
                # made unit here and again by the tracer, as the service always did for a disk's normal: one
                # rounding fewer would move the answer's last bits
                d = np.asarray(v, float)
                out[f.name] = d / np.linalg.norm(d)
            elif f.value in ("point", "vector"):
                out[f.name] = np.asarray(v, float)
            else:
                out[f.name] = {"number": float, "count": int}.get(f.value, lambda x: x)(v)
        return out

    @staticmethod
    def payload(result: Any, sensor: dict, live: Any) -> dict:
        payload = result_payload(result, live.revision)
        payload.update(sensor=str(sensor["id"]), type=str(sensor["type"]))
        return summary(payload, np.asarray(payload["lux"], float))


class Surface:
    """A node's surfaces: the illuminance on each triangle of its instances (`tracer.sensors.surface`). ``lux`` and
    ``stderr`` are every triangle's, instance after instance in ``instances`` order (each instance's triangles in its
    geometry's order); ``instances`` gives each one's node, path, instance id, geometry and its own ``lux``/``stderr``.
    Forward only, without observe, reference or physics_left_out."""

    TYPE = "surface"
    KEEP = "map"

    @staticmethod
    def check(sensor: dict, query: Query, limits: Any, live: Any) -> None:
        sid = sensor.get("id")
        refuse_for_tally(sid, "surface", "triangle", query)
        instances = [int(i) for i in sensor.get("instances", [])]
        if not instances:
            raise Invalid(f"sensor {sid!r}: node {sensor.get('node')} and its descendants have no geometry in "
                          f"revision {live.revision}: nothing to tally", node=sensor.get("node"))
        triangles = sum(len(live.tracer.geometry_arrays(live.tracer.instance_geometry(i))[1]) for i in instances)
        if triangles > limits.max_points:
            raise TooLarge(f"sensor {sid!r} covers {triangles} triangles; this service answers at most "
                           f"{limits.max_points} points per query", limit=limits.max_points)

    @staticmethod
    def body(sensor: dict, live: Any) -> dict:
        return {"type": "surface", "instances": [int(i) for i in sensor.get("instances", [])]}

    @staticmethod
    def payload(result: Any, sensor: dict, live: Any) -> dict:
        payload = result_payload(_flat(result, np.concatenate(result.lux), np.concatenate(result.stderr)),
                                 live.revision)
        node_of = {inst: key for key, inst in live.instance_of_node.items()}
        payload.update(sensor=str(sensor.get("id")), type="surface", node=sensor.get("node"), instances=[
            {"instance": inst, "node": node_of.get(inst), "path": None,   # the route names the paths
             "geometry": live.tracer.instance_geometry(inst), "lux": finite_list(lux), "stderr": finite_list(err),
             "area": finite_list(area)}
            for inst, lux, err, area in zip(result.instances, result.lux, result.stderr, result.area, strict=True)])
        area = np.concatenate([np.asarray(i["area"], float) for i in payload["instances"]])
        lux = np.asarray(payload["lux"], float)
        robust_max(payload, lux, np.asarray(payload["stderr"], float), area)
        return summary(payload, lux, area)


class FarField:
    """The scene as a lamp (`tracer.sensors.far_field`): ``candela`` and ``stderr`` (cd) as nγ rows of nc values,
    ``c_deg``, ``gamma_deg``, ``flux_lm`` ± ``flux_stderr`` leaving the scene, and the frame. Forward only, without
    observe, reference or physics_left_out; not kept past an edit as lux results are."""

    TYPE = "far_field"
    KEEP = "far"

    @staticmethod
    def check(sensor: dict, query: Query, limits: Any, live: Any) -> None:
        sid = sensor.get("id")
        refuse_for_tally(sid, "far-field", "bin", query)
        nc, ng = int(sensor["nc"]), int(sensor["ngamma"])
        if nc * ng > limits.max_points:
            raise TooLarge(f"sensor {sid!r} has {nc} x {ng} = {nc * ng} bins; this service answers at most "
                           f"{limits.max_points} points per query", limit=limits.max_points)

    @staticmethod
    def body(sensor: dict, live: Any) -> dict:
        return {"type": "far_field", "nc": int(sensor["nc"]), "ngamma": int(sensor["ngamma"]),
                **{k: np.asarray(sensor[k], float) for k in ("direction", "c0") if sensor.get(k) is not None}}

    @staticmethod
    def payload(result: Any, sensor: dict, live: Any) -> dict:
        payload = result_payload(_flat(result, result.candela, result.stderr), live.revision)
        payload["candela"] = payload.pop("lux")
        payload.update(sensor=str(sensor.get("id")), type="far_field", nc=int(sensor["nc"]),
                       ngamma=int(sensor["ngamma"]), c_deg=finite_list(result.c_deg),
                       gamma_deg=finite_list(result.gamma_deg), flux_lm=float(result.flux_lm),
                       flux_stderr=float(result.flux_stderr), direction=finite_list(result.direction),
                       c0=finite_list(result.c0), max_cd=float(np.max(result.candela)))
        return payload


#: the sensor kinds that store or render something of their own, by their wire ``type``; every other sensor kind of
#: the wire (`service.kind_wire`, from the tracer's kinds) is `Measured`
KINDS: dict[str, Any] = {k.TYPE: k for k in (Grid, Surface, FarField, Luminance, Camera)}


def kind_of(sensor: dict) -> Any:
    """The service kind of a stored sensor; 422 for a type no kind answers."""
    t = str(sensor.get("type"))
    kind = KINDS.get(t) or (Measured if t in kind_wire.FIELDS["sensor"] else None)
    if kind is None:
        raise Invalid(f"sensor {sensor.get('id')!r} has type {sensor.get('type')!r}, which cannot be simulated")
    return kind

if TYPE_CHECKING:   # made from the registry at import: to a type checker it is a string
    SensorType = str
else:
    SensorType = Literal[tuple(kind_wire.FIELDS["sensor"])]   # the wire's sensor types, from the tracer's kinds
