"""The car sample: its parameters, carried UUIDs and the checks on its arguments."""

from __future__ import annotations

import math

import pytest
from cad_helpers import car

import cad_adapter
from cad_adapter.errors import CadAdapterError
from cad_adapter.identity import shape_signature
from cad_adapter.samples import LENS_APERTURE_MM, WIDTH, car_assembly, lens, node_uuid


def test_nodes_carry_the_same_uuids_in_every_build() -> None:
    a = cad_adapter.read_document(car(0.0, 120.0))
    b = cad_adapter.read_document(car(30.0, 150.0))
    assert [n.uuid for n in a.nodes] == [n.uuid for n in b.nodes] == [node_uuid(n.path) for n in a.nodes]
    assert {n.match for n in a.nodes} == {"carried"}
    assert len({n.uuid for n in a.nodes}) == len(a.nodes)


@pytest.mark.parametrize("radius", [65.0, 120.0, 400.0])
def test_lens_is_the_spherical_cap_of_its_radius(radius) -> None:
    sig = shape_signature(lens(radius).val().wrapped)
    a = LENS_APERTURE_MM
    h = radius - math.sqrt(radius**2 - a**2)
    assert sig["volume"] == pytest.approx(math.pi * h * h * (3 * radius - h) / 3, rel=1e-6)
    assert sig["area"] == pytest.approx(2 * math.pi * radius * h + math.pi * a * a, rel=1e-6)
    assert sig["bbox"][3] == pytest.approx(h, abs=1e-6) and sig["bbox"][0] == pytest.approx(0.0, abs=1e-6)


def test_doors_turn_about_their_hinges() -> None:
    doc = cad_adapter.read_document(car(30.0))
    left = next(n for n in doc.nodes if n.name == "door_left").transform
    right = next(n for n in doc.nodes if n.name == "door_right").transform
    assert math.degrees(math.atan2(left[1, 0], left[0, 0])) == pytest.approx(-30.0)
    assert math.degrees(math.atan2(right[1, 0], right[0, 0])) == pytest.approx(30.0)
    # the free edge of each panel (1100 mm behind its hinge) swings out of the body, never into the cabin
    free_edge = [-1100.0, 0.0, 0.0, 1.0]
    assert (left @ free_edge)[1] > WIDTH / 2 + 500
    assert (right @ free_edge)[1] < -WIDTH / 2 - 500


@pytest.mark.parametrize("kwargs, match", [
    ({"door_angle_deg": -1.0}, "door_angle_deg"), ({"door_angle_deg": 91.0}, "door_angle_deg"),
    ({"door_angle_deg": float("nan")}, "finite"), ({"lens_radius_mm": 60.0}, "rim radius"),
    ({"lens_radius_mm": "120"}, "finite"), ({"door_angle_deg": True}, "finite"),
])
def test_bad_arguments(kwargs, match) -> None:
    with pytest.raises(CadAdapterError, match=match):
        car_assembly(**kwargs)
