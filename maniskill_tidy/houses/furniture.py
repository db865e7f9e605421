"""Furniture templates: sizes, how each type stands in a room, its surfaces and its joints.

Sizes are in the range of ProcTHOR's assets (see ``knowledge/data/catalog.json``); surfaces
are typed with the receptacle type D judges, so a dresser's top is a "Dresser" and its drawers
are "Drawer"s, a sink cabinet has a "Sink" basin, a "CounterTop" and a "Cabinet" inside.
Hinged doors are revolute joints about +z at a front edge; drawers are prismatic along +y.

Stances follow ProcTHOR's placement annotations (``onEdge``/``inCorner``/``onWall`` in
``catalog.json``); tables, chairs, stools and ottomans stand in the middle of the room, as
ProcTHOR's object groups (a dining table with chairs) put them, although the per-type
annotation marks them as edge/corner pieces.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from maniskill_tidy.houses.schema import Joint, Surface

DOOR_THICKNESS = 0.03


@dataclass(frozen=True)
class Template:
    type: str
    size: tuple[tuple[float, float], tuple[float, float], tuple[float, float]]  # w, d, h ranges
    stance: str  # "wall", "corner", "middle", "on_counter", "wall_mounted", "on_stand"
    parts: Callable[[float, float, float], tuple[list[Surface], list[Joint]]]
    elevation: float = 0.0  # base height for wall-mounted pieces
    blocks_navigation: bool = True

    def sample_size(self, rng: np.random.Generator) -> list[float]:
        return [round(float(rng.uniform(lo, hi)), 2) for lo, hi in self.size]


def top(
    rtype: str, w: float, d: float, h: float, inset: float = 0.05, name: str = "top"
) -> Surface:
    return Surface(name, rtype, [0.0, 0.0, h], [max(w - 2 * inset, 0.05), max(d - 2 * inset, 0.05)])


def hinged_door(name: str, w: float, d: float, z0: float, z1: float, x0: float, x1: float) -> Joint:
    """A door covering local x in [x0, x1], z in [z0, z1] on the front face, hinged at x0."""
    return Joint(
        name=name,
        type="revolute",
        axis=[0.0, 0.0, 1.0],
        origin=[x0, d / 2, 0.0],
        limits=[0.0, 1.9],
        link_size=[x1 - x0, DOOR_THICKNESS, z1 - z0],
        link_center=[(x0 + x1) / 2, d / 2 + DOOR_THICKNESS / 2, (z0 + z1) / 2],
    )


def drawer(name: str, w: float, d: float, z0: float, z1: float, x0: float, x1: float) -> Joint:
    return Joint(
        name=name,
        type="prismatic",
        axis=[0.0, 1.0, 0.0],
        origin=[(x0 + x1) / 2, 0.0, z0],
        limits=[0.0, round(0.75 * d, 3)],
        link_size=[x1 - x0, d - 0.04, z1 - z0],
        link_center=[(x0 + x1) / 2, 0.0, (z0 + z1) / 2],
    )


def inside(
    rtype: str,
    name: str,
    w: float,
    d: float,
    z: float,
    clearance: float,
    link: str = "body",
    x: float = 0.0,
) -> Surface:
    return Surface(name, rtype, [x, 0.0, z], [w, d], clearance=clearance, link=link)


def _counter(w, d, h):
    doors = max(1, round(w / 0.6))
    dw = w / doors
    joints = [
        hinged_door(f"door_{i}", w, d, 0.1, h - 0.1, -w / 2 + i * dw, -w / 2 + (i + 1) * dw)
        for i in range(doors)
    ]
    return [
        top("CounterTop", w, d, h),
        inside("Cabinet", "cabinet", w - 0.1, d - 0.1, 0.12, h - 0.3),
    ], joints


def _sink(w, d, h):
    basin_w = 0.55 * w
    surfaces = [
        Surface(
            "basin",
            "Sink",
            [w / 2 - basin_w / 2 - 0.05, 0.0, h - 0.15],
            [basin_w, d - 0.2],
            clearance=None,
        ),
        Surface(
            "top",
            "CounterTop",
            [-(w / 2) + (w - basin_w - 0.1) / 2, 0.0, h],
            [w - basin_w - 0.15, d - 0.1],
        ),
        inside("Cabinet", "cabinet", w - 0.1, d - 0.1, 0.12, h - 0.45),
    ]
    return surfaces, [hinged_door("door_0", w, d, 0.1, h - 0.1, -w / 2, w / 2)]


def _fridge(w, d, h):
    shelves = [
        inside("Fridge", f"shelf_{i}", w - 0.1, d - 0.15, z, 0.35)
        for i, z in enumerate((0.45, 0.9, 1.35))
    ]
    return shelves, [hinged_door("door", w, d, 0.05, h - 0.02, -w / 2, w / 2)]


def _microwave(w, d, h):
    return [inside("Microwave", "inside", 0.65 * w, d - 0.08, 0.04, h - 0.08, x=-0.12 * w)], [
        hinged_door("door", w, d, 0.02, h - 0.02, -w / 2, w / 4)
    ]


def _dresser(w, d, h):
    n = 3
    dz = (h - 0.1) / n
    joints = [
        drawer(
            f"drawer_{i}",
            w,
            d,
            0.05 + i * dz + 0.01,
            0.05 + (i + 1) * dz - 0.01,
            -w / 2 + 0.03,
            w / 2 - 0.03,
        )
        for i in range(n)
    ]
    surfaces = [top("Dresser", w, d, h)] + [
        inside(
            "Drawer",
            f"in_drawer_{i}",
            w - 0.12,
            d - 0.12,
            0.05 + i * dz + 0.03,
            dz - 0.06,
            link=f"drawer_{i}",
        )
        for i in range(n)
    ]
    return surfaces, joints


def _table_with_drawer(rtype: str):
    def parts(w, d, h):
        dw = min(0.5, 0.45 * w)
        x0 = w / 2 - dw - 0.03
        j = drawer("drawer_0", w, d, h - 0.16, h - 0.04, x0, w / 2 - 0.03)
        return [
            top(rtype, w, d, h),
            inside(
                "Drawer",
                "in_drawer_0",
                dw - 0.06,
                d - 0.12,
                h - 0.14,
                0.08,
                link="drawer_0",
                x=x0 + dw / 2,
            ),
        ], [j]

    return parts


def _shelves(w, d, h):
    levels = [0.35, 0.75, 1.1]
    return [top("ShelvingUnit", w, d, h)] + [
        inside("Shelf", f"shelf_{i}", w - 0.06, d - 0.06, z, 0.3)
        for i, z in enumerate(levels)
        if z < h - 0.3
    ], []


def _seat(rtype: str, seat_frac: float, depth_frac: float = 0.8):
    def parts(w, d, h):
        return [
            Surface(
                "seat",
                rtype,
                [0.0, d * (1 - depth_frac) / 2, seat_frac * h],
                [w - 0.2, d * depth_frac - 0.1],
            )
        ], []

    return parts


def _open_top(rtype: str):
    return lambda w, d, h: ([top(rtype, w, d, h)], [])


def _bin(rtype: str):
    return lambda w, d, h: ([inside(rtype, "inside", w - 0.08, d - 0.08, 0.05, h - 0.08)], [])


def _safe(w, d, h):
    return [inside("Safe", "inside", w - 0.1, d - 0.1, 0.06, h - 0.12)], [
        hinged_door("door", w, d, 0.03, h - 0.03, -w / 2, w / 2)
    ]


def _bathtub(w, d, h):
    return [Surface("basin", "Bathtub", [0.0, 0.0, 0.12], [w - 0.3, d - 0.25])], []


def _bar(rtype: str):
    return lambda w, d, h: ([Surface("bar", rtype, [0.0, 0.0, h], [w - 0.04, 0.06])], [])


def _toilet(w, d, h):
    return [Surface("tank", "Toilet", [0.0, -d / 2 + 0.12, h], [w - 0.08, 0.18])], []


def _nothing(w, d, h):
    return [], []


TEMPLATES: dict[str, Template] = {
    t.type: t
    for t in [
        Template("CounterTop", ((1.2, 2.4), (0.6, 0.65), (0.9, 0.92)), "wall", _counter),
        Template("Sink", ((0.8, 1.1), (0.55, 0.6), (0.85, 0.9)), "wall", _sink),
        Template("Fridge", ((0.7, 0.9), (0.7, 0.75), (1.75, 1.9)), "corner", _fridge),
        Template(
            "StoveBurner", ((0.6, 0.76), (0.6, 0.65), (0.9, 0.92)), "wall", _open_top("StoveBurner")
        ),
        Template("Microwave", ((0.45, 0.55), (0.35, 0.4), (0.28, 0.33)), "on_counter", _microwave),
        Template("CoffeeMachine", ((0.25, 0.3), (0.25, 0.3), (0.35, 0.4)), "on_counter", _nothing),
        Template("Toaster", ((0.25, 0.3), (0.18, 0.2), (0.18, 0.22)), "on_counter", _nothing),
        Template(
            "DiningTable",
            ((1.2, 1.6), (0.8, 0.95), (0.74, 0.78)),
            "middle",
            _open_top("DiningTable"),
        ),
        Template("Chair", ((0.42, 0.48), (0.45, 0.5), (0.85, 0.95)), "middle", _seat("Chair", 0.5)),
        Template("Stool", ((0.35, 0.4), (0.35, 0.4), (0.6, 0.7)), "middle", _open_top("Stool")),
        Template("GarbageCan", ((0.3, 0.4), (0.3, 0.4), (0.45, 0.6)), "corner", _bin("GarbageCan")),
        Template("ShelvingUnit", ((0.7, 1.0), (0.33, 0.4), (1.3, 1.6)), "wall", _shelves),
        Template("Sofa", ((1.8, 2.3), (0.85, 0.95), (0.8, 0.9)), "wall", _seat("Sofa", 0.5)),
        Template(
            "ArmChair", ((0.85, 0.95), (0.85, 0.9), (0.85, 0.95)), "corner", _seat("ArmChair", 0.5)
        ),
        Template(
            "CoffeeTable",
            ((0.9, 1.2), (0.55, 0.7), (0.4, 0.46)),
            "middle",
            _open_top("CoffeeTable"),
        ),
        Template("TVStand", ((1.2, 1.6), (0.4, 0.5), (0.5, 0.6)), "wall", _open_top("TVStand")),
        Template("Television", ((0.9, 1.2), (0.15, 0.2), (0.55, 0.7)), "on_stand", _nothing),
        Template(
            "SideTable",
            ((0.45, 0.6), (0.4, 0.45), (0.55, 0.68)),
            "corner",
            _table_with_drawer("SideTable"),
        ),
        Template(
            "Desk", ((1.1, 1.4), (0.6, 0.65), (0.74, 0.78)), "wall", _table_with_drawer("Desk")
        ),
        Template("Dresser", ((0.9, 1.3), (0.48, 0.55), (0.8, 1.0)), "wall", _dresser),
        Template("Ottoman", ((0.5, 0.7), (0.5, 0.7), (0.4, 0.45)), "middle", _open_top("Ottoman")),
        Template("Bed", ((1.4, 1.8), (2.0, 2.1), (0.55, 0.6)), "wall", _seat("Bed", 1.0, 0.95)),
        Template(
            "LaundryHamper",
            ((0.4, 0.5), (0.35, 0.45), (0.55, 0.65)),
            "corner",
            _bin("LaundryHamper"),
        ),
        Template("Safe", ((0.4, 0.5), (0.4, 0.5), (0.45, 0.55)), "corner", _safe),
        Template("Toilet", ((0.4, 0.5), (0.65, 0.75), (0.75, 0.8)), "wall", _toilet),
        Template("Bathtub", ((1.5, 1.7), (0.7, 0.8), (0.5, 0.58)), "corner", _bathtub),
        Template(
            "TowelHolder",
            ((0.5, 0.6), (0.08, 0.1), (0.04, 0.05)),
            "wall_mounted",
            _bar("TowelHolder"),
            elevation=1.2,
            blocks_navigation=False,
        ),
        Template(
            "HandTowelHolder",
            ((0.25, 0.3), (0.08, 0.1), (0.04, 0.05)),
            "wall_mounted",
            _bar("HandTowelHolder"),
            elevation=1.0,
            blocks_navigation=False,
        ),
        Template(
            "ToiletPaperHanger",
            ((0.14, 0.16), (0.1, 0.12), (0.04, 0.05)),
            "wall_mounted",
            _bar("ToiletPaperHanger"),
            elevation=0.7,
            blocks_navigation=False,
        ),
        Template("FloorLamp", ((0.35, 0.4), (0.35, 0.4), (1.5, 1.7)), "corner", _nothing),
        Template("HousePlant", ((0.35, 0.5), (0.35, 0.5), (0.6, 1.1)), "corner", _nothing),
    ]
}

# What each room type holds: (type, probability, max count). Required pieces have p = 1.
ROOM_FURNITURE: dict[str, list[tuple[str, float, int]]] = {
    "Kitchen": [
        ("Fridge", 1, 1),
        ("CounterTop", 1, 2),
        ("Sink", 1, 1),
        ("StoveBurner", 1, 1),
        ("DiningTable", 0.6, 1),
        ("Chair", 0.5, 2),
        ("ShelvingUnit", 0.4, 1),
        ("GarbageCan", 0.8, 1),
        ("SideTable", 0.3, 1),
        ("Stool", 0.2, 1),
        ("HousePlant", 0.2, 1),
    ],
    "LivingRoom": [
        ("Sofa", 1, 1),
        ("TVStand", 0.8, 1),
        ("CoffeeTable", 0.8, 1),
        ("ArmChair", 0.6, 1),
        ("SideTable", 0.7, 2),
        ("ShelvingUnit", 0.5, 1),
        ("Dresser", 0.3, 1),
        ("DiningTable", 0.3, 1),
        ("Desk", 0.3, 1),
        ("Chair", 0.3, 1),
        ("Ottoman", 0.3, 1),
        ("GarbageCan", 0.5, 1),
        ("FloorLamp", 0.5, 1),
        ("HousePlant", 0.5, 1),
    ],
    "Bedroom": [
        ("Bed", 1, 1),
        ("Dresser", 0.8, 1),
        ("SideTable", 0.8, 2),
        ("Desk", 0.5, 1),
        ("Chair", 0.4, 1),
        ("ShelvingUnit", 0.4, 1),
        ("ArmChair", 0.3, 1),
        ("CoffeeTable", 0.2, 1),
        ("LaundryHamper", 0.3, 1),
        ("GarbageCan", 0.5, 1),
        ("Safe", 0.2, 1),
        ("FloorLamp", 0.3, 1),
    ],
    "Bathroom": [
        ("Toilet", 1, 1),
        ("Sink", 1, 1),
        ("Bathtub", 0.6, 1),
        ("TowelHolder", 0.8, 1),
        ("HandTowelHolder", 0.7, 1),
        ("ToiletPaperHanger", 0.8, 1),
        ("GarbageCan", 0.6, 1),
        ("ShelvingUnit", 0.4, 1),
        ("SideTable", 0.3, 1),
        ("Dresser", 0.15, 1),
    ],
}
# Pieces that stand on another: the host type and the probability per host.
ON_HOST: dict[str, list[tuple[str, float]]] = {
    "CounterTop": [("Microwave", 0.8), ("CoffeeMachine", 0.6), ("Toaster", 0.5)],
    "TVStand": [("Television", 0.9)],
}


def parts_for(type_name: str, size: list[float]) -> tuple[list[Surface], list[Joint]]:
    """Surfaces and joints of a piece of ``type_name`` with ``size`` (w, d, h)."""
    template = TEMPLATES.get(type_name)
    if template is None:
        return [], []
    surfaces, joints = template.parts(*size)
    for s in surfaces:
        s.center = [round(v, 4) for v in s.center]
        s.size = [round(v, 4) for v in s.size]
    return surfaces, joints
