"""``lumenlink push`` / ``watch`` end to end against a real service process (tests/service_process.py)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from cad_helpers import car, needs_fixtures

import cad_adapter
from cad_adapter import cli
from cad_adapter.client import Pusher
from cad_adapter.errors import RevisionConflict
from cad_adapter.step_uuid import write_step

ROOT = Path(__file__).resolve().parents[2]

try:
    from service_process import free_port, running_service

    import service.app  # noqa: F401  (the service and the tracer it needs must import)

    HAVE_SERVICE = True
    WHY = ""
except ImportError as exc:  # the service is another issue; say why the test cannot run
    HAVE_SERVICE = False
    WHY = f"the service cannot be started here: {exc}"

pytestmark = [pytest.mark.skipif(not HAVE_SERVICE, reason=WHY or "no service"), pytest.mark.slow]

COARSE_ARGS = ["--linear", "1.0", "--angular", "0.8"]


@pytest.fixture(scope="module")
def service(tmp_path_factory):
    with running_service(tmp_path_factory.mktemp("service")) as url:
        yield url


def write_car(path: Path, door: float = 0.0, radius: float = 120.0) -> dict[str, str]:
    """Write the sample car with stable UUIDs (the sidecar beside ``path``); returns name -> uuid."""
    doc = cad_adapter.read_document(car(door, radius), sidecar=path.with_name(path.name + ".ids.json"))
    write_step(doc, path)
    return {n.name: n.uuid for n in doc.nodes}


def run_cli(*args: str, env_extra: dict | None = None) -> subprocess.CompletedProcess:
    env = {**os.environ, **(env_extra or {})}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    return subprocess.run([sys.executable, "-m", "lumenlink.cli", *args], capture_output=True, text=True, env=env,
                          cwd=ROOT, timeout=600)


def test_push_edit_move_through_the_real_cli(service, tmp_path) -> None:
    step = tmp_path / "car.step"
    ids = write_car(step)
    env = {"LUMENLINK_CACHE_DIR": str(tmp_path / "cache")}
    first = run_cli("push", str(step), "--scene", "cli-car", "--server", service, "--json", *COARSE_ARGS, env_extra=env)
    assert first.returncode == 0, first.stderr
    a = json.loads(first.stdout)
    assert sorted(a["added"]) == sorted(ids.values())
    assert a["blas_built"] == 7 and a["instances"] == 10

    same = json.loads(run_cli("push", str(step), "--scene", "cli-car", "--server", service, "--json", *COARSE_ARGS,
                              env_extra=env).stdout)
    assert same["unchanged"] == 12 and not same["added"] and not same["geometry_changed"] and same["blas_built"] == 0

    write_car(step, radius=150.0)  # the lens only
    edited = run_cli("push", str(step), "--scene", "cli-car", "--server", service, "--json", *COARSE_ARGS,
                     env_extra=env)
    e = json.loads(edited.stdout)
    assert e["geometry_changed"] == [ids["lens"]]
    assert e["blas_built"] == 1 and not e["added"] and not e["removed"] and not e["moved"]

    write_car(step, door=40.0, radius=150.0)  # a move
    moved = run_cli("push", str(step), "--scene", "cli-car", "--server", service, *COARSE_ARGS, env_extra=env)
    assert moved.returncode == 0, moved.stderr
    assert "moved 2" in moved.stdout and "geometry changed 0" in moved.stdout and "0 uploaded" in moved.stdout


def test_push_to_a_stopped_service_fails_cleanly(tmp_path) -> None:
    step = tmp_path / "car.step"
    write_car(step)
    r = run_cli("push", str(step), "--scene", "x", "--server", f"http://127.0.0.1:{free_port()}", *COARSE_ARGS,
                env_extra={"LUMENLINK_CACHE_DIR": str(tmp_path / "cache")})
    assert r.returncode == cli.EXIT_UNREACHABLE
    assert "cannot reach the service" in r.stderr


def test_push_bad_file_through_the_cli(service, tmp_path) -> None:
    bad = tmp_path / "notes.step"
    bad.write_text("hello")
    r = run_cli("push", str(bad), "--scene", "x", "--server", service)
    assert r.returncode == cli.EXIT_INPUT and "not a STEP file" in r.stderr


def test_stale_revision_gets_409_and_changes_nothing(service, tmp_path) -> None:
    doc = cad_adapter.read_document(car(), sidecar=tmp_path / "ids.json")
    tess = cad_adapter.tessellate(doc, linear=1.0, angular=0.8)
    with Pusher(service) as p:
        first = p.push(doc, tess, scene="stale-car")
        assert first.answer["revision"] == 1
        p.push(doc, tess, scene="stale-car")  # no-op push: revision stays or moves; read it back
        current = p.revision(first.scene_id)
        moved = cad_adapter.read_document(car(30.0), sidecar=tmp_path / "ids.json")
        with pytest.raises(RevisionConflict) as err:
            p.push(moved, cad_adapter.tessellate(moved, linear=1.0, angular=0.8), scene="stale-car",
                   base_revision=current - 1 if current > 0 else 99)
        assert err.value.current_revision == current
        assert p.revision(first.scene_id) == current


def test_watch_pushes_again_when_the_file_changes(service, tmp_path) -> None:
    step = tmp_path / "car.step"
    ids = write_car(step)
    codes: list[int] = []
    t = threading.Thread(target=lambda: codes.append(cli.watch(step, "watch-car", service, linear=1.0, angular=0.8,
                                                               debounce=0.3, poll=0.05, max_pushes=2, timeout=240,
                                                               cache_dir=tmp_path / "cache")))
    t.start()
    with Pusher(service) as p:
        deadline = time.monotonic() + 120
        while p.scene_by_name("watch-car") is None or p.scene_by_name("watch-car")["revision"] < 1:
            assert time.monotonic() < deadline, "the first push of watch never arrived"
            time.sleep(0.2)
        write_car(step, radius=150.0)
        t.join(timeout=240)
        assert not t.is_alive() and codes == [0]
        scene = p.scene_by_name("watch-car")
        assert scene["revision"] == 2
    assert ids["lens"]


def _xcaf_round_trip(src: Path, dst: Path) -> None:
    """Read a STEP file into OCCT's XCAF document and write it again with OCCT's own writer (another writer:
    instance ids renumbered, entities reordered), with no edit."""
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPCAFControl import STEPCAFControl_Writer
    from OCP.STEPControl import STEPControl_AsIs

    from cad_adapter.step_reader import read_xcaf

    doc, _, _, _ = read_xcaf(src)
    writer = STEPCAFControl_Writer()
    writer.SetNameMode(True)
    writer.SetColorMode(True)
    assert writer.Transfer(doc, STEPControl_AsIs)
    assert writer.Write(str(dst)) == IFSelect_RetDone


@needs_fixtures
def test_save_as_and_another_writer_keep_identity_and_dry_run_changes_nothing(service, tmp_path) -> None:
    import shutil

    import httpx
    from cad_helpers import AS1

    env = {"LUMENLINK_CACHE_DIR": str(tmp_path / "cache")}
    lamp = tmp_path / "lamp.step"
    shutil.copy(AS1, lamp)
    first = run_cli("push", str(lamp), "--scene", "saveas", "--server", service, "--json", *COARSE_ARGS,
                    env_extra=env)
    assert first.returncode == 0, first.stderr
    added = json.loads(first.stdout)["added"]
    with httpx.Client(base_url=service) as http:
        sid = next(s["id"] for s in http.get("/scenes").json() if s["name"] == "saveas")
        before = http.get(f"/scenes/{sid}/nodes").json()
        plate = next(n["uuid"] for n in before if n["name"] == "plate_1")
        mirror = {"type": "mirror", "reflectance": 0.9}
        assert http.put(f"/scenes/{sid}/materials/{plate}", json=mirror).status_code == 200
        rev = http.get(f"/scenes/{sid}").json()["revision"]

        # "Save As" under a new name (no sidecar beside it), then re-exported by OCCT's writer
        rev2 = tmp_path / "lamp_rev2.step"
        _xcaf_round_trip(lamp, rev2)
        assert not (tmp_path / "lamp_rev2.step.lumenlink.json").exists()
        dry = run_cli("push", str(rev2), "--scene", "saveas", "--server", service, "--json", "--dry-run",
                      *COARSE_ARGS, env_extra=env)
        assert dry.returncode == 0, dry.stderr
        d = json.loads(dry.stdout)
        assert d["dry_run"] is True and not d["added"] and not d["removed"]
        assert http.get(f"/scenes/{sid}").json()["revision"] == rev  # nothing changed
        assert http.get(f"/scenes/{sid}/nodes").json() == before
        assert not (tmp_path / "lamp_rev2.step.lumenlink.json").exists()  # not even the sidecar

        real = run_cli("push", str(rev2), "--scene", "saveas", "--server", service, "--json", *COARSE_ARGS,
                       env_extra=env)
        assert real.returncode == 0, real.stderr
        a = json.loads(real.stdout)
        # the push is exactly the user's edit: none
        assert not a["added"] and not a["removed"] and not a["moved"] and not a["geometry_changed"]
        assert a["blas_built"] == 0 and not a["orphaned"]
        assert a["reconciliation"]["source"] == "scene" and a["reconciliation"]["matched"]["new"] == 0
        after = {n["uuid"]: n for n in http.get(f"/scenes/{sid}/nodes").json()}
        assert set(after) == set(added)
        assert {n["uuid"]: n["geometry"] for n in before} == {u: n["geometry"] for u, n in after.items()}
        mats = http.get(f"/scenes/{sid}/materials").json()
        assert plate in json.dumps(mats)  # the material is still on the plate


@needs_fixtures
def test_a_deleted_subassembly_pushed_back_gets_its_uuids_and_assignments_again(service, tmp_path) -> None:
    """Issue 42, on the CAX-IF as1 file: rod-assembly_1 deleted in OCCT's XCAF editor and saved (its nuts and the
    assembly go, the rod stays as a free root), pushed; the original pushed again. The 3 removed nodes come back
    under their old UUIDs (`restored`, not `new`), with the material that sat on one of them; no match is
    ambiguous. The first two pushes go through `push_file` in this process, the dry run and the last push through
    the real CLI."""
    import shutil

    import httpx
    from cad_helpers import AS1, xcaf_without

    env = {"LUMENLINK_CACHE_DIR": str(tmp_path / "cache")}
    orig, cut = tmp_path / "as1.stp", tmp_path / "as1_cut.stp"
    shutil.copy(AS1, orig)
    xcaf_without(AS1, cut, "rod-assembly_1")
    cache = cli.TessellationCache(tmp_path / "cache")
    first, doc, _, _, _ = cli.push_file(orig, "as1-restore", service, 1.0, 0.8, cache=cache)
    sid = first.scene_id
    with httpx.Client(base_url=service) as http:
        nodes = {n["path"]: n["uuid"] for n in http.get(f"/scenes/{sid}/nodes").json()}
        nut = nodes["as1/rod-assembly_1/nut_1"]
        assert http.put(f"/scenes/{sid}/materials/{nut}", json={"type": "black"}).status_code == 200
        cut_push, _, _, _, _ = cli.push_file(cut, "as1-restore", service, 1.0, 0.8, cache=cache)
        a = cut_push.answer
        rod_assembly = [nodes[p] for p in ("as1/rod-assembly_1", "as1/rod-assembly_1/nut_1",
                                           "as1/rod-assembly_1/nut_2")]
        assert sorted(a["removed"]) == sorted(rod_assembly) and not a["added"]
        assert a["orphaned"] == [{"kind": "material", "id": nut, "node": nut}]
        assert not a["reconciliation"]["ambiguous"]
        remembered = http.get(f"/scenes/{sid}/removed-nodes").json()
        assert sorted(r["uuid"] for r in remembered) == sorted(rod_assembly)

        dry = run_cli("push", str(orig), "--scene", "as1-restore", "--server", service, "--dry-run", *COARSE_ARGS,
                      env_extra=env)
        assert dry.returncode == 0, dry.stderr
        assert "would restore 3 removed node(s) under their old UUIDs" in dry.stdout
        assert "restored 3" in dry.stderr  # the identity report: nodes per rule

        back = run_cli("push", str(orig), "--scene", "as1-restore", "--server", service, "--json", *COARSE_ARGS,
                       env_extra=env)
        assert back.returncode == 0, back.stderr
        b = json.loads(back.stdout)
        assert sorted(b["restored_nodes"]) == sorted(rod_assembly) == sorted(b["added"])
        assert b["reconciliation"]["matched"]["restored"] == 3 and b["reconciliation"]["matched"]["new"] == 0
        assert b["reconciliation"]["ambiguous"] == [] and a["reconciliation"]["ambiguous"] == []
        assert b["restored"] == [{"kind": "material", "id": nut, "node": nut}]
        assert {n["path"]: n["uuid"] for n in http.get(f"/scenes/{sid}/nodes").json()} == nodes
        assert http.get(f"/scenes/{sid}/removed-nodes").json() == []
        assert b["blas_built"] == 0 and not b["geometry_changed"]


@needs_fixtures
def test_stamp_reexported_changes_no_geometry_and_a_restart_rebuilds_no_bottom_level(tmp_path) -> None:
    """Issue 42 on Creo's Stamp-S3: re-exported through OCCT (ids renumbered, one edge of the board split) it keeps
    every geometry id (the board's by the Hausdorff test: no upload, no bottom level); a restart of the service then
    loads all its bottom levels from the BLAS library, the small ones too, and builds none."""
    import httpx
    from cad_helpers import STAMP, xcaf_round_trip
    from service_process import running_service

    rt = tmp_path / "Stamp-S3_occt.step"
    xcaf_round_trip(STAMP, rt)
    cache = cli.TessellationCache(tmp_path / "cache")
    data = tmp_path / "service"
    with running_service(data) as url:
        first, _, tess, _, _ = cli.push_file(STAMP, "stamp", url, 0.05, 0.5, cache=cache)
        assert first.answer["blas_built"] == first.geometries == len(tess.meshes)
        small = sum(m.n_triangles < 512 for m in tess.meshes.values())
        again, doc, tess2, _, _ = cli.push_file(rt, "stamp", url, 0.05, 0.5, cache=cache)
        a = again.answer
        assert not a["geometry_changed"] and not a["added"] and not a["removed"] and not a["moved"]
        assert a["blas_built"] == 0 and again.uploaded == 0 and not tess2.meshes
        assert list(doc.reconciliation_detail["same_surface"]) == ["STAMP-S3"]
        assert doc.reconciliation_detail["same_surface"]["STAMP-S3"] <= 2 * 0.05
        assert a["reconciliation"]["ambiguous"] == []
        sid = first.scene_id
    with running_service(data, log_name="restart.log") as url:
        last = httpx.get(f"{url}/scenes/{sid}").json()["last_commit"]
        assert small > 0 and last["blas_built"] == 0 and last["blas_loaded"] == first.geometries
