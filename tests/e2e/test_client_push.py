"""The engineer's loop in Python alone (issue 22): `lumenlink.Client.push` pushes real STEP files, written by
cadquery without any LumenLink ids, to a real service process; a "Save As" keeps every UUID and so the material
given by path; opening the doors is a move of two nodes; a floor map before and after the edit compares."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))

from service_process import running_service  # noqa: E402

from lumenlink import Client, LumenLinkError  # noqa: E402

pytestmark = pytest.mark.slow


def _step(path: Path, door_deg: float) -> Path:
    from cad_adapter.samples import car_assembly

    car_assembly(door_deg).export(str(path))   # cadquery's own STEP writer: no LumenLink ids in the file
    return path


def test_push_find_assign_map_edit_compare_from_python(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("LUMENLINK_CACHE_DIR", str(tmp_path / "mesh-cache"))
    first, saved_as, opened = (_step(tmp_path / "car.step", 0.0), _step(tmp_path / "car_rev2.step", 0.0),
                               _step(tmp_path / "car_doors_open.step", 40.0))
    with running_service(tmp_path / "service") as url, Client(url) as ll:
        a = ll.push(first, "py-car", linear=2.0, angular=0.8)
        assert a["revision"] == 1 and len(a["added"]) >= 10 and a["dry_run"] is False
        uuids = {n["path"]: n["uuid"] for n in ll.nodes("py-car")}
        lens = next(p for p in uuids if p.endswith("/lens"))
        ll.assign("py-car", lens, {"type": "dielectric", "ior": 1.5})
        ll.add_light("py-car", {"type": "point", "position": [6, 0, 3], "intensity_cd": 1000})
        floor = ll.add_sensor("py-car", Client.grid(origin=(-4, -4, 0.001), u=(8, 0, 0), v=(0, 8, 0), nu=4, nv=4,
                                                    name="floor"))
        ll.simulate("py-car", floor["id"], max_photons=40_000)

        b = ll.push(saved_as, "py-car", linear=2.0, angular=0.8)          # "Save As": the same model, a new file
        assert (b["added"], b["removed"], b["moved"]) == ([], [], [])
        assert {n["path"]: n["uuid"] for n in ll.nodes("py-car")} == uuids
        assert [m["material"]["type"] for m in ll.materials("py-car") if m["node"] == uuids[lens]] == ["dielectric"]

        c = ll.push(opened, "py-car", linear=2.0, angular=0.8)            # the designer opens both doors
        assert len(c["moved"]) == 2 and not c["added"] and not c["removed"] and c["revision"] == 2
        assert all(uuids[p] in c["moved"] for p in uuids if "door" in p)
        ll.simulate("py-car", floor["id"], max_photons=40_000)
        change = ll.compare("py-car", "floor")[floor["id"]]
        assert change["summary"]["cells"] == 16 and change["from"].startswith("1") and change["to"].startswith("2")

        with pytest.raises(LumenLinkError) as bad:
            ll.push(tmp_path / "missing.step", "py-car")
        assert bad.value.usage and "missing.step" in str(bad.value)


def test_push_carries_the_client_s_own_token(tmp_path, monkeypatch) -> None:
    """`Client(token=...)` pushes with that token, not only with $LUMENLINK_TOKEN: against a service that asks for
    one, with the variable unset, the push lands; a client with a wrong token gets the 401 as a LumenLinkError."""
    import cadquery as cq

    monkeypatch.setenv("LUMENLINK_CACHE_DIR", str(tmp_path / "mesh-cache"))
    monkeypatch.delenv("LUMENLINK_TOKEN", raising=False)
    step = tmp_path / "block.step"
    cq.Assembly(cq.Workplane().box(1, 2, 3), name="block").export(str(step))
    token = "client-token-of-at-least-16-chars"
    with running_service(tmp_path / "service", env={"LUMENLINK_TOKEN": token}) as url:
        with Client(url, token="a-wrong-token-of-16-chars") as wrong, pytest.raises(LumenLinkError) as refused:
            wrong.push(step, "tokened")
        assert "401" in str(refused.value) or refused.value.status == 401
        with Client(url, token=token) as ll:
            answer = ll.push(step, "tokened")
            assert answer["revision"] == 1 and answer["added"]
            assert "block" in [n["name"] for n in ll.nodes("tokened")]
