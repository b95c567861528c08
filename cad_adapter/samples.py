"""A car-like sample assembly built with cadquery (millimetres), for the tests, the benchmark and the demo.

Tree (names are stable, so occurrence paths match from one build to the next)::

    car
    ├── body            painted shell (a filleted box with a cabin on top)
    ├── door_left       hinged at its front edge, opened by ``door_angle_deg``
    ├── door_right      the mirror image, opened the other way
    ├── wheel_fl, wheel_fr, wheel_rl, wheel_rr   four instances of ONE wheel part
    ├── windscreen      a thin glass plate leaning back
    └── headlamp
        ├── housing     a cup open towards +x
        └── lens        a plano-convex spherical cap; its radius of curvature is ``lens_radius_mm``

Axes: x forward, y to the left, z up; the origin on the ground under the middle of the car.

Every node carries its UUID in its metadata (``metadata["uuid"]``, a UUID5 of its occurrence path), so the
same node has the same UUID in every build, whatever the parameters, with or without a sidecar.
"""

from __future__ import annotations

import math
import uuid

import cadquery as cq

from .errors import CadAdapterError

LENGTH = 4000.0
WIDTH = 1800.0
BODY_HEIGHT = 700.0
GROUND = 300.0
WHEEL_RADIUS = 330.0
WHEEL_WIDTH = 220.0
LENS_APERTURE_MM = 60.0  # radius of the lens' rim
DEFAULT_LENS_RADIUS_MM = 120.0
HOUSING_DEPTH_MM = 90.0
SAMPLE_NAMESPACE = uuid.UUID("6c1d4f0e-3b0a-5d6e-9a51-6c756d656e6c")


def node_uuid(path: str) -> str:
    """The UUID the sample carries for the node at occurrence path ``path`` (e.g. ``car/headlamp/lens``)."""
    return str(uuid.uuid5(SAMPLE_NAMESPACE, path))


def _meta(path: str) -> dict[str, str]:
    return {"uuid": node_uuid(path)}


def wheel() -> cq.Workplane:
    """A wheel with its axle along y, centred at the origin."""
    tyre = cq.Workplane("XZ").circle(WHEEL_RADIUS).circle(WHEEL_RADIUS * 0.6).extrude(WHEEL_WIDTH / 2, both=True)
    rim = cq.Workplane("XZ").circle(WHEEL_RADIUS * 0.6).extrude(WHEEL_WIDTH * 0.35, both=True)
    return tyre.union(rim)


def body() -> cq.Workplane:
    lower = (cq.Workplane("XY").box(LENGTH, WIDTH - 40, BODY_HEIGHT).edges("|X").fillet(120)
             .translate((0, 0, GROUND + BODY_HEIGHT / 2)))
    cabin = (cq.Workplane("XY").box(LENGTH * 0.45, WIDTH - 160, 550).edges("|Y").fillet(150)
             .translate((-LENGTH * 0.08, 0, GROUND + BODY_HEIGHT + 275 - 20)))
    arches = None
    for x in (LENGTH * 0.32, -LENGTH * 0.32):
        cut = cq.Workplane("XZ").center(x, GROUND + 30).circle(WHEEL_RADIUS + 40).extrude(WIDTH, both=True)
        arches = cut if arches is None else arches.union(cut)
    return lower.union(cabin).cut(arches)


def door() -> cq.Workplane:
    """A door panel in its own frame: hinge axis along z through the origin, panel towards -x."""
    return cq.Workplane("XY").box(1100, 40, 650).edges("|Y").fillet(60).translate((-550, 0, 325))


def windscreen() -> cq.Workplane:
    return cq.Workplane("XY").box(12, WIDTH - 260, 620).rotate((0, 0, 0), (0, 1, 0), -35)


def housing() -> cq.Workplane:
    """A cup open towards +x (where the lens sits), its back at x = -HOUSING_DEPTH_MM."""
    cup = cq.Workplane("YZ").circle(LENS_APERTURE_MM + 8).extrude(-HOUSING_DEPTH_MM)
    return cup.faces(">X").shell(-4)


def lens(radius_mm: float) -> cq.Workplane:
    """Plano-convex cap: flat face in x = 0, convex towards +x, rim radius LENS_APERTURE_MM."""
    a = LENS_APERTURE_MM
    sag = radius_mm - math.sqrt(radius_mm**2 - a**2)
    # the profile (flat side on the axis plane, arc of radius ``radius_mm``) revolved about the x axis
    apex = (sag, 0.0)
    mid_angle = math.asin(a / radius_mm) / 2
    mid = (sag - radius_mm + radius_mm * math.cos(mid_angle), radius_mm * math.sin(mid_angle))
    profile = (cq.Workplane("XY").moveTo(0, 0).lineTo(0, a).threePointArc(mid, apex).close())
    return profile.revolve(360, (0, 0, 0), (1, 0, 0))


def car_assembly(door_angle_deg: float = 0.0, lens_radius_mm: float = DEFAULT_LENS_RADIUS_MM) -> cq.Assembly:
    """Build the car-like sample assembly.

    Parameters
    ----------
    door_angle_deg : float
        How far both doors are open, degrees in [0, 90] (a move: same geometry, new transform).
    lens_radius_mm : float
        Radius of curvature of the headlamp lens' convex face, mm, > 60 (the rim radius); changing it
        changes exactly one geometry.

    Returns
    -------
    cadquery.Assembly
        In millimetres.
    """
    for name, v in (("door_angle_deg", door_angle_deg), ("lens_radius_mm", lens_radius_mm)):
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise CadAdapterError(f"{name} must be a finite number, got {v!r}")
    if not 0.0 <= door_angle_deg <= 90.0:
        raise CadAdapterError(f"door_angle_deg must lie in [0, 90], got {door_angle_deg}")
    if not lens_radius_mm > LENS_APERTURE_MM:
        raise CadAdapterError(f"lens_radius_mm must exceed the lens rim radius {LENS_APERTURE_MM} mm, "
                              f"got {lens_radius_mm}")
    paint = cq.Color(0.6, 0.05, 0.05)
    car = cq.Assembly(name="car", metadata=_meta("car"))
    car.add(body(), name="body", color=paint, metadata=_meta("car/body"))
    d = door()
    hinge_x = LENGTH * 0.18
    # the panels run towards -x from the hinge: the left (+y) door opens by turning clockwise seen from above
    car.add(d, name="door_left", color=paint, metadata=_meta("car/door_left"),
            loc=cq.Location((hinge_x, WIDTH / 2, GROUND + 60), (0, 0, 1), -door_angle_deg))
    car.add(d.mirror("XZ"), name="door_right", color=paint, metadata=_meta("car/door_right"),
            loc=cq.Location((hinge_x, -WIDTH / 2, GROUND + 60), (0, 0, 1), door_angle_deg))
    w = wheel()
    tyre = cq.Color(0.05, 0.05, 0.05)
    for name, x, y in (("wheel_fl", 1, 1), ("wheel_fr", 1, -1), ("wheel_rl", -1, 1), ("wheel_rr", -1, -1)):
        car.add(w, name=name, color=tyre, metadata=_meta(f"car/{name}"),
                loc=cq.Location((x * LENGTH * 0.32, y * (WIDTH / 2 - WHEEL_WIDTH / 2 + 30), WHEEL_RADIUS)))
    car.add(windscreen(), name="windscreen", color=cq.Color(0.7, 0.8, 0.9, 0.3), metadata=_meta("car/windscreen"),
            loc=cq.Location((LENGTH * 0.15, 0, GROUND + BODY_HEIGHT + 260)))
    # the housing's closed back (x = -HOUSING_DEPTH_MM in the lamp frame) sits on the body's front face
    lamp = cq.Assembly(name="headlamp",
                       loc=cq.Location((LENGTH / 2 + HOUSING_DEPTH_MM, WIDTH * 0.3, GROUND + BODY_HEIGHT * 0.6)),
                       metadata=_meta("car/headlamp"))
    lamp.add(housing(), name="housing", color=cq.Color(0.8, 0.8, 0.8), metadata=_meta("car/headlamp/housing"))
    lamp.add(lens(lens_radius_mm), name="lens", color=cq.Color(0.9, 0.95, 1.0, 0.2),
             metadata=_meta("car/headlamp/lens"))
    car.add(lamp, name="headlamp")
    return car
