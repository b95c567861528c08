"""Wire schemas: one pydantic model per role (``…Create`` what a client sends, ``…Public`` what it gets).

Every model forbids unknown fields (a misspelt field is an error, never silently ignored) and
accepts finite numbers only. Lengths are metres unless a field says otherwise; a document's
node transforms are in the document's own ``length_unit``. Checks that need more than one
field (non-zero directions, reflectance ≤ 1, …) live in validators here; checks that need
the whole tree (cycles, parents, invertibility) live in `service.tree`.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, Strict, StringConstraints, model_validator

from service import optics
from service.paths import NODE_REF_PATTERN, is_uuid
from tracer.optics import spectra
from tracer.optics.polarization import PolarizationError, light_polarization

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


def _nonzero(name: str, v: Vec3 | None) -> None:
    if v is not None and math.hypot(*v) == 0.0:
        raise ValueError(f"{name} must be a non-zero vector")


# ---------------------------------------------------------------- scenes

class SceneCreate(Wire):
    """Body of ``POST /scenes``."""

    name: Annotated[str, StringConstraints(min_length=1, max_length=200, strip_whitespace=True)]


class OrphanPublic(Wire):
    """An assignment whose node a push removed: kept, and live again if the UUID comes back."""

    kind: Literal["material", "light", "sensor", "object"]
    id: str  # the node uuid for a material, else the light/sensor/object id
    node: str  # the missing node


class ScenePublic(Wire):
    """What ``GET /scenes/{id}`` answers (DESIGN.md), plus a few counts."""

    id: str
    name: str
    revision: int
    length_unit: str | None
    nodes: int
    objects: int  # instances in the tracer scene (document parts and sim-owned objects)
    triangles: int
    geometries: int
    effects: list[str]
    orphaned: list[OrphanPublic]
    materials_assigned: int  # explicit assignments (live ones)
    default_material: dict[str, Any]
    default_material_instances: int  # instances that fall back to the default material
    lights: int
    sensors: int
    sim_objects: int
    last_commit: dict[str, Any]  # what the last tracer commit in this process built or loaded
    source: dict[str, Any] | None = None  # the last push's source: document name, tessellation settings


class SceneListItem(Wire):
    id: str
    name: str
    revision: int


# ---------------------------------------------------------------- the pushed document

class Source(Wire):
    """Where a push came from: the document's name and the tessellation settings (bounded: it is stored with
    every revision)."""

    name: Annotated[str, StringConstraints(max_length=1000)] | None = None
    tessellation: Annotated[dict[Annotated[str, StringConstraints(max_length=100)],
                                 float | bool | Annotated[str, StringConstraints(max_length=100_000)] | None],
                            Field(max_length=64)] | None = None


class NodeIn(Wire):
    """One node of a pushed tree: parent link, local transform (row-major 4×4, document units)."""

    uuid: Uuid
    parent: Uuid | None = None
    name: Annotated[str, StringConstraints(max_length=500)] = ""
    transform: Matrix16
    geometry: GeometryId | None = None
    color: tuple[Fraction, Fraction, Fraction] | None = None


NonNegNum = Annotated[float, Strict(), Field(ge=0.0)]  # a finite JSON number >= 0 (no boolean, no string)
Count = Annotated[int, Strict(), Field(ge=0)]


class Signature(Wire):
    """A part's frame-independent shape signature, as the CAD adapter measures it on the B-rep.

    ``moments`` are the principal moments of inertia about the centroid (unit density), sorted
    ascending, in document units⁵; ``centroid`` and ``axes`` (the principal axes as three rows,
    ``None`` where they are not well defined) are in the part's own frame, document units.
    """

    volume: NonNegNum
    area: NonNegNum
    moments: Annotated[list[NonNegNum], Field(min_length=3, max_length=3)]
    centroid: Annotated[list[Num], Field(min_length=3, max_length=3)]
    axes: Annotated[list[Num], Field(min_length=9, max_length=9)] | None = None
    topology: Annotated[list[Count], Field(min_length=3, max_length=3)] | None = None  # faces, edges, vertices

    @model_validator(mode="after")
    def _sorted(self) -> Signature:
        m = self.moments
        if not m[0] <= m[1] <= m[2]:
            raise ValueError(f"moments must be sorted ascending, got {m}")
        return self


class IdentityIn(Wire):
    """What the adapter matches a node by, besides its tree: the product it instantiates and its shape signature."""

    product: Annotated[str, StringConstraints(max_length=500)] | None = None
    signature: Signature | None = None


class AmbiguousNode(Wire):
    """A node the adapter could not match with certainty: the candidates it hesitated between, and why."""

    uuid: Uuid
    path: str
    candidates: list[Uuid]
    reason: str


class Reconciliation(Wire):
    """The adapter's report of how it matched the document against the scene; the service only
    validates it and echoes it in the push answer."""

    matched: dict[str, Count] = Field(default_factory=dict)  # rule name -> nodes matched by it
    ambiguous: list[AmbiguousNode] = Field(default_factory=list)
    seconds: NonNegNum | None = None
    source: str | None = None


class DocumentPush(Wire):
    """Body of ``PUT /scenes/{id}/document``.

    ``base_revision`` is the revision the client's tree is based on: a stale one gets 409
    (unless the pushed tree equals the current one, which is then a 200 no-op, so a retried
    push is harmless). Omitted or null: push unconditionally.

    ``identity`` maps node uuids of this push to their identity records (product name, shape
    signature); every key must be a node of this push (else 422). It is the whole set: a node
    without an entry has no record afterwards, and omitting ``identity`` (or null) clears them
    all. Records are not part of the tree: a push that changes only them stores them without a
    new revision (also with a stale ``base_revision``, as the tree is the current one).
    ``reconciliation`` is echoed in the answer. Clients put both before ``nodes``, which stays
    the body's last member (`service.document` reuses the node bytes of the previous push).
    """

    base_revision: Annotated[int, Strict(), Field(ge=0)] | None = None   # strict: not true, "2" or 3.0
    length_unit: LengthUnit = "m"
    source: Source | None = None
    identity: dict[Uuid, IdentityIn] | None = None
    reconciliation: Reconciliation | None = None
    nodes: list[NodeIn]


class StageSeconds(Wire):
    validate_: float = Field(alias="validate")
    diff: float
    blas: float
    tlas: float
    store: float
    total: float

    model_config = ConfigDict(extra="forbid", populate_by_name=True)


class PushPublic(Wire):
    """The answer to a push: the diff by UUID, what was rebuilt, and the seconds of each stage.

    A dry run (``?dry_run=true``) answers the same diff without changing anything: ``revision``
    is the current one, ``orphaned``/``restored`` are the assignments the push would orphan or
    restore, ``blas_built`` is 0, and it adds ``blas_to_build`` (geometry ids the scene's tracer
    does not hold yet) and ``missing_geometries`` (ids not uploaded yet: no error in a dry run).
    """

    scene: str
    revision: int
    base_revision: int | None
    added: list[str]
    removed: list[str]
    moved: list[str]
    geometry_changed: list[str]
    renamed: list[str]
    reparented: list[str]
    recolored: list[str]
    unchanged: int
    blas_built: int
    blas_reused: int
    blas_loaded: int
    instances: int
    seconds: dict[str, float]
    orphaned: list[OrphanPublic]
    restored: list[OrphanPublic]
    reconciliation: Reconciliation | None = None  # the push's, echoed
    dry_run: bool = False
    blas_to_build: list[str] | None = None  # dry runs only
    missing_geometries: list[str] | None = None  # dry runs only


# ---------------------------------------------------------------- geometries

class MissingQuery(Wire):
    """Body of ``POST /geometries/missing``."""

    ids: Annotated[list[GeometryId], Field(max_length=1_000_000)]


class MissingPublic(Wire):
    missing: list[str]


class GeometryPublic(Wire):
    id: str
    vertices: int
    triangles: int
    normals: bool
    bytes: int
    created: bool  # False when the mesh was already stored (idempotent upload)


# ---------------------------------------------------------------- materials (DESIGN.md bodies)

# Material bodies are made from the tracer's typed specs, in one place: `service.optics`.
Material = optics.Material


class MaterialAssignment(Wire):
    """Wrapper used only to validate a material body (the body itself is the material)."""

    material: Material


class MaterialPublic(Wire):
    node: str
    material: dict[str, Any]
    orphaned: bool


# ---------------------------------------------------------------- lights (DESIGN.md bodies)

class LinearPolarization(Wire):
    type: Literal["linear"]
    axis: Vec3 = Field(description="the field's direction (in the light's frame: world, or its node's with "
                                   "attached_to), taken across each ray")


class CircularPolarization(Wire):
    type: Literal["circular"]
    handedness: Literal["right", "left"] = Field(description="right: S3 = +S0 (IEEE: clockwise seen from the source)")


class _Spectral(Wire):
    spectrum: optics.Spectrum | None = Field(
        default=None, description="The light's relative spectral power; default equal energy over 380–780 nm.")
    polarization: Annotated[LinearPolarization | CircularPolarization, Field(discriminator="type")] | None = Field(
        default=None, description="The light's polarization (`tracer.optics.polarization`); default unpolarized.")

    @model_validator(mode="after")
    def _spectrum(self) -> _Spectral:
        if self.spectrum is not None:   # the tracer's rules beyond the schema: increasing nm, some power
            try:
                spectra.spectrum(self.spectrum.model_dump(), "spectrum")
            except spectra.SpectrumError as exc:
                raise ValueError(str(exc)) from None
        if self.polarization is not None:   # the tracer's rules beyond the schema: a non-zero axis
            try:
                light_polarization(self.polarization.model_dump(), "light")
            except PolarizationError as exc:
                raise ValueError(str(exc).removeprefix("light: ")) from None
        return self


class _Attachable(_Spectral):
    name: Annotated[str, StringConstraints(max_length=200)] | None = None
    attached_to: NodeRef | None = None  # then positions/directions are in that node's frame, metres


class _Intensity(_Attachable):
    intensity_cd: Photometric | None = None
    flux_lm: Photometric | None = None
    flux_w: Annotated[float, Field(ge=0.0, le=1e13, description=(
        "radiant flux, W (instead of a photometric quantity; lm = W × the spectrum's efficacy)"))] | None = None

    @model_validator(mode="after")
    def _one_of(self) -> _Intensity:
        if sum(v is not None for v in (self.intensity_cd, self.flux_lm, self.flux_w)) != 1:
            raise ValueError("give exactly one of intensity_cd, flux_lm and flux_w")
        return self


class PointLight(_Intensity):
    type: Literal["point"]
    position: Vec3


class SpotLight(_Intensity):
    type: Literal["spot"]
    position: Vec3
    direction: Vec3
    cone_deg: Annotated[float, Field(gt=0.0, le=180.0)]
    falloff_deg: Annotated[float, Field(ge=0.0, le=180.0)] = 0.0

    @model_validator(mode="after")
    def _check(self) -> SpotLight:
        _nonzero("direction", self.direction)
        if self.falloff_deg > self.cone_deg:
            raise ValueError(f"falloff_deg ({self.falloff_deg}) must not exceed cone_deg ({self.cone_deg})")
        return self


class CollimatedLight(_Attachable):
    """A parallel beam from an aperture centred on `origin`: a disk (`radius`) or a rectangle
    (`width` × `height`, its height along `up` projected off the direction)."""

    type: Literal["collimated"]
    origin: Vec3
    direction: Vec3
    radius: Positive | None = None
    width: Positive | None = None
    height: Positive | None = None
    up: Vec3 | None = None
    illuminance_lx: Photometric

    @model_validator(mode="after")
    def _check(self) -> CollimatedLight:
        _nonzero("direction", self.direction)
        rect = self.width is not None or self.height is not None
        if (self.radius is None) == (not rect) or (rect and (self.width is None or self.height is None)):
            raise ValueError("give either radius (a disk aperture) or width and height (a rectangle)")
        if self.up is not None:
            if not rect:
                raise ValueError("up orients a rectangular aperture; a disk has none")
            _nonzero("up", self.up)
            dx, dy, dz = self.direction
            ux, uy, uz = self.up
            cross = math.hypot(dy * uz - dz * uy, dz * ux - dx * uz, dx * uy - dy * ux)
            if cross <= 1e-9 * math.hypot(*self.direction) * math.hypot(*self.up):
                raise ValueError("up must not be parallel to direction")
        return self


class AreaLight(_Spectral):
    type: Literal["area"]
    name: Annotated[str, StringConstraints(max_length=200)] | None = None
    node: NodeRef  # the node whose surfaces (with its descendants') emit
    exitance_lm_m2: Photometric


class GoniometricLight(_Attachable):
    """A type-C photometric file; `direction` is its γ = 0 axis (default straight down, −z) and `c0`
    its C = 0 half-plane (default +x); both turn with the node the light is attached to."""

    type: Literal["goniometric"]
    position: Vec3
    format: Literal["ies", "ldt"]
    data: Annotated[str, StringConstraints(min_length=1, max_length=10_000_000)]
    direction: Vec3 | None = None
    c0: Vec3 | None = None

    @model_validator(mode="after")
    def _check(self) -> GoniometricLight:
        _nonzero("direction", self.direction)
        _nonzero("c0", self.c0)
        if self.direction is not None and self.c0 is not None:
            (ax, ay, az), (bx, by, bz) = self.direction, self.c0
            cross = math.hypot(ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx)
            if cross <= 1e-9 * math.hypot(ax, ay, az) * math.hypot(bx, by, bz):
                raise ValueError("c0 must not be parallel to direction")
        return self


Light = Annotated[PointLight | SpotLight | CollimatedLight | AreaLight | GoniometricLight, Field(discriminator="type")]


class LightCreate(Wire):
    light: Light


# ---------------------------------------------------------------- sensors

class GridSensor(_Attachable):
    """A rectangle ``origin + s·u + t·v`` (s, t in [0, 1]) split into nu × nv cells; front side u × v."""

    type: Literal["grid"]
    origin: Vec3
    u: Vec3
    v: Vec3
    nu: Annotated[int, Field(ge=1, le=4096)]
    nv: Annotated[int, Field(ge=1, le=4096)]

    @model_validator(mode="after")
    def _check(self) -> GridSensor:
        _nonzero("u", self.u)
        _nonzero("v", self.v)
        ux, uy, uz = self.u
        vx, vy, vz = self.v
        cross = math.hypot(uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx)
        if cross <= 1e-12 * math.hypot(*self.u) * math.hypot(*self.v):
            raise ValueError("u and v must not be parallel")
        return self


class DiskSensor(_Attachable):
    type: Literal["disk"]
    center: Vec3
    normal: Vec3
    radius: Positive

    @model_validator(mode="after")
    def _check(self) -> DiskSensor:
        _nonzero("normal", self.normal)
        return self


Sensor = Annotated[GridSensor | DiskSensor, Field(discriminator="type")]


class SensorCreate(Wire):
    sensor: Sensor


# ---------------------------------------------------------------- simulation-owned objects

class ObjectCreate(Wire):
    """A library object owned by the simulation: a stored mesh placed by a transform; pushes never touch it.

    ``transform`` (row-major 4×4) is ``world_from_object`` in metres, or ``node_from_object`` when
    ``attached_to`` names a node; the mesh vertices are in ``mesh_unit``.
    """

    geometry: GeometryId
    transform: Matrix16 = Field(default_factory=lambda: [1.0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1])
    mesh_unit: LengthUnit = "m"
    name: Annotated[str, StringConstraints(max_length=200)] | None = None
    attached_to: NodeRef | None = None
    material: Material | None = None


class AssignmentPublic(BaseModel):
    """A stored light, sensor or object: its id, its body as given, and whether it is orphaned."""

    model_config = ConfigDict(extra="forbid")

    id: str
    body: dict[str, Any]
    orphaned: bool
