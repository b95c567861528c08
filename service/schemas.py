"""Wire schemas: one pydantic model per role (``…Create`` what a client sends, ``…Public`` what it gets).

Every model forbids unknown fields (a misspelt field is an error, never silently ignored) and
accepts finite numbers only. Lengths are metres unless a field says otherwise; a document's
node transforms are in the document's own ``length_unit``. Checks that need more than one
field live in the tracer and run in the models' validators (materials: `service.optics`; lights and
sensors: `service.kind_wire`); checks that need the whole tree (cycles, parents, invertibility) live in `service.tree`.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, Strict, StringConstraints, model_validator

from service import kind_wire, optics
from service.wire import (  # noqa: F401 (the wire's names, here as before)
    GEOMETRY_PATTERN,
    LENGTH_UNITS,
    UUID_PATTERN,
    Attachable,
    CircularPolarization,
    Fraction,
    GeometryId,
    LengthUnit,
    LinearPolarization,
    Matrix16,
    NodeRef,
    NonNegative,
    Num,
    Photometric,
    Positive,
    Spectral,
    Uuid,
    Vec3,
    Wire,
    nonzero,
)
from tracer.sensors import disk as sensor_disk
from tracer.sensors import grid as sensor_grid

# ---------------------------------------------------------------- examples shown by /docs and /redoc

# One plausible scene behind every example: a room whose floor is a 4 m × 4 m mesh at z = 0 (node `room/floor`,
# its corner at (-2, -2, 0)), a ceiling panel (`room/ceiling_panel`) and a car headlamp lens (`car/lens`).
# tests/service/test_openapi_docs.py sends each example to a service holding that scene.
EXAMPLE_FLOOR_GEOMETRY = "f4a4f688dfc96096e3ccecf720e75bc783e5bf6d2afab5296004b62c64ad0fef"  # the 4 m floor's GLB
_IDENTITY = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]
DOCUMENT_EXAMPLE: dict[str, Any] = {
    "base_revision": 0, "length_unit": "m",
    "source": {"name": "room.FCStd", "tessellation": {"linear_deflection_m": 0.001, "angular_deflection_deg": 15.0}},
    "nodes": [
        {"uuid": "6f1c9a52-3b7e-4d08-9e2a-51c4b7d3e001", "name": "room", "transform": _IDENTITY},
        {"uuid": "6f1c9a52-3b7e-4d08-9e2a-51c4b7d3e002", "parent": "6f1c9a52-3b7e-4d08-9e2a-51c4b7d3e001",
         "name": "floor", "transform": [1.0, 0.0, 0.0, -2.0, 0.0, 1.0, 0.0, -2.0, 0.0, 0.0, 1.0, 0.0,
                                        0.0, 0.0, 0.0, 1.0],
         "geometry": EXAMPLE_FLOOR_GEOMETRY, "color": [0.6, 0.6, 0.6]}]}
# the kinds' own examples (`EXAMPLE` in each tracer kind module), by the names the tests and docs use
GRID_SENSOR_EXAMPLE: dict[str, Any] = sensor_grid.EXAMPLE
DISK_SENSOR_EXAMPLE: dict[str, Any] = sensor_disk.EXAMPLE


# ---------------------------------------------------------------- scenes

class SceneCreate(Wire):
    """Body of ``POST /scenes``."""

    name: Annotated[str, StringConstraints(min_length=1, max_length=200, strip_whitespace=True)] = Field(
        description="The scene's name, unique in this service (1–200 characters, outer spaces dropped).")

    model_config = ConfigDict(json_schema_extra={"examples": [{"name": "headlamp-test-bench"}]})


class OrphanPublic(Wire):
    """An assignment whose node a push removed: kept, and live again if the UUID comes back."""

    kind: Literal["material", "light", "sensor", "object"] = Field(description="What the assignment is.")
    id: str = Field(description="The node UUID for a material, else the light's, sensor's or object's id.")
    node: str = Field(description="The UUID of the node the push removed.")


class ScenePublic(Wire):
    """What ``GET /scenes/{id}`` answers (docs/DESIGN.md), plus a few counts."""

    id: str = Field(description="The scene's id (a UUID).")
    name: str = Field(description="The scene's name.")
    revision: int = Field(description="The scene revision: 0 when empty, +1 per push that changed the tree.")
    length_unit: str | None = Field(description="The last pushed document's length unit (m, cm, mm, um, in, ft); "
                                                "null before the first push.")
    nodes: int = Field(description="Nodes in the current tree.")
    objects: int = Field(description="Instances in the tracer scene (document parts and simulation-owned objects).")
    triangles: int = Field(description="Triangles over all instances.")
    geometries: int = Field(description="Distinct meshes the instances use.")
    effects: list[str] = Field(description="The physical effects the scene calls for (e.g. `refraction`, "
                                           "`spectral`), the tracer's names.")
    orphaned: list[OrphanPublic] = Field(description="Assignments whose node a push removed.")
    materials_assigned: int = Field(description="Explicit material assignments that are live.")
    default_material: dict[str, Any] = Field(description="The material of instances that have none (a material "
                                                         "body, e.g. Lambertian with reflectance 0.5, a fraction).")
    default_material_instances: int = Field(description="Instances that fall back to the default material.")
    lights: int = Field(description="Live lights.")
    sensors: int = Field(description="Live sensors.")
    sim_objects: int = Field(description="Simulation-owned objects (`POST …/objects`).")
    last_commit: dict[str, Any] = Field(description="What the last tracer commit in this process built or loaded "
                                                    "(counts, and its seconds, s).")
    source: dict[str, Any] | None = Field(None, description="The last push's source: the document's name and the "
                                                            "tessellation settings (deflections in m, angles in "
                                                            "degrees, as the adapter sent them).")


class SceneListItem(Wire):
    """One scene: its id, name and revision."""

    id: str = Field(description="The scene's id (a UUID).")
    name: str = Field(description="The scene's name.")
    revision: int = Field(description="The scene revision (0 when empty).")


# ---------------------------------------------------------------- the pushed document

class Source(Wire):
    """Where a push came from: the document's name and the tessellation settings (bounded: it is stored with
    every revision)."""

    name: Annotated[str, StringConstraints(max_length=1000)] | None = Field(
        None, description="The CAD document's name or file.")
    tessellation: Annotated[dict[Annotated[str, StringConstraints(max_length=100)],
                                 float | bool | Annotated[str, StringConstraints(max_length=100_000)] | None],
                            Field(max_length=64)] | None = Field(
        None, description="The tessellation settings the adapter used, as it names them (e.g. linear_deflection_m "
                          "in m, angular_deflection_deg in degrees); stored, not interpreted.")


class NodeIn(Wire):
    """One node of a pushed tree: parent link, local transform (row-major 4×4, document units)."""

    uuid: Uuid = Field(description="The node's stable id: assignments refer to it across pushes.")
    parent: Uuid | None = Field(None, description="The parent node's UUID; null for a root.")
    name: Annotated[str, StringConstraints(max_length=500)] = Field(
        "", description="The node's name in the CAD tree (its path is made of names).")
    transform: Matrix16 = Field(description="parent_from_node, a row-major 4×4 matrix (16 numbers); its "
                                            "translation in the document's length unit.")
    geometry: GeometryId | None = Field(None, description="The SHA-256 (64 hex digits) of the node's mesh, uploaded "
                                                          "with `PUT /geometries/{gid}`; null for an assembly.")
    color: tuple[Fraction, Fraction, Fraction] | None = Field(
        None, description="The CAD colour, linear RGB fractions 0–1 (display only; materials set the optics).")


NonNegNum = Annotated[float, Strict(), Field(ge=0.0)]  # a finite JSON number >= 0 (no boolean, no string)
Count = Annotated[int, Strict(), Field(ge=0)]


class Signature(Wire):
    """A part's frame-independent shape signature, as the CAD adapter measures it on the B-rep.

    ``moments`` are the principal moments of inertia about the centroid (unit density), sorted
    ascending, in document units⁵; ``centroid`` and ``axes`` (the principal axes as three rows,
    ``None`` where they are not well defined) are in the part's own frame, document units.
    """

    volume: NonNegNum = Field(description="Volume, document units³.")
    area: NonNegNum = Field(description="Surface area, document units².")
    moments: Annotated[list[NonNegNum], Field(min_length=3, max_length=3)] = Field(
        description="Principal moments of inertia about the centroid (unit density), ascending, document units⁵.")
    centroid: Annotated[list[Num], Field(min_length=3, max_length=3)] = Field(
        description="Centroid [x, y, z] in the part's own frame, document units.")
    axes: Annotated[list[Num], Field(min_length=9, max_length=9)] | None = Field(
        None, description="The principal axes as three rows of unit vectors (dimensionless); null where not well "
                          "defined.")
    topology: Annotated[list[Count], Field(min_length=3, max_length=3)] | None = Field(
        None, description="Counts of faces, edges and vertices of the B-rep.")

    @model_validator(mode="after")
    def _sorted(self) -> Signature:
        m = self.moments
        if not m[0] <= m[1] <= m[2]:
            raise ValueError(f"moments must be sorted ascending, got {m}")
        return self


class IdentityIn(Wire):
    """What the adapter matches a node by, besides its tree: the product it instantiates and its shape signature."""

    product: Annotated[str, StringConstraints(max_length=500)] | None = Field(
        None, description="The product (part definition) the node instantiates.")
    signature: Signature | None = Field(None, description="The part's shape signature.")


class AmbiguousNode(Wire):
    """A node the adapter could not match with certainty: the candidates it hesitated between, and why."""

    uuid: Uuid = Field(description="The UUID the adapter gave the node.")
    path: str = Field(description="The node's path in the document.")
    candidates: list[Uuid] = Field(description="The scene's nodes it could have been.")
    reason: str = Field(description="Why the match was uncertain.")


class Reconciliation(Wire):
    """The adapter's report of how it matched the document against the scene; the service only
    validates it and echoes it in the push answer."""

    matched: dict[str, Count] = Field(default_factory=dict, description="Rule name → nodes matched by it.")
    ambiguous: list[AmbiguousNode] = Field(default_factory=list, description="Nodes matched with doubt.")
    seconds: NonNegNum | None = Field(None, description="Seconds the matching took, s.")
    source: str | None = Field(None, description="The adapter that matched (name and version).")


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

    base_revision: Annotated[int, Strict(), Field(ge=0)] | None = Field(   # strict: not true, "2" or 3.0
        None, description="The revision the tree is based on (stale: 409); null pushes unconditionally.")
    length_unit: LengthUnit = Field("m", description="The unit of the nodes' translations (m, cm, mm, um, in, ft).")
    source: Source | None = Field(None, description="Where the push came from (stored with the revision).")
    identity: dict[Uuid, IdentityIn] | None = Field(
        None, description="Node UUID → its identity record (product, shape signature); the whole set.")
    reconciliation: Reconciliation | None = Field(None, description="The adapter's matching report, echoed.")
    nodes: list[NodeIn] = Field(description="The whole tree, parents before children; the body's last member.")

    model_config = ConfigDict(json_schema_extra={"examples": [DOCUMENT_EXAMPLE]})


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

    scene: str = Field(description="The scene's id.")
    revision: int = Field(description="The scene revision after the push.")
    base_revision: int | None = Field(description="The push's base_revision, echoed.")
    added: list[str] = Field(description="UUIDs of the nodes added.")
    removed: list[str] = Field(description="UUIDs of the nodes removed.")
    moved: list[str] = Field(description="UUIDs of the nodes whose transform changed.")
    geometry_changed: list[str] = Field(description="UUIDs of the nodes whose mesh changed.")
    renamed: list[str] = Field(description="UUIDs of the nodes renamed.")
    reparented: list[str] = Field(description="UUIDs of the nodes given another parent.")
    recolored: list[str] = Field(description="UUIDs of the nodes whose colour changed.")
    unchanged: int = Field(description="Nodes the push left as they were.")
    blas_built: int = Field(description="Meshes whose acceleration structure (BLAS) was built.")
    blas_reused: int = Field(description="Meshes whose BLAS was already in memory.")
    blas_loaded: int = Field(description="Meshes whose BLAS was loaded from disk.")
    instances: int = Field(description="Instances in the tracer scene after the push.")
    seconds: dict[str, float] = Field(description="Seconds per stage (validate, diff, blas, tlas, store, total), s.")
    orphaned: list[OrphanPublic] = Field(description="Assignments the push orphaned.")
    restored: list[OrphanPublic] = Field(description="Orphaned assignments the push made live again.")
    restored_nodes: list[str] = Field(default_factory=list, description=(
        "UUIDs among `added` of nodes the scene had removed and remembered (`GET /scenes/{id}/removed-nodes`): "
        "they came back, with the assignments they carried."))
    reconciliation: Reconciliation | None = Field(None, description="The push's reconciliation, echoed.")
    dry_run: bool = Field(False, description="True for `?dry_run=true`: nothing was changed.")
    blas_to_build: list[str] | None = Field(None, description="Dry runs: geometry ids whose BLAS would be built.")
    missing_geometries: list[str] | None = Field(None, description="Dry runs: geometry ids not uploaded yet.")


# ---------------------------------------------------------------- geometries

class MissingQuery(Wire):
    """Body of ``POST /geometries/missing``."""

    ids: Annotated[list[GeometryId], Field(max_length=1_000_000)] = Field(
        description="Geometry ids (SHA-256 of each GLB, 64 hex digits) the client holds.")

    model_config = ConfigDict(json_schema_extra={"examples": [{"ids": [
        "9f2c4e1b7a3d5c8e0f6a2b4d1c3e5f7a9b0d2e4f6a8c1e3b5d7f9a0c2e4b6d8f",
        "0b1c2d3e4f5a6b7c8d9e0f1a2b3c4d5e6f7a8b9c0d1e2f3a4b5c6d7e8f9a0b1c"]}]})


class MissingPublic(Wire):
    """The geometries still to upload."""

    missing: list[str] = Field(description="Of the ids asked, those not stored (in the order asked, no repeats).")


class GeometryPublic(Wire):
    """A stored mesh."""

    id: str = Field(description="The SHA-256 of the GLB, 64 hex digits.")
    vertices: int = Field(description="Vertices of the mesh.")
    triangles: int = Field(description="Triangles of the mesh.")
    normals: bool = Field(description="Whether the GLB carries vertex normals.")
    faces: bool = Field(False, description="Whether the GLB carries each triangle's B-rep face index "
                                           "(_FEATURE_ID_0; what an element assignment's `faces` selects).")
    bytes: int = Field(description="Size of the GLB, bytes.")
    created: bool = Field(description="False when the mesh was already stored (an idempotent upload).")


# ---------------------------------------------------------------- materials (docs/DESIGN.md bodies)

# Material bodies are made from the tracer's typed specs, in one place: `service.optics`.
Material = optics.Material


class MaterialAssignment(Wire):
    """Wrapper used only to validate a material body (the body itself is the material)."""

    material: Material


class MaterialPublic(Wire):
    """A material assignment."""

    node: str = Field(description="The node's (or sim-owned object's) UUID.")
    material: dict[str, Any] = Field(description="The material body as given (see the material kinds).")
    orphaned: bool = Field(description="True while a push has removed the node.")


# ---------------------------------------------------------------- lights and sensors (docs/DESIGN.md bodies)

# Light and sensor bodies are made from the tracer's kinds' typed fields, in one place: `service.kind_wire`.
Light = kind_wire.Light
Sensor = kind_wire.Sensor
LightCreate = kind_wire.LightCreate
SensorCreate = kind_wire.SensorCreate


# ---------------------------------------------------------------- simulation-owned objects

class ObjectCreate(Wire):
    """A library object owned by the simulation: a stored mesh placed by a transform; pushes never touch it.

    ``transform`` (row-major 4×4) is ``world_from_object`` in metres, or ``node_from_object`` when
    ``attached_to`` names a node; the mesh vertices are in ``mesh_unit``.
    """

    geometry: GeometryId = Field(description="A stored mesh's id (SHA-256 of its GLB, 64 hex digits).")
    transform: Matrix16 = Field(default_factory=lambda: [1.0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1],
                                description="world_from_object (or node_from_object), row-major 4×4; its "
                                            "translation in m. Default identity.")
    mesh_unit: LengthUnit = Field("m", description="The unit of the mesh's vertices (m, cm, mm, um, in, ft).")
    name: Annotated[str, StringConstraints(max_length=200)] | None = Field(None, description="A name for people.")
    attached_to: NodeRef | None = Field(None, description="A node (UUID or path) the object moves with.")
    material: Material | None = Field(None, description="Its material; default the scene's default material.")

    model_config = ConfigDict(json_schema_extra={"examples": [{
        "geometry": EXAMPLE_FLOOR_GEOMETRY, "name": "test plate", "mesh_unit": "m",
        "transform": [0.25, 0.0, 0.0, -0.5, 0.0, 0.25, 0.0, -0.5, 0.0, 0.0, 0.25, 0.75, 0.0, 0.0, 0.0, 1.0],
        "material": {"type": "lambertian", "reflectance": 0.8}}]})


class AssignmentPublic(BaseModel):
    """A stored light, sensor or object: its id, its body as given, and whether it is orphaned."""

    model_config = ConfigDict(extra="forbid")

    id: str = Field(description="The light's, sensor's or object's id.")
    body: dict[str, Any] = Field(description="Its body as given (attached_to and node stored as UUIDs).")
    orphaned: bool = Field(description="True while a push has removed the node it refers to.")
