"""Geometry identity within tolerance (issue 42): a part whose B-rep a writer changed within tolerance (Stamp-S3's
board re-exported through OCCT: one edge split, 1593 -> 1594 edges, volume 8.6e-7 apart) keeps its geometry id,
decided by the symmetric Hausdorff distance of the two meshes against twice the deflection; a change of ten
deflections does not."""

from __future__ import annotations

import numpy as np
import pytest
from cad_helpers import STAMP, needs_fixtures, xcaf_round_trip

from cad_adapter.identity import confirm_same_surface, identify, node_records, part_signature
from cad_adapter.same_surface import closest_on_triangles, hausdorff_within, within
from cad_adapter.step_reader import read_step
from cad_adapter.tessellate import Settings, tessellate

DEFLECTION = 0.05  # mm


def test_point_to_triangle_distance_matches_a_dense_sampling() -> None:
    rng = np.random.default_rng(3)
    a, b, c = (rng.normal(size=(200, 3)) for _ in range(3))
    p = rng.normal(size=(200, 3)) * 2
    d = closest_on_triangles(p, a, b, c)
    u, v = np.meshgrid(np.linspace(0, 1, 201), np.linspace(0, 1, 201))
    keep = u + v <= 1
    u, v = u[keep], v[keep]
    for i in range(0, 200, 20):
        pts = a[i] + np.outer(u, b[i] - a[i]) + np.outer(v, c[i] - a[i])
        sampled = np.linalg.norm(pts - p[i], axis=1).min()
        spacing = max(np.linalg.norm(b[i] - a[i]), np.linalg.norm(c[i] - a[i])) / 200
        assert d[i] <= sampled + 1e-12 and sampled - d[i] <= spacing


def test_bad_tolerance_and_empty_meshes_are_refused() -> None:
    v = np.eye(3)
    t = np.array([[0, 1, 2]])
    with pytest.raises(ValueError, match="tol"):
        within((v, t), (v, t), float("nan"))
    with pytest.raises(ValueError, match="no triangle"):
        within((v, t), (v, t[:0]), 1.0)
    assert hausdorff_within((v, t), (v, t), 1e-12) <= 1e-15


@pytest.fixture(scope="module")
def stamp_pair(tmp_path_factory):
    out = tmp_path_factory.mktemp("stamp") / "Stamp-S3_occt.step"
    xcaf_round_trip(STAMP, out)
    return read_step(STAMP), read_step(out)


@needs_fixtures
def test_the_reexported_board_keeps_its_geometry_id_and_a_real_change_does_not(stamp_pair) -> None:
    a, b = stamp_pair
    settings = Settings.default(a.length_unit, DEFLECTION, 0.5, False)
    identify(a, None, write=False)
    tess_a = tessellate(a, settings)
    scene = node_records(a, {k: m.geometry_id for k, m in tess_a.meshes.items()})
    by_gid = {m.geometry_id: (m.vertices, m.triangles) for m in tess_a.meshes.values()}
    identify(b, None, write=False, previous=scene, reuse_geometry=True)
    assert len(b.reuse_if_same_surface) == 1  # the board: its topology changed, its invariants by 1e-6
    (key,) = b.reuse_if_same_surface
    board = b.parts[key]
    (key_a,) = [k for k, p in a.parts.items() if p.name == board.name]
    assert part_signature(b, key)["topology"][1] == part_signature(a, key_a)["topology"][1] + 1  # the split edge
    tess_b = tessellate(b, settings)
    assert list(tess_b.meshes) == [key]  # the only part meshed again
    changed = {gid: (v + np.array([0.0, 0.0, 10 * DEFLECTION], np.float32) * (v[:, 2:] > 0), t)
               for gid, (v, t) in by_gid.items()}  # the old board 10 deflections thicker
    found = confirm_same_surface(b, tess_b, changed.__getitem__)
    assert found[key] > 2 * DEFLECTION and key in tess_b.meshes and key not in b.reuse
    found = confirm_same_surface(b, tess_b, by_gid.__getitem__)
    assert found[key] <= 2 * DEFLECTION and not tess_b.meshes  # nothing to upload, no bottom level to build
    assert len(set(b.reuse.values())) == len({m.geometry_id for m in tess_a.meshes.values()})
    assert board.name == "STAMP-S3"
