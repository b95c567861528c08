"""Tessellation: determinism, the edited-part round trip, normals, watertightness, relative tolerance, cache."""

from __future__ import annotations

import math
import sys

import cadquery as cq
import numpy as np
import pytest
import trimesh
from cad_helpers import AS1, COARSE, car, needs_fixtures

import cad_adapter
from cad_adapter.assembly import read_assembly
from cad_adapter.errors import TessellationError
from cad_adapter.identity import shape_signature
from cad_adapter.samples import LENS_APERTURE_MM, lens
from cad_adapter.step_reader import read_step
from cad_adapter.tessellate import Settings, TessellationCache, mesh_shape, tessellate

# the package's `tessellate` is the convenience function; the module is reached through sys.modules
tess_mod = sys.modules["cad_adapter.tessellate"]


def ids_by_path(doc, tess) -> dict[str, str | None]:
    return {n.path: (tess.meshes[n.part].geometry_id if n.part in tess.meshes else None)
            for n in doc.nodes if n.part is not None}


@needs_fixtures
def test_same_shape_same_bytes_across_reads_and_parallel_modes() -> None:
    s = Settings(linear=0.2, angular=0.5)
    a, b = read_step(AS1), read_step(AS1)
    ta, tb = tessellate(a, s, parallel=True), tessellate(b, s, parallel=False)
    assert ta.meshes.keys() == tb.meshes.keys()
    for key, ma in ta.meshes.items():
        mb = tb.meshes[key]
        assert ma.vertices.tobytes() == mb.vertices.tobytes()
        assert ma.triangles.tobytes() == mb.triangles.tobytes()
        assert ma.normals.tobytes() == mb.normals.tobytes()
        assert ma.geometry_id == mb.geometry_id


@needs_fixtures
def test_previous_mesh_on_the_shape_does_not_change_the_result() -> None:
    doc = read_step(AS1)
    part = next(iter(doc.parts.values()))
    mesh_shape(part.shape, 0.01, 0.1)  # leaves a fine triangulation on the faces
    coarse_after_fine, _ = mesh_shape(part.shape, 0.5, 0.5)
    fresh, _ = mesh_shape(read_step(AS1).parts[part.key].shape, 0.5, 0.5)
    assert coarse_after_fine.geometry_id == fresh.geometry_id


def test_edited_part_changes_exactly_its_geometry_id() -> None:
    s = Settings(**COARSE)
    base = read_assembly(car(0.0, 120.0))
    edited = read_assembly(car(0.0, 150.0))
    opened = read_assembly(car(30.0, 120.0))
    ib, ie, io = (ids_by_path(d, tessellate(d, s)) for d in (base, edited, opened))
    changed = {p for p in ib if ib[p] != ie[p]}
    assert changed == {"car/headlamp/lens"}
    assert io == ib  # opening the doors moves nodes, it changes no geometry
    moved = {n.path for n, m in zip(base.nodes, opened.nodes, strict=True)
             if not np.array_equal(n.transform, m.transform)}
    assert moved == {"car/door_left", "car/door_right"}


def test_edited_part_round_trip_through_step(tmp_path) -> None:
    from cad_adapter.step_uuid import write_step

    s = Settings(**COARSE)
    ids = []
    for r in (120.0, 150.0):
        doc = cad_adapter.read_document(car(0.0, r), sidecar=tmp_path / "car.lumenlink.json")
        write_step(doc, tmp_path / f"car_{r:.0f}.step")
        back = read_step(tmp_path / f"car_{r:.0f}.step")
        ids.append(ids_by_path(back, tessellate(back, s)))
    assert {p for p in ids[0] if ids[0][p] != ids[1][p]} == {"car/headlamp/lens"}


def test_lens_mesh_honours_the_linear_deflection() -> None:
    radius, deflection = 120.0, 0.05
    mesh, missing = mesh_shape(lens(radius).val().wrapped, deflection, 0.5)
    assert missing == 0
    sag = radius - math.sqrt(radius**2 - LENS_APERTURE_MM**2)
    centre = np.array([sag - radius, 0.0, 0.0])
    v = mesh.vertices.astype(np.float64)
    f = mesh.triangles
    curved = mesh.normals[f][:, :, 0].min(axis=1) > -0.99  # not the flat back face
    dist = np.linalg.norm(v[f[curved]].mean(axis=1) - centre, axis=1)
    # a chord's midpoint lies inside the sphere by at most the deflection (vertices lie on the sphere)
    assert np.abs(np.linalg.norm(v[f[curved]].reshape(-1, 3) - centre, axis=1) - radius).max() < 1e-4
    assert (radius - dist).max() <= deflection * 1.05
    # and the back face is flat with normals pointing -x
    np.testing.assert_allclose(mesh.normals[f[~curved]].reshape(-1, 3), [[-1.0, 0.0, 0.0]] * (3 * (~curved).sum()),
                               atol=1e-6)


def closed_checks(mesh, shape, deflection: float) -> None:
    v = mesh.vertices.astype(np.float64)
    f = mesh.triangles.astype(np.int64)
    # normals are unit and on the outer side of their triangles
    np.testing.assert_allclose(np.linalg.norm(mesh.normals, axis=1), 1.0, atol=1e-5)
    g = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    assert ((g * mesh.normals[f].mean(axis=1)).sum(axis=1) > 0).all()
    # positions along shared edges coincide exactly: merged, the mesh is closed
    uniq, inverse = np.unique(mesh.vertices, axis=0, return_inverse=True)
    merged = trimesh.Trimesh(uniq, inverse.reshape(-1)[f], process=False)
    assert merged.is_watertight
    # outward winding: positive signed volume, within (surface area × deflection) of the B-rep's, since
    # every facet lies within the linear deflection of the surface
    vol = np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])).sum() / 6
    sig = shape_signature(shape)
    assert vol > 0
    assert abs(vol - sig["volume"]) <= sig["area"] * deflection


def test_car_parts_are_closed_with_outward_normals() -> None:
    doc = read_assembly(car())
    t = tessellate(doc, Settings(**COARSE))
    assert not t.failed and not t.empty
    for key, mesh in t.meshes.items():
        closed_checks(mesh, doc.parts[key].shape, COARSE["linear"])


@needs_fixtures
def test_step_parts_are_closed_with_outward_normals() -> None:
    doc = read_step(AS1)
    t = tessellate(doc, Settings(linear=0.2, angular=0.5))
    for key, mesh in t.meshes.items():
        closed_checks(mesh, doc.parts[key].shape, 0.2)


def test_face_locations_are_applied() -> None:
    box = cq.Workplane().box(10, 20, 30).val()
    moved = box.moved(cq.Location((5, -7, 11), (0, 0, 1), 30))
    transformed = box.rotate((0, 0, 0), (0, 0, 1), 30).translate((5, -7, 11))
    a, _ = mesh_shape(moved.wrapped, 0.5, 0.5)
    b, _ = mesh_shape(transformed.wrapped, 0.5, 0.5)
    assert a.vertices.shape == b.vertices.shape
    np.testing.assert_allclose(np.sort(a.vertices, axis=0), np.sort(b.vertices, axis=0), atol=1e-4)


def test_relative_tolerance_is_per_part() -> None:
    # a 1 mm and a 1 m sphere: relative to each part, both get the same triangle count;
    # absolute, the small one is coarse and the big one fine
    assy = cq.Assembly(name="scales")
    assy.add(cq.Workplane().sphere(0.5), name="small")
    assy.add(cq.Workplane().sphere(500.0), name="big", loc=cq.Location((2000, 0, 0)))
    doc = read_assembly(assy)
    rel = tessellate(doc, Settings(linear=0.002, angular=0.8, relative=True))
    small, big = (rel.meshes[n.part].n_triangles for n in doc.nodes[1:])
    assert small == big
    absolute = tessellate(doc, Settings(linear=0.5, angular=0.8))
    small_a, big_a = (absolute.meshes[n.part].n_triangles for n in doc.nodes[1:])
    assert big_a > 10 * small_a


def test_cache_meshes_only_changed_parts(tmp_path) -> None:
    s = Settings(**COARSE)
    cache = TessellationCache(tmp_path / "meshes")
    first = tessellate(read_assembly(car()), s, cache=cache)
    assert (first.meshed, first.cached) == (7, 0)
    again = tessellate(read_assembly(car()), s, cache=cache)
    assert (again.meshed, again.cached) == (0, 7)
    edited = tessellate(read_assembly(car(0.0, 150.0)), s, cache=cache)
    assert (edited.meshed, edited.cached) == (1, 6)
    # a new process: the disk cache answers, with identical arrays
    disk = TessellationCache(tmp_path / "meshes")
    fromdisk = tessellate(read_assembly(car()), s, cache=disk)
    assert (fromdisk.meshed, fromdisk.cached) == (0, 7)
    assert {k: m.geometry_id for k, m in fromdisk.meshes.items()} == {k: m.geometry_id for k, m in first.meshes.items()}
    # other settings are other cache entries
    finer = tessellate(read_assembly(car()), Settings(linear=0.5, angular=0.8), cache=disk)
    assert finer.meshed == 7


def test_damaged_cache_entry_is_a_miss(tmp_path) -> None:
    s = Settings(**COARSE)
    cache = TessellationCache(tmp_path)
    tessellate(read_assembly(car()), s, cache=cache)
    for f in tmp_path.glob("*.npz"):
        f.write_bytes(b"garbage")
    t = tessellate(read_assembly(car()), s, cache=TessellationCache(tmp_path))
    assert t.meshed == 7 and not t.failed


def test_failing_part_is_reported_and_the_rest_goes_on(monkeypatch) -> None:
    doc = cad_adapter.read_document(car())
    lens_key = next(n.part for n in doc.nodes if n.name == "lens")
    real = tess_mod.mesh_shape

    def flaky(shape, *args, **kwargs):
        if shape.IsSame(doc.parts[lens_key].shape):
            raise RuntimeError("Standard_Failure: BRepMesh gave up")
        return real(shape, *args, **kwargs)

    monkeypatch.setattr(tess_mod, "mesh_shape", flaky)
    t = tessellate(doc, Settings(**COARSE))
    assert set(t.failed) == {lens_key} and "BRepMesh gave up" in t.failed[lens_key]
    assert len(t.meshes) == 6
    body = cad_adapter.build_push(doc, t)
    lens_node = next(n for n in body["nodes"] if n["name"] == "lens")
    assert lens_node["geometry"] is None
    assert body["source"]["tessellation"]["failed"] == lens_node["uuid"]
    assert body["source"]["tessellation"]["failed_count"] == 1
    assert sum(n["geometry"] is not None for n in body["nodes"]) == 9


@pytest.mark.parametrize("kwargs, match", [
    ({"linear": 0.0}, "linear"), ({"linear": -1.0}, "linear"), ({"linear": float("nan")}, "linear"),
    ({"linear": True}, "linear"), ({"linear": 0.1, "angular": 0.0}, "angular"),
    ({"linear": 0.1, "angular": 2.0}, "pi/2"), ({"linear": 1.5, "relative": True}, "fraction"),
])
def test_bad_settings(kwargs, match) -> None:
    with pytest.raises(TessellationError, match=match):
        Settings(**kwargs)


def test_default_linear_is_a_tenth_of_a_millimetre_in_any_unit() -> None:
    assert Settings.default("mm").linear == pytest.approx(0.1)
    assert Settings.default("m").linear == pytest.approx(1e-4)
    assert Settings.default("in").linear == pytest.approx(0.1 / 25.4)
    assert Settings.default("mm", relative=True).linear == pytest.approx(0.002)


def test_tessellate_rejects_non_settings() -> None:
    with pytest.raises(TessellationError, match="Settings"):
        tessellate(read_assembly(car()), {"linear": 1.0})  # type: ignore[arg-type]
