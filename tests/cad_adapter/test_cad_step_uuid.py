"""The STEP writer carries node UUIDs through a STEP round trip (NAUO and product ids)."""

from __future__ import annotations

import shutil

import pytest
from cad_helpers import AS1, car, needs_fixtures

import cad_adapter
from cad_adapter.errors import CadAdapterError
from cad_adapter.step_reader import read_step
from cad_adapter.step_uuid import write_step


def test_car_uuids_survive_a_step_round_trip_without_sidecar(tmp_path) -> None:
    doc = cad_adapter.read_document(car())
    out = write_step(doc, tmp_path / "car.step")
    back = cad_adapter.read_document(out, write_sidecar=False)
    assert not (tmp_path / "car.step.lumenlink.json").exists()
    assert [n.path for n in back.nodes] == [n.path for n in doc.nodes]
    assert [n.uuid for n in back.nodes] == [n.uuid for n in doc.nodes]
    assert {n.match for n in back.nodes} == {"carried"}
    assert len(back.parts) == len(doc.parts)  # the wheel is still one part
    text = out.read_text()
    assert all(n.uuid in text for n in doc.nodes)


def test_carried_uuid_beats_a_stale_sidecar(tmp_path) -> None:
    from cad_adapter.assembly import read_assembly
    from cad_adapter.identity import identify

    doc = cad_adapter.read_document(car())
    out = write_step(doc, tmp_path / "car.step")
    # a sidecar at the same place that gives every path another UUID must not override what the file carries
    other = read_assembly(car())
    for n in other.nodes:
        n.carried_uuid = None
    identify(other, tmp_path / "car.step.lumenlink.json")
    assert {n.uuid for n in other.nodes}.isdisjoint({n.uuid for n in doc.nodes})
    back = cad_adapter.read_document(out)
    assert [n.uuid for n in back.nodes] == [n.uuid for n in doc.nodes]
    assert {n.match for n in back.nodes} == {"carried"}


@needs_fixtures
def test_as1_rewritten_keeps_instancing_and_uuids(tmp_path) -> None:
    src = tmp_path / "as1.stp"
    shutil.copy(AS1, src)
    doc = cad_adapter.read_document(src)
    out = write_step(doc, tmp_path / "as1-uuids.step")
    back = read_step(out)
    assert len(back.parts) == 5 and len(back.leaves()) == 18
    cad_adapter.identity.identify(back, None)
    assert [n.uuid for n in back.nodes] == [n.uuid for n in doc.nodes]
    assert {n.match for n in back.nodes} == {"carried"}


def test_shared_subassembly_uuids_are_not_trusted(tmp_path) -> None:
    # in the original as1 file NAUOs inside the reused nut-bolt assembly would be ambiguous; the reader only
    # applies carried ids to components occurring once. Simulate: put a UUID into every NAUO id of as1.
    if not AS1.exists():
        pytest.skip("fixture missing")
    import re
    import uuid

    text = AS1.read_text()
    made = []

    def sub(m: re.Match) -> str:
        u = str(uuid.uuid4())
        made.append(u)
        return f"NEXT_ASSEMBLY_USAGE_OCCURRENCE('{u}'"

    text = re.sub(r"NEXT_ASSEMBLY_USAGE_OCCURRENCE\('[^']*'", sub, text)
    p = tmp_path / "as1-ids.stp"
    p.write_text(text)
    doc = read_step(p)
    carried = sorted(n.path for n in doc.nodes if n.carried_uuid)
    # the top's 4 components and the rod assembly's 3 occur once each; the l-bracket assembly is used
    # twice and the nut-bolt assembly six times, so their components' NAUOs stand for several nodes
    assert carried == sorted(["as1/rod-assembly_1", "as1/l-bracket-assembly_1", "as1/plate_1",
                              "as1/l-bracket-assembly_2", "as1/rod-assembly_1/nut_1", "as1/rod-assembly_1/nut_2",
                              "as1/rod-assembly_1/rod_1"])
    assert len({n.carried_uuid for n in doc.nodes if n.carried_uuid}) == 7


def test_write_step_needs_uuids(tmp_path) -> None:
    from cad_adapter.assembly import read_assembly

    with pytest.raises(CadAdapterError, match="UUID"):
        write_step(read_assembly(car()), tmp_path / "x.step")
