"""The one seam between the wire and the tracer's optics: wire models made from the tracer's typed specs.

Each surface or element kind of the tracer (`tracer.optics.surfaces.dispatch.KINDS`) declares its fields
once, in its `Spec` dataclass (name, default, range in ``bounds(...)`` metadata, meaning). The material
wire models are built here from those specs, so the OpenAPI schema, the 422s and the kernels' packing
read the same table, and a new kind appears in the API with no change to the service. A model's
cross-field rule is the spec's own ``check()``. `to_spec` turns a validated body into the typed spec.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import TYPE_CHECKING, Annotated, Any, Literal, Union

from pydantic import BaseModel, ConfigDict, Field, Strict, create_model, model_validator

from tracer.optics.surfaces.dispatch import KINDS, material_spec


class _MaterialWire(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


def _number(meta: Mapping) -> Any:
    limits = {("gt" if meta["lo_open"] else "ge"): meta["lo"], ("lt" if meta["hi_open"] else "le"): meta["hi"]}
    return Annotated[float, Strict(), Field(description=meta.get("doc") or None, **limits)]


def _model(kind) -> type[BaseModel]:
    """The pydantic model of one kind's wire body, from its spec's fields."""
    fields: dict[str, Any] = {"type": (Literal[kind.NAME], ...)}
    for f in dataclasses.fields(kind.Spec):
        default = ... if f.default is dataclasses.MISSING else f.default
        fields[f.name] = (_number(f.metadata), default)

    def _check(self):
        spec = kind.Spec(**{f.name: getattr(self, f.name) for f in dataclasses.fields(kind.Spec)})
        problem = spec.check() if hasattr(spec, "check") else None
        if problem:
            raise ValueError(problem)
        return self

    doc = (kind.__doc__ or kind.NAME).strip().split("\n\n")[0]
    validators: dict[str, Any] = {"_check": model_validator(mode="after")(_check)}
    return create_model(kind.NAME.title().replace("_", ""), __base__=_MaterialWire, __doc__=doc,
                        __validators__=validators, **fields)


MATERIAL_MODELS = tuple(_model(kind) for kind in KINDS)
if TYPE_CHECKING:  # the models are made at import: to a type checker a material is a wire model
    Material = _MaterialWire
else:
    Material = Annotated[Union[MATERIAL_MODELS], Field(discriminator="type")]  # noqa: UP007 (a runtime tuple)


def to_spec(body: dict) -> Any:
    """The tracer's typed spec of a validated material body."""
    return material_spec(body)
