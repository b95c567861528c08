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
  runs (``sized(sensor, limits)``: what its body alone makes too large, before the scene is even read);
- ``body(sensor, live)``: the tracer sensor body of a stored sensor (world metres);
- ``payload(result, sensor, live)``: the answer's JSON, ``lux`` (or ``candela``) and the kind's own fields, with
  ``min_lux``/``mean_lux``/``max_lux`` where it answers lux;
- where it differs from `service.sensor_base.SensorKind`'s defaults: what its kept results are (`service.results`:
  ``QUANTITY``, ``kept(sensor)``, ``layout(meta)``, ``centres(meta, shape)``, ``size(meta, values)``,
  ``change(...)``), why a body of it cannot be made here (``refusal(sensor, limits)``), its centre for the distance
  warnings (``centre(sensor)``), and what may be drawn or driven from it (``DIFFERENCE_MAP``, ``PACKS``);
- ``ANSWER``: the model of that answer (on `service.sensor_base`' bases, ``type`` its own literal): the wire's
  answer, `SensorPublic`, is the union of every kind's, told apart by ``type``.
"""

from __future__ import annotations

from collections.abc import Callable
from types import SimpleNamespace
from typing import TYPE_CHECKING, Annotated, Any, Literal, Union

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, create_model

from service import kind_wire
from service.errors import Invalid, TooLarge
from service.maps import cell_centres, summarize_change
from service.payloads import finite_list, result_payload
from service.sensor_base import LuxAnswer, SensorAnswer, SensorKind, count_refusal
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


class GridAnswer(LuxAnswer):
    """A grid's answer: ``lux``/``stderr`` are nv rows of nu cells, lx."""

    type: Literal["grid"] = Field(description="The sensor's kind.")
    nu: int = Field(description="Cells along u.")
    nv: int = Field(description="Cells along v.")
    origin: list[float] = Field(description="Corner of the rectangle, world metres.")
    u: list[float] = Field(description="Edge along which the nu cells lie, world metres.")
    v: list[float] = Field(description="Edge along which the nv cells lie, world metres.")
    map_url: str | None = Field(None, description="The false-colour PNG of this result.")


class Grid(SensorKind):
    """A rectangle of nu × nv cells, each answering its mean illuminance (lx)."""

    TYPE = "grid"
    KEEP = "map"
    ANSWER = GridAnswer
    DIFFERENCE_MAP = True
    PACKS = True

    @staticmethod
    def layout(meta: dict) -> tuple[int, int]:
        return int(meta["nv"]), int(meta["nu"])

    @staticmethod
    def centres(meta: dict, shape: tuple[int, int]) -> np.ndarray:
        return cell_centres(meta["origin"], meta["u"], meta["v"], int(meta["nu"]), int(meta["nv"]))

    @staticmethod
    def size(meta: dict, values: int) -> str:
        return f"a {meta['nu']} x {meta['nv']} grid"

    @staticmethod
    def change(before: np.ndarray, after: np.ndarray, se_before: np.ndarray, se_after: np.ndarray,
               meta: dict) -> dict[str, Any]:
        s = summarize_change(before, after, meta["origin"], meta["u"], meta["v"], stderr_before=se_before,
                             stderr_after=se_after)
        return {**s.__dict__, "max_increase_at": list(s.max_increase_at), "max_decrease_at": list(s.max_decrease_at)}

    @staticmethod
    def refusal(sensor: dict, limits: Any) -> tuple[str, int] | None:
        return count_refusal(sensor, "nu", "nv", "cells", limits)

    @staticmethod
    def centre(sensor: dict) -> np.ndarray:
        return np.asarray(sensor["origin"], float) + 0.5 * (np.asarray(sensor["u"], float) +
                                                            np.asarray(sensor["v"], float))

    @staticmethod
    def sized(sensor: dict, limits: Any) -> None:
        nu, nv = int(sensor["nu"]), int(sensor["nv"])
        if nu * nv > limits.max_points:
            raise TooLarge(f"sensor {sensor['id']!r} has {nu * nv} cells; this service answers "
                           f"at most {limits.max_points} points per query", limit=limits.max_points)

    @staticmethod
    def check(sensor: dict, query: Query, limits: Any, live: Any) -> None:
        Grid.sized(sensor, limits)

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


class Measured(SensorKind):
    """Any sensor kind the service has no class of its own for (the disk among them): its tracer body made from its
    declared fields (`tracer.optics.fields`), its answer the tracer's lux with ``min_lux``/``mean_lux``/``max_lux``,
    kept in the result store."""

    TYPE = ""   # every wire sensor kind not in `KINDS`
    KEEP = "store"
    ANSWER = LuxAnswer   # what each of them answers, less its own ``type`` (`answer`)

    @staticmethod
    def kept(sensor: dict) -> dict[str, Any]:
        """Its placed fields (a disk's centre, normal and radius), so a kept result says where it measured."""
        out: dict[str, Any] = {}
        for f in kind_wire.fields_of("sensor", sensor).values():
            v = sensor.get(f.name)
            if v is None or f.value not in ("point", "vector", "direction", "number"):
                continue
            out[f.name] = float(v) if f.value == "number" else list(map(float, v))
        return out

    @staticmethod
    def centres(meta: dict, shape: tuple[int, int]) -> np.ndarray:
        centre = meta.get("center") or [np.nan] * 3
        return np.broadcast_to(np.asarray(centre, float), (*shape, 3))

    @staticmethod
    def answer(kind: str) -> type[BaseModel]:
        """The answer model of wire sensor kind `kind`: illuminance, one value per point it measures."""
        name = "".join(part.title() for part in kind.split("_")) + "Answer"
        literal: Any = Literal[kind]   # a literal of a name known at run time
        return create_model(name, __base__=LuxAnswer, __doc__=f"A {kind} sensor's answer: ``lux``/``stderr``, lx.",
                            type=(literal, Field(description="The sensor's kind.")))

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


class SurfaceInstance(BaseModel):
    """One instance of a surface sensor's node subtree and the illuminance on each of its triangles."""

    model_config = ConfigDict(extra="forbid")

    instance: int = Field(description="The tracer's instance id.")
    node: str | None = Field(description="The node (UUID) the instance belongs to; a simulation-owned object's id.")
    path: str | None = Field(None, description="The node's path; null for a simulation-owned object.")
    geometry: str = Field(description="The geometry (id) whose triangles are listed, in its order.")
    lux: list[float] = Field(description="Illuminance on each triangle's front side, lx (area average).")
    stderr: list[float] = Field(description="Standard error of each value, lx.")
    area: list[float] = Field(description="World area of each triangle, m² (lux × area: the flux it receives, lm).")


class SurfaceAnswer(LuxAnswer):
    """A surface sensor's answer: ``lux``/``stderr`` every triangle's, instance after instance as in ``instances``;
    ``min_lux``/``max_lux`` over all triangles, ``mean_lux`` area-weighted (the total flux over the total area)."""

    type: Literal["surface"] = Field(description="The sensor's kind.")
    node: str | None = Field(None, description="The sensor's node (UUID).")
    instances: list[SurfaceInstance] = Field(description=(
        "Each instance of the node's subtree, its triangles' illuminance on their front side (the outside of a CAD "
        "solid)."))
    max_lux_stderr: float = Field(description=(
        "The standard error of `max_lux` (its triangle's), lx: a small triangle by a lamp gets few photons and a "
        "wide error bar."))
    max_lux_area: float = Field(description="The area of the triangle `max_lux` is on, m².")
    max_lux_p99: float = Field(description=(
        "A robust maximum: the illuminance 99 % of the surfaces' area is at or below (area-weighted 99th percentile "
        "over the triangles), lx."))


class Surface(SensorKind):
    """A node's surfaces: the illuminance on each triangle of its instances (`tracer.sensors.surface`). ``lux`` and
    ``stderr`` are every triangle's, instance after instance in ``instances`` order (each instance's triangles in its
    geometry's order); ``instances`` gives each one's node, path, instance id, geometry and its own ``lux``/``stderr``.
    Forward only, without observe, reference or physics_left_out."""

    TYPE = "surface"
    KEEP = "map"
    ANSWER = SurfaceAnswer

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


class FarFieldAnswer(SensorAnswer):
    """A far field's answer: ``candela``/``stderr`` as nγ rows of nc values, cd (no lux)."""

    type: Literal["far_field"] = Field(description="The sensor's kind.")
    candela: list[list[float]] = Field(description=(
        "Luminous intensity, cd, nγ rows (γ_j, `gamma_deg`) of nc values (C_i, `c_deg`): the flux leaving the scene "
        "in each bin's directions over the bin's solid angle; `stderr` holds its standard errors."))
    c_deg: list[float] = Field(description="The C angles C_i = i·360°/nc, degrees.")
    gamma_deg: list[float] = Field(description="The γ angles γ_j = j·180°/(nγ−1), degrees.")
    flux_lm: float = Field(description="The total luminous flux leaving the scene, lm.")
    flux_stderr: float = Field(description="Standard error of `flux_lm`, lm.")
    max_cd: float = Field(description="The largest intensity, cd.")
    nc: int = Field(description="C samples.")
    ngamma: int = Field(description="γ samples.")
    direction: list[float] = Field(description="The γ = 0 axis (unit, world).")
    c0: list[float] = Field(description="The C = 0 axis (unit, world, across `direction`).")


class FarField(SensorKind):
    """The scene as a lamp (`tracer.sensors.far_field`): ``candela`` and ``stderr`` (cd) as nγ rows of nc values,
    ``c_deg``, ``gamma_deg``, ``flux_lm`` ± ``flux_stderr`` leaving the scene, and the frame. Forward only, without
    observe, reference or physics_left_out; not kept past an edit as lux results are."""

    TYPE = "far_field"
    KEEP = "far"
    ANSWER = FarFieldAnswer
    QUANTITY = "candela"

    @staticmethod
    def refusal(sensor: dict, limits: Any) -> tuple[str, int] | None:
        return count_refusal(sensor, "nc", "ngamma", "bins", limits)

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


def types_where(test: Callable[[Any], bool]) -> list[str]:
    """The wire types of the kinds with a class of their own that pass `test`, sorted: what a refusal names."""
    return sorted(t for t, k in KINDS.items() if test(k))


def kind_of_type(kind: Any) -> Any:
    """The class of a kept result's ``type`` (`Measured` for a kind with no class of its own)."""
    return KINDS.get(str(kind), Measured)


def answer_of(kind: str) -> type[BaseModel]:
    """The answer model of wire sensor kind `kind`: its class's own, else `Measured`'s."""
    return KINDS[kind].ANSWER if kind in KINDS else Measured.answer(kind)


if TYPE_CHECKING:   # made from the registry at import: to a type checker it is a model
    SensorPublic = SensorAnswer
else:
    #: the answer of a sensor simulation: one model per wire sensor kind (from the tracer's kinds), told apart by type
    SensorPublic = Annotated[Union[tuple(answer_of(t) for t in kind_wire.FIELDS["sensor"])],  # noqa: UP007
                             Field(discriminator="type")]
