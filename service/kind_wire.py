"""Light and sensor wire models made from the tracer's kinds, as `service.optics` makes the material models.

Each light kind (`tracer.optics.lights.dispatch.KINDS`) and each sensor kind a scene keeps
(`tracer.sensors.dispatch.KINDS`, those with ``FIELDS``) declares its body fields once, typed
(`tracer.optics.fields`). A kind's model here holds ``type``, ``name``, ``attached_to`` where its body lies
somewhere (a point, direction or edge field), a light's ``spectrum`` and ``polarization``, and its fields by their
value: a point, direction or edge is ``[x, y, z]``, a number or a count keeps its declared bounds, a choice its
choices, a node is a node reference (`service.wire.NodeRef`). Its validator then runs the tracer's own check
(a light's `light_spec`, a sensor kind's ``check``), so the rules across fields (exactly one magnitude, the falloff
within the cone, an aperture's shape, non-zero and non-parallel axes) are written once, in the tracer, and both
sides refuse alike. A node's instances are known only when the scene is read: the check gets a stand-in id, and
whether the scene holds them is the tracer's ``pack``/``probe`` at query time.

`fields_of` and `follow_node` give the rest of the service what a stored body's fields are: which follow the node
the body is attached to, and which names a node whose instances the tracer receives. A new kind in the tracer
appears in the REST body, the OpenAPI schema and the 422s with no change here.
"""

from __future__ import annotations

import copy
from typing import TYPE_CHECKING, Annotated, Any, Literal, Union

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, StringConstraints, create_model, model_validator

from service.wire import Attachable, NodeRef, Spectral, Vec3, Wire
from tracer.errors import TracerError
from tracer.geometry_id import MAX_FACE_INDEX
from tracer.optics.fields import PLACED, BodyField, is_placed, node_field
from tracer.optics.lights import dispatch as light_kinds
from tracer.sensors import dispatch as sensor_kinds

STAND_IN_INSTANCES = [0]   # a node field's instances for the check on the wire (see the module docstring)


class Placed(Wire):
    """A sensor placed in the world, or in a node's frame (``attached_to``)."""

    name: Annotated[str, StringConstraints(max_length=200)] | None = Field(None, description="A name for people.")
    attached_to: NodeRef | None = Field(None, description=(
        "A node (UUID or path): positions and directions are then in that node's frame, in metres, and follow it "
        "when a push moves it; default world."))


class Unplaced(Wire):
    """A sensor that lies nowhere of its own (it covers a node's surfaces, or the whole scene)."""

    name: Annotated[str, StringConstraints(max_length=200)] | None = Field(None, description="A name for people.")


class UnplacedLight(Spectral):
    """A light that lies nowhere of its own (a node's surfaces emit)."""

    name: Annotated[str, StringConstraints(max_length=200)] | None = Field(None, description="A name for people.")


def _type(f: BodyField) -> Any:
    """The wire type of one declared field (`tracer.optics.fields`)."""
    if f.value in PLACED or f.value == "part_dir":
        return Vec3
    if f.value == "node":
        return NodeRef
    if f.value == "faces":
        return Annotated[list[Annotated[int, Field(ge=0, le=MAX_FACE_INDEX)]], Field(min_length=1, max_length=10_000)]
    if f.value == "choice":
        return Literal[f.choices]
    if f.value == "text":
        return Annotated[str, StringConstraints(min_length=1, max_length=f.max_length or None)]
    limits: dict[str, Any] = {}
    if np.isfinite(f.lo):
        limits["gt" if f.lo_open else "ge"] = f.lo
    if np.isfinite(f.hi):
        limits["lt" if f.hi_open else "le"] = f.hi
    if f.value == "count":
        counts: dict[str, Any] = {k: int(v) for k, v in limits.items()}
        return Annotated[int, Field(**counts)]
    return Annotated[float, Field(**limits)]


def _model(family: str, name: str, module: Any, table: dict[str, BodyField], base: type[BaseModel],
           check: Any) -> type[BaseModel]:
    """The pydantic model of one kind's wire body; `check(body)` is the tracer's check (raises `TracerError`)."""
    doc = (module.__doc__ or name).strip().split("\n\n")[0]
    fields: dict[str, Any] = {"type": (Literal[name], Field(description=doc.split("\n")[0]))}
    for f in table.values():
        fields[f.name] = ((_type(f), Field(description=f.doc)) if f.required
                          else (_type(f) | None, Field(None, description=f.doc)))
    node = node_field(table)

    def _check(self):
        body = self.model_dump(exclude_none=True)
        if node is not None:
            body["instances"] = STAND_IN_INSTANCES
        try:
            check(body)
        except TracerError as exc:
            raise ValueError(str(exc).removeprefix(f"{family}: ")) from None
        return self

    if hasattr(module, "EXAMPLE"):   # shown by /docs (tests/service/test_openapi_docs.py sends each)
        base = type(f"_{name}_{family}", (base,), {"__module__": __name__, "model_config": ConfigDict(
            json_schema_extra={"examples": [module.EXAMPLE]})})
    validators: dict[str, Any] = {"_check": model_validator(mode="after")(_check)}
    return create_model(name.title().replace("_", "") + family.title(), __base__=base, __doc__=doc,
                        __validators__=validators, **fields)


def _light(module: Any) -> type[BaseModel]:
    table = light_kinds.body_fields(module)
    return _model("light", module.NAME, module, table, Attachable if is_placed(table) else UnplacedLight,
                  lambda body: light_kinds.light_spec(body, "light"))


def _sensor(name: str, module: Any) -> type[BaseModel]:
    return _model("sensor", name, module, module.FIELDS, Placed if is_placed(module.FIELDS) else Unplaced,
                  module.check)


LIGHT_MODELS = tuple(_light(m) for m in light_kinds.KINDS)
SENSOR_MODELS = tuple(_sensor(name, m) for name, m in sensor_kinds.KINDS.items() if m.FIELDS is not None)
#: the field tables of the kinds on the wire, by family and ``type``
FIELDS: dict[str, dict[str, dict[str, BodyField]]] = {
    "light": {m.NAME: light_kinds.body_fields(m) for m in light_kinds.KINDS},
    "sensor": {name: m.FIELDS for name, m in sensor_kinds.KINDS.items() if m.FIELDS is not None}}

if TYPE_CHECKING:  # the models are made at import: to a type checker a light or a sensor is a wire model
    Light = Wire
    Sensor = Wire
else:
    Light = Annotated[Union[LIGHT_MODELS], Field(discriminator="type")]  # noqa: UP007 (a runtime tuple)
    Sensor = Annotated[Union[SENSOR_MODELS], Field(discriminator="type")]  # noqa: UP007 (a runtime tuple)


class LightCreate(Wire):
    light: Light = Field(description="A light body.")


class SensorCreate(Wire):
    sensor: Sensor = Field(description="A sensor body.")


def fields_of(family: str, body: dict) -> dict[str, BodyField]:
    """The declared fields of a `family` ("light", "sensor") body's kind ({} for an object or a type no kind has;
    a light kind and a sensor kind may share a name)."""
    return FIELDS.get(family, {}).get(body.get("type"), {})   # type: ignore[arg-type]


def anchor_of(family: str, body: dict) -> str | None:
    """The node a light, sensor or object body depends on: the one it is attached to, or the one its node field
    names."""
    node = node_field(fields_of(family, body))
    return body.get("attached_to") or (body.get(node) if node is not None else None)


def follow_node(family: str, body: dict, world: np.ndarray | None, instances: list[int] | None) -> dict:
    """A stored body in world metres: its points, directions and edges carried by the node's 4×4 `world` (a
    direction made unit) where it is attached, and a node field's `instances` given; a linear polarization's axis
    turns with the node too."""
    out = {k: copy.deepcopy(v) for k, v in body.items() if k not in ("attached_to", "name")}
    table = fields_of(family, body)
    if instances is not None:
        out["instances"] = instances
    if world is None:
        return out
    lin = world[:3, :3]
    for f in table.values():
        if f.name not in out or f.value not in PLACED:
            continue
        v = lin @ np.asarray(out[f.name], dtype=float)
        if f.value == "point":
            v = v + world[:3, 3]
        elif f.value == "direction":
            v = v / np.linalg.norm(v)
        out[f.name] = v.tolist()
    pol = out.get("polarization")
    if isinstance(pol, dict) and pol.get("type") == "linear":   # the field's axis turns with the node
        a = lin @ np.asarray(pol["axis"], dtype=float)
        out["polarization"] = {**pol, "axis": (a / np.linalg.norm(a)).tolist()}
    return out


if TYPE_CHECKING:   # made from the registry at import: to a type checker it is a string
    SensorType = str
else:
    SensorType = Literal[tuple(FIELDS["sensor"])]   # the wire's sensor types, from the tracer's kinds
