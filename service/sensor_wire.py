"""Sensor wire bodies (DESIGN.md): one model per kind, the discriminated union `Sensor`, and `SensorCreate`.

The service answers each kind through `service.sensor_kinds`, the tracer measures it through `tracer.sensors`.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import ConfigDict, Field, StringConstraints, model_validator

from service.wire import Attachable, NodeRef, Positive, Vec3, Wire, nonzero

GRID_SENSOR_EXAMPLE: dict[str, Any] = {"type": "grid", "name": "floor grid", "origin": [-2.0, -2.0, 0.01],
                                       "u": [4.0, 0.0, 0.0], "v": [0.0, 4.0, 0.0], "nu": 20, "nv": 20}
DISK_SENSOR_EXAMPLE: dict[str, Any] = {"type": "disk", "name": "desk", "center": [0.5, 0.5, 0.75],
                                       "normal": [0.0, 0.0, 1.0], "radius": 0.05}


class GridSensor(Attachable):
    """A rectangle ``origin + s·u + t·v`` (s, t in [0, 1]) split into nu × nv cells; front side u × v."""

    type: Literal["grid"] = Field(description="A rectangle of cells, each answering its mean illuminance.")
    origin: Vec3 = Field(description="A corner of the rectangle [x, y, z], m.")
    u: Vec3 = Field(description="The edge along which the nu cells lie, m (its length is the width).")
    v: Vec3 = Field(description="The edge along which the nv cells lie, m; u × v is the side facing the light.")
    nu: Annotated[int, Field(ge=1, le=4096)] = Field(description="Cells along u.")
    nv: Annotated[int, Field(ge=1, le=4096)] = Field(description="Cells along v.")

    model_config = ConfigDict(json_schema_extra={"examples": [GRID_SENSOR_EXAMPLE]})

    @model_validator(mode="after")
    def _check(self) -> GridSensor:
        nonzero("u", self.u)
        nonzero("v", self.v)
        ux, uy, uz = self.u
        vx, vy, vz = self.v
        cross = math.hypot(uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx)
        if cross <= 1e-12 * math.hypot(*self.u) * math.hypot(*self.v):
            raise ValueError("u and v must not be parallel")
        return self


class DiskSensor(Attachable):
    type: Literal["disk"] = Field(description="One disk answering its mean illuminance.")
    center: Vec3 = Field(description="The disk's centre [x, y, z], m.")
    normal: Vec3 = Field(description="The side that receives (any length, not zero; dimensionless).")
    radius: Positive = Field(description="The disk's radius, m.")

    model_config = ConfigDict(json_schema_extra={"examples": [DISK_SENSOR_EXAMPLE]})

    @model_validator(mode="after")
    def _check(self) -> DiskSensor:
        nonzero("normal", self.normal)
        return self


class SurfaceSensor(Wire):
    """The model's own surfaces as a sensor: the illuminance on each triangle of a node's geometry and its
    descendants' (`tracer.simulate.Simulation.surface`), on the triangles' front side (the outside of a CAD
    solid). It observes and changes nothing: the light goes on as if it were not there."""

    type: Literal["surface"] = Field(description="A node's surfaces, answering the illuminance on each triangle.")
    name: Annotated[str, StringConstraints(max_length=200)] | None = Field(None, description="A name for people.")
    node: NodeRef = Field(description="The node (UUID or path) whose surfaces, with its descendants', are tallied; "
                                      "it or a descendant must have geometry.")

    model_config = ConfigDict(json_schema_extra={"examples": [{"type": "surface", "node": "room/floor",
                                                                "name": "the floor in lux"}]})


class FarFieldSensor(Wire):
    """The scene as a lamp seen from far away (`tracer.simulate.Simulation.far_field`): the luminous intensity (cd) of
    all the light leaving the scene, binned by direction on a type-C grid (γ from `direction`, C from `c0`, as a
    goniometric light's), and the total flux leaving. The scene is taken as a point: valid where it is small against
    the viewing distance. It observes and changes nothing. Its latest result exports as an IES or EULUMDAT file
    (`GET /scenes/{id}/sensors/{sid}/export`)."""

    type: Literal["far_field"] = Field(description="A far-field intensity distribution, cd on a C-γ grid.")
    name: Annotated[str, StringConstraints(max_length=200)] | None = Field(None, description="A name for people.")
    nc: Annotated[int, Field(ge=1, le=3600)] = Field(
        description="C samples (dimensionless count): C_i = i·360°/nc, each owning ±180°/nc around it; 1 for an "
                    "axially symmetric distribution.")
    ngamma: Annotated[int, Field(ge=2, le=1801)] = Field(
        description="γ samples (dimensionless count): γ_j = j·180°/(ngamma−1) from 0° to 180°, each owning ±half a "
                    "step (the two polar caps are one bin each).")
    direction: Vec3 | None = Field(None, description="The γ = 0 axis (dimensionless, any length); default −z, "
                                                     "straight down.")
    c0: Vec3 | None = Field(None, description="The C = 0 half-plane's direction (dimensionless; its part across "
                                              "`direction` counts); default +x. C = 90° lies along c0 × direction.")
    attached_to: NodeRef | None = Field(None, description=(
        "A node (UUID or path): `direction` and `c0` are then in that node's frame and turn with it when a push "
        "moves it; default world."))

    model_config = ConfigDict(json_schema_extra={"examples": [{"type": "far_field", "name": "downlight far field",
                                                                "nc": 24, "ngamma": 37, "direction": [0.0, 0.0, -1.0],
                                                                "c0": [1.0, 0.0, 0.0]}]})

    @model_validator(mode="after")
    def _check(self) -> FarFieldSensor:
        nonzero("direction", self.direction)
        nonzero("c0", self.c0)
        if self.c0 is not None:   # a default c0 along the direction turns to +y, as for a goniometric light
            ax, ay, az = self.direction if self.direction is not None else (0.0, 0.0, -1.0)
            bx, by, bz = self.c0
            cross = math.hypot(ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx)
            if cross <= 1e-9 * math.hypot(ax, ay, az) * math.hypot(bx, by, bz):
                raise ValueError("c0 must not be parallel to direction")
        return self


Sensor = Annotated[GridSensor | DiskSensor | SurfaceSensor | FarFieldSensor, Field(discriminator="type")]


class SensorCreate(Wire):
    sensor: Sensor = Field(description="A sensor body.")
