"""The one seam between the wire and the tracer's optics: wire models made from the tracer's typed specs.

Each surface or element kind of the tracer (`tracer.optics.surfaces.dispatch.KINDS`) declares its fields
once, in its `Spec` dataclass (name, default, range in ``bounds(...)`` metadata, meaning). The material
wire models are built here from those specs, so the OpenAPI schema, the 422s and the kernels' packing
read the same table, and a new kind appears in the API with no change to the service. A field's wire
type follows its metadata's value rule: a number, a number or a table over λ (``value="spectral"``), an
index (``"ior"``: number, Sellmeier or table), or an object (``parse``: coating, fluorescence, metal, and a
dielectric's ``medium``, whose models are made the same way from the medium kinds' specs,
`tracer.optics.media.dispatch.KINDS`). Each model's validator then runs the tracer's own validation
(`material_spec`: cross-field rules, increasing wavelengths, Sellmeier poles), so both sides refuse alike. An older
body (a kind since folded into another, fields since moved) is read in today's form first (`upgrade_body`). `to_spec`
turns a validated body into the spec.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import TYPE_CHECKING, Annotated, Any, Literal, Optional, Union

from pydantic import BaseModel, BeforeValidator, ConfigDict, Discriminator, Field, Strict, create_model, model_validator

from tracer.optics import spectra
from tracer.optics.media import dispatch as media
from tracer.optics.surfaces.base import MaterialError
from tracer.optics.surfaces.dispatch import KINDS, material_spec, upgrade_body

#: examples shown by /docs, per kind (tests/service/test_openapi_docs.py assigns each to a node): BK7 is Schott's
#: Sellmeier fit, aluminium's [n, k] at 550 nm
MATERIAL_EXAMPLES: dict[str, list[dict[str, Any]]] = {
    "black": [{"type": "black"}],
    "lambertian": [{"type": "lambertian", "reflectance": 0.5},
                   {"type": "lambertian", "reflectance": {"nm": [400.0, 550.0, 700.0], "values": [0.2, 0.5, 0.7]}}],
    "mirror": [{"type": "mirror", "metal": [0.96, 6.69]}, {"type": "mirror", "reflectance": 0.9}],
    "mix": [{"type": "mix", "diffuse": 0.6, "specular": 0.3}],
    "dielectric": [{"type": "dielectric", "ior": {"sellmeier": {"b": [1.03961212, 0.231792344, 1.01046945],
                                                                "c_um2": [0.00600069867, 0.0200179144, 103.560653]}},
                    "medium": {"type": "homogeneous", "absorption_per_m": 0.1}},
                   {"type": "dielectric", "ior": 1.5, "absorption_per_m": 0.0, "scattering_per_m": 0.0, "g": 0.0},
                   {"type": "dielectric", "ior": 1.49, "coating": {"layers": [{"ior": 1.38, "thickness_nm": 99.6}]}},
                   {"type": "dielectric", "ior": 1.49, "alpha": 0.2},
                   {"type": "dielectric", "ior": 1.5, "alpha": 0.05, "alpha_y": 0.3, "axis": [1.0, 0.0, 0.0]},
                   {"type": "dielectric", "ior": 1.49, "medium": {"type": "homogeneous", "scattering_per_m": 40.0,
                                                                  "g": 0.8}}],
    "diffuser": [{"type": "diffuser", "transmittance": 0.6, "reflectance": 0.3}],
    "polarizer": [{"type": "polarizer", "axis": [1.0, 0.0, 0.0], "transmittance": 0.85, "extinction_ratio": 1000.0}],
    "retarder": [{"type": "retarder", "fast_axis": [1.0, 0.0, 0.0], "retardance_deg": 90.0}],
}
#: examples of each medium kind (a dielectric's ``medium``)
MEDIUM_EXAMPLES: dict[str, list[dict[str, Any]]] = {
    "homogeneous": [{"type": "homogeneous", "absorption_per_m": 0.5, "scattering_per_m": 20.0, "g": 0.7},
                    {"type": "homogeneous", "particles": {"radius_um": 0.5, "ior": [1.59, 0.0],
                                                          "number_per_m3": 1e15}}],
}


def _examples(schema: dict[str, Any], cls: type) -> None:
    """A material kind's examples in its JSON schema (``json_schema_extra``); other wire models have none."""
    kind = cls.model_fields["type"].annotation.__args__[0] if "type" in cls.model_fields else None  # type: ignore
    examples = MEDIUM_EXAMPLES if issubclass(cls, _MediumWire) else MATERIAL_EXAMPLES
    if kind in examples:
        schema["examples"] = examples[kind]


class _MaterialWire(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, json_schema_extra=_examples)


class _MediumWire(_MaterialWire):
    """The base of the medium kinds' wire models (a dielectric's ``medium``)."""


# ------------------------------------------------------------------------ values that may vary with λ

Wavelength = Annotated[float, Field(ge=spectra.LAMBDA_MIN, le=spectra.LAMBDA_MAX, description="nm")]
Samples = Annotated[list[Annotated[float, Strict()]], Field(min_length=2, max_length=10_000)]


class SpectralTable(_MaterialWire):
    """A value sampled over wavelength: linear between the samples, the end values held beyond them."""

    nm: Annotated[list[Wavelength], Field(min_length=2, max_length=10_000, description="increasing, nm")]
    values: Samples = Field(description="the value at each wavelength, in the field's own unit (a fraction for a "
                                        "reflectance, 1/m for a coefficient)")


class SellmeierTerms(_MaterialWire):
    b: Annotated[list[Annotated[float, Strict()]], Field(min_length=1, max_length=6, description=(
        "the oscillator strengths B, dimensionless (BK7: 1.03961212, 0.231792344, 1.01046945)"))]
    c_um2: Annotated[list[Annotated[float, Strict()]], Field(min_length=1, max_length=6, description="µm²")]


class Sellmeier(_MaterialWire):
    """n² = 1 + Σ b λ² / (λ² − c), λ in µm."""

    sellmeier: SellmeierTerms = Field(description="the Sellmeier terms: B (dimensionless) and C (µm²), one per pole")


class IndexTable(_MaterialWire):
    nm: Annotated[list[Wavelength], Field(min_length=2, max_length=10_000, description="increasing, nm")]
    n: Samples = Field(description="the refractive index at each wavelength, dimensionless")


class IorTable(_MaterialWire):
    table: IndexTable = Field(description="the refractive index sampled over wavelength (nm)")


class CoatingLayer(_MaterialWire):
    ior: Annotated[float, Strict(), Field(ge=1.0, le=5.0, description="the film's refractive index")]
    thickness_nm: Annotated[float, Strict(), Field(ge=0.0, le=1e5, description="physical thickness, nm")]


class CoatingWire(_MaterialWire):
    """Thin films on the surface, outermost first (`tracer.optics.coating`)."""

    layers: Annotated[list[CoatingLayer], Field(min_length=1, max_length=200, description=(
        "the films, outermost first: each its index (dimensionless) and thickness (nm)"))]


class Monochromatic(_MaterialWire):
    type: Literal["monochromatic"] = Field(description="one wavelength")
    nm: Wavelength


class Blackbody(_MaterialWire):
    type: Literal["blackbody"] = Field(description="Planck's law at a temperature")
    kelvin: Annotated[float, Field(ge=100.0, le=1e5, description="K")]


class SpectrumTable(_MaterialWire):
    """Relative spectral power, linear between the samples, zero outside them."""

    type: Literal["table"] = Field(description="a sampled spectrum")
    nm: Annotated[list[Wavelength], Field(min_length=2, max_length=10_000, description="increasing, nm")]
    values: Annotated[list[Annotated[float, Field(ge=0.0)]], Field(min_length=2, max_length=10_000, description=(
        "relative spectral power at each wavelength (any scale: the light's own magnitude sets it)"))]


Spectrum = Annotated[Monochromatic | Blackbody | SpectrumTable, Field(discriminator="type")]


class FluorescenceWire(_MaterialWire):
    """Absorption by spectrum and isotropic re-emission (`tracer.optics.media.fluorescence`)."""

    absorption_per_m: Annotated[float, Strict(), Field(ge=0.0, le=1e9)] | SpectralTable = Field(
        description="fluorescent absorption coefficient σf, 1/m (or a table over λ)")
    quantum_yield: Annotated[float, Strict(), Field(ge=0.0, le=1.0, description="photons out per photon in")]
    emission: Spectrum = Field(description="the spectrum of the re-emitted light (relative power over nm)")


Metal = Annotated[tuple[Annotated[float, Strict(), Field(gt=0.0, le=20.0)],
                        Annotated[float, Strict(), Field(ge=0.0, le=50.0)]],
                  Field(description="the metal's complex index [n, k] (n − ik), e.g. aluminium at 550 nm [0.96, 6.69]")]
class ParticlesWire(_MaterialWire):
    """Spheres suspended in the dielectric: Mie scattering and absorption at each wavelength (`tracer.optics.mie`)."""

    radius_um: Annotated[float, Strict(), Field(ge=1e-4, le=1000.0, description="sphere radius, µm")]
    ior: Annotated[tuple[Annotated[float, Strict(), Field(gt=0.0, le=10.0)],
                         Annotated[float, Strict(), Field(ge=0.0, le=10.0)]],
                   Field(description="the spheres' complex index [n, k] (n − ik); relative to the host's ior")]
    number_per_m3: Annotated[float, Strict(), Field(gt=0.0, le=1e30, description="number density, 1/m³")]


Axis = Annotated[tuple[Annotated[float, Strict()], Annotated[float, Strict()], Annotated[float, Strict()]],
                 Field(description="a direction [x, y, z] in the node's frame, in the sheet's plane; not zero")]
Angles = Annotated[list[float], Field(min_length=1, max_length=1000)]


class BrdfTableWire(_MaterialWire):
    """An isotropic BRDF as a goniophotometer measures it (`tracer.optics.surfaces.measured_brdf`)."""

    theta_i_deg: Angles = Field(description="incidence angles measured, strictly increasing in [0, 90), degrees")
    theta_o_deg: Angles = Field(description="outgoing polar bin edges, strictly increasing from 0 to 90, degrees")
    dphi_deg: Angles = Field(description="azimuth-difference bin edges from 0 (towards the source) to 180 "
                                         "(the specular side), strictly increasing, degrees")
    brdf: list[list[list[float]]] = Field(description="[n_i][n_o][n_p] BRDF values, sr⁻¹, ≥ 0; each θi row's "
                                                      "directional albedo at most 1")


BrdfTable = BrdfTableWire | Annotated[str, Field(max_length=20_000_000, description=(
    "the text of a table file (format: `tracer.optics.surfaces.measured_brdf`)"))]
FileId = Annotated[str, Field(pattern=r"^[0-9a-f]{64}$", description=(
    "an uploaded file's id (POST /optical-files): the SHA-256 of its bytes, 64 lowercase hex digits"))]
_OBJECTS: dict[str, Any] = {"coating": CoatingWire, "fluorescence": FluorescenceWire, "metal": Metal, "axis": Axis,
                            "fast_axis": Axis, "particles": ParticlesWire, "table": BrdfTable, "file": FileId}


def _number(meta: Mapping) -> Any:
    limits = {("gt" if meta["lo_open"] else "ge"): meta["lo"], ("lt" if meta["hi_open"] else "le"): meta["hi"]}
    return Annotated[float, Strict(), Field(description=meta.get("doc") or None, **limits)]


def _field_type(name: str, meta: Mapping, required: bool) -> Any:
    """The wire type of one spec field, by the value rule its metadata names (`tracer.optics.surfaces.base`)."""
    if "parse" in meta:
        return _OBJECTS[name] if required else Optional[_OBJECTS[name]]  # noqa: UP045 (a runtime type)
    if meta["value"] == "spectral":
        return _number(meta) | SpectralTable
    if meta["value"] == "ior":
        return _number(meta) | Sellmeier | IorTable
    return _number(meta)


def _model(kind, family: str = "material") -> type[BaseModel]:
    """The pydantic model of one kind's wire body, from its spec's fields (`family`: ``"material"`` or
    ``"medium"``)."""
    fields: dict[str, Any] = {"type": (Literal[kind.NAME], Field(description=f"the {family} kind: `{kind.NAME}`"))}
    for f in dataclasses.fields(kind.Spec):
        default = ... if f.default is dataclasses.MISSING else f.default
        # the spec's meaning (with its unit) on the field itself, where /docs shows it, not only inside a union
        fields[f.name] = (_field_type(f.name, f.metadata, default is ...),
                          Field(default, description=f.metadata.get("doc") or None))

    def _check(self):
        # the tracer's own validation: cross-field rules (`Spec.check`), increasing wavelengths, Sellmeier poles
        try:
            if family == "medium":
                media.medium_spec(self.model_dump(exclude_none=True))
            else:
                material_spec(self.model_dump(exclude_none=True))
        except MaterialError as exc:
            raise ValueError(str(exc).removeprefix("material: ")) from None
        return self

    doc = (kind.__doc__ or kind.NAME).strip().split("\n\n")[0]
    validators: dict[str, Any] = {"_check": model_validator(mode="after")(_check)}
    name = kind.NAME.title().replace("_", "") + ("Medium" if family == "medium" else "")
    return create_model(name, __base__=_MediumWire if family == "medium" else _MaterialWire, __doc__=doc,
                        __validators__=validators, **fields)


def _todays_form(body: Any) -> Any:
    """An older material body read in today's form (`upgrade_body`); what is wrong with it, a 422."""
    try:
        return upgrade_body(body)
    except MaterialError as exc:
        raise ValueError(str(exc).removeprefix("material: ")) from None


MEDIUM_MODELS = tuple(_model(kind, "medium") for kind in media.KINDS)
if TYPE_CHECKING:
    MediumWire = _MediumWire
else:
    MediumWire = Annotated[Union[MEDIUM_MODELS], Field(discriminator="type", description=(  # noqa: UP007
        "what fills the solid, a medium kind (`tracer/optics/media/`)"))]
_OBJECTS["medium"] = MediumWire
MATERIAL_MODELS = tuple(_model(kind) for kind in KINDS)
if TYPE_CHECKING:  # the models are made at import: to a type checker a material is a wire model
    Material = _MaterialWire
else:
    # `Discriminator`, not `Field(discriminator=)`: FastAPI takes a `Field` off a body parameter's type, and the
    # older body must be read in today's form before the union picks its kind
    Material = Annotated[Union[MATERIAL_MODELS], Discriminator("type"),  # noqa: UP007 (a runtime tuple)
                         BeforeValidator(_todays_form)]


def to_spec(body: dict) -> Any:
    """The tracer's typed spec of a validated material body."""
    return material_spec({k: v for k, v in body.items() if v is not None})
