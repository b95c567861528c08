"""The wire's building blocks: value types (vectors, ids, node references, bounded numbers), the `Wire` base that
forbids unknown fields and non-finite numbers, and the placed-and-spectral bases of lights and sensors.
`service.schemas` and the wire models made from the tracer's kinds (`service.optics`, `service.kind_wire`) build on
these.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, Strict, StringConstraints

from service import optics
from service.paths import NODE_REF_PATTERN, is_uuid

UUID_PATTERN = r"^[0-9a-fA-F]{8}-[0-9a-fA-F]{4}-[0-9a-fA-F]{4}-[0-9a-fA-F]{4}-[0-9a-fA-F]{12}$"
GEOMETRY_PATTERN = r"^[0-9a-f]{64}$"

Uuid = Annotated[str, StringConstraints(pattern=UUID_PATTERN, to_lower=True)]
GeometryId = Annotated[str, StringConstraints(pattern=GEOMETRY_PATTERN)]
#: a node by its UUID or by its path (`service.paths`); the route resolves a path to the UUID, which is stored
NodeRef = Annotated[str, StringConstraints(pattern=NODE_REF_PATTERN),
                    AfterValidator(lambda s: s.lower() if is_uuid(s) else s),
                    Field(description="a node's UUID, or its path (names from the root joined by `/`, "
                                      "`name[2]` for the second sibling of that name; `GET /scenes/{id}/nodes`)")]
Num = Annotated[float, Strict()]  # a JSON number (an integer is fine; a boolean or a string is not)
Vec3 = tuple[Num, Num, Num]
Matrix16 = Annotated[list[Num], Field(min_length=16, max_length=16)]
Fraction = Annotated[float, Strict(), Field(ge=0.0, le=1.0)]
NonNegative = Annotated[float, Field(ge=0.0)]
# A photometric magnitude (cd, lm, lx, lm/m²): beyond 1e15 it is a unit mistake, and a light's flux is held to
# the tracer's `MAX_FLUX_LM` when a query packs it.
Photometric = Annotated[float, Field(ge=0.0, le=1e15)]
Positive = Annotated[float, Field(gt=0.0)]

# metres per unit, for the document's declared length unit
LENGTH_UNITS: dict[str, float] = {"m": 1.0, "cm": 0.01, "mm": 0.001, "um": 1e-6, "in": 0.0254, "ft": 0.3048}
LengthUnit = Literal["m", "cm", "mm", "um", "in", "ft"]


class Wire(BaseModel):
    """Base of every wire model: unknown fields rejected, NaN and infinities rejected."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


def nonzero(name: str, v: Vec3 | None) -> None:
    """A `ValueError` (a 422 in a validator) where the vector `v` is given and zero."""
    if v is not None and math.hypot(*v) == 0.0:
        raise ValueError(f"{name} must be a non-zero vector")



class LinearPolarization(Wire):
    type: Literal["linear"] = Field(description="Linearly polarized.")
    axis: Vec3 = Field(description="the field's direction (in the light's frame: world, or its node's with "
                                   "attached_to), taken across each ray")


class CircularPolarization(Wire):
    type: Literal["circular"] = Field(description="Circularly polarized.")
    handedness: Literal["right", "left"] = Field(description="right: S3 = +S0 (IEEE: clockwise seen from the source)")


class Spectral(Wire):
    """A light's spectrum and polarization (their rules beyond the schema, increasing nm, some power, a non-zero
    axis, are the tracer's: `tracer.optics.lights.dispatch.light_spec` runs them in each light model's check)."""

    spectrum: optics.Spectrum | None = Field(
        default=None, description="The light's relative spectral power; default equal energy over 380–780 nm.")
    polarization: Annotated[LinearPolarization | CircularPolarization, Field(discriminator="type")] | None = Field(
        default=None, description="The light's polarization (`tracer.optics.polarization`); default unpolarized.")


class Attachable(Spectral):
    """Placed in the world, or in a node's frame (``attached_to``)."""

    name: Annotated[str, StringConstraints(max_length=200)] | None = Field(None, description="A name for people.")
    attached_to: NodeRef | None = Field(None, description=(   # then positions/directions are in that node's frame
        "A node (UUID or path): positions and directions are then in that node's frame, in metres, and follow it "
        "when a push moves it; default world."))
