"""The house schema: one JSON document per house, shared by generated and imported houses.

Conventions (decided once, used everywhere):
- metres, right-handed, z up; the floor is z = 0; x, y span the floor plan;
- a piece of furniture has a local frame with x along its width, y along its depth and z up;
  its *front* (where doors open, drawers slide out and agents stand) faces local +y;
  ``yaw`` rotates local into world about z (generated houses use multiples of 90 degrees);
- ``position`` of furniture and objects is the centre of the footprint at the bottom face;
- surfaces are rectangles in the furniture's local frame (closed state for articulated parts);
  ``receptacle_type`` is the type D judges (a dresser's top is "Dresser", its drawers "Drawer");
- the navigation grid has 0.25 m cells, row-major strings with '.' free and '#' blocked,
  row 0 at the smallest y.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, is_dataclass
from typing import Any

SCHEMA_VERSION = "1.0"
CELL = 0.25  # metres per navigation cell (one MoveAhead)
AGENT_RADIUS = 0.2  # a cell is free when a disc of this radius fits around its centre
WALL_THICKNESS = 0.1


class HouseFormatError(ValueError):
    """A house document is malformed; the message names the field and what was expected."""


@dataclass
class Room:
    id: str
    type: str
    polygon: list[list[float]]  # [[x, y], ...] counter-clockwise
    floor_material: str = "wood"
    wall_material: str = "plaster"

    def bounds(self) -> tuple[float, float, float, float]:
        xs = [p[0] for p in self.polygon]
        ys = [p[1] for p in self.polygon]
        return min(xs), min(ys), max(xs), max(ys)

    def area(self) -> float:
        p = self.polygon
        return 0.5 * abs(sum(p[i][0] * p[i - 1][1] - p[i - 1][0] * p[i][1] for i in range(len(p))))


@dataclass
class Wall:
    id: str
    start: list[float]
    end: list[float]
    rooms: list[str]  # one room: exterior wall; two: interior wall between them
    height: float = 2.6
    thickness: float = WALL_THICKNESS
    material: str = "plaster"


@dataclass
class Door:
    """An opening in a wall; ``center`` lies on the wall line."""

    id: str
    wall: str
    rooms: list[str]
    center: list[float]
    width: float = 1.0
    height: float = 2.1


@dataclass
class Light:
    id: str
    room: str
    position: list[float]
    intensity: float = 1.0


@dataclass
class Joint:
    """A joint of articulated furniture, in the furniture's local frame (closed at 0)."""

    name: str  # also the name of the moving link
    type: str  # "revolute" (hinged door) or "prismatic" (drawer)
    axis: list[float]
    origin: list[float]  # hinge line point or drawer rest position
    limits: list[float]
    link_size: list[float]  # the moving panel or drawer box (w, d, h)
    link_center: list[float]  # centre of the moving part when closed, local frame


@dataclass
class Surface:
    name: str
    receptacle_type: str
    center: list[float]  # local (x, y, z): z is the height objects rest at
    size: list[float]  # (w, d) of the usable rectangle
    clearance: float | None = None  # max object height inside; None: open above
    link: str = "body"  # which link carries it: "body" or a joint name

    @property
    def inside(self) -> bool:
        return self.clearance is not None


@dataclass
class Furniture:
    id: str
    type: str
    room: str
    position: list[float]
    yaw: float
    size: list[float]  # (w, d, h) local
    surfaces: list[Surface] = field(default_factory=list)
    joints: list[Joint] = field(default_factory=list)
    parent: str | None = None  # furniture it stands on (a microwave on a counter)
    asset: str | None = None  # source asset id for imported houses

    def footprint(self) -> tuple[float, float, float, float]:
        """World axis-aligned bounds (x0, y0, x1, y1) of the footprint."""
        return rotated_bounds(self.position, self.size[0], self.size[1], self.yaw)

    def surface(self, name: str) -> Surface:
        for s in self.surfaces:
            if s.name == name:
                return s
        raise KeyError(
            f"{self.id} has no surface {name!r}; it has {[s.name for s in self.surfaces]}"
        )

    def surface_world(self, s: Surface) -> tuple[list[float], tuple[float, float, float, float]]:
        """World centre (x, y, z) of a surface and its world axis-aligned bounds."""
        c, sn = math.cos(self.yaw), math.sin(self.yaw)
        x = self.position[0] + c * s.center[0] - sn * s.center[1]
        y = self.position[1] + sn * s.center[0] + c * s.center[1]
        z = self.position[2] + s.center[2]
        return [x, y, z], rotated_bounds([x, y], s.size[0], s.size[1], self.yaw)


@dataclass
class PlacedObject:
    id: str
    type: str
    room: str
    receptacle: str  # furniture id, or "Floor"
    surface: str | None  # surface name on that furniture; None on the floor
    position: list[float]
    yaw: float
    size: list[float]

    def footprint(self) -> tuple[float, float, float, float]:
        return rotated_bounds(self.position, self.size[0], self.size[1], self.yaw)


@dataclass
class NavGrid:
    origin: list[float]  # world (x, y) of the corner of cell (0, 0)
    shape: list[int]  # (rows along y, cols along x)
    rows: list[str]
    cell: float = CELL

    def free(self, row: int, col: int) -> bool:
        return 0 <= row < self.shape[0] and 0 <= col < self.shape[1] and self.rows[row][col] == "."

    def center(self, row: int, col: int) -> tuple[float, float]:
        return (self.origin[0] + (col + 0.5) * self.cell, self.origin[1] + (row + 0.5) * self.cell)

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        return (int((y - self.origin[1]) // self.cell), int((x - self.origin[0]) // self.cell))


@dataclass
class House:
    id: str
    seed: int | None
    source: str  # "procedural" or "procthor"
    rooms: list[Room]
    walls: list[Wall]
    doors: list[Door]
    lights: list[Light]
    furniture: list[Furniture]
    objects: list[PlacedObject]
    navgrid: NavGrid | None = None
    room_spec: list[str] = field(default_factory=list)
    schema_version: str = SCHEMA_VERSION

    def room(self, room_id: str) -> Room:
        for r in self.rooms:
            if r.id == room_id:
                return r
        raise KeyError(f"house {self.id} has no room {room_id!r}")

    def room_at(self, x: float, y: float) -> str | None:
        """The id of the room whose polygon contains (x, y), or None outside every room."""
        from matplotlib.path import Path as PolygonPath

        for r in self.rooms:
            if PolygonPath(r.polygon).contains_point((x, y)):
                return r.id
        return None

    def furniture_by_id(self) -> dict[str, Furniture]:
        return {f.id: f for f in self.furniture}

    def object_by_id(self) -> dict[str, PlacedObject]:
        return {o.id: o for o in self.objects}

    def to_dict(self) -> dict[str, Any]:
        return _rounded(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> House:
        return house_from_dict(d)


def rotated_bounds(
    center: list[float], w: float, d: float, yaw: float
) -> tuple[float, float, float, float]:
    c, s = abs(math.cos(yaw)), abs(math.sin(yaw))
    hw, hd = (w * c + d * s) / 2, (w * s + d * c) / 2
    return center[0] - hw, center[1] - hd, center[0] + hw, center[1] + hd


def _rounded(x: Any) -> Any:
    """Plain JSON values with floats rounded, so that files are small and identical across
    runs and platforms. Walks dataclasses itself: ``asdict`` deep-copies every leaf first,
    which took about 15 % of dataset generation."""
    if isinstance(x, float):
        r = round(x, 4)
        return 0.0 if r == 0 else r
    if is_dataclass(x) and not isinstance(x, type):
        return {f.name: _rounded(getattr(x, f.name)) for f in fields(x)}
    if isinstance(x, dict):
        return {k: _rounded(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_rounded(v) for v in x]
    return x


def _build(kind: type, d: Any, where: str) -> Any:
    if not isinstance(d, dict):
        raise HouseFormatError(f"{where}: expected an object, got {type(d).__name__}")
    try:
        return kind(**d)
    except TypeError as e:
        raise HouseFormatError(f"{where}: {e} (fields of {kind.__name__})") from None


def house_from_dict(d: dict[str, Any]) -> House:
    """Parse a house document, with errors that name the offending field."""
    if not isinstance(d, dict):
        raise HouseFormatError(f"house: expected a JSON object, got {type(d).__name__}")
    version = d.get("schema_version")
    if version != SCHEMA_VERSION:
        raise HouseFormatError(
            f"house {d.get('id', '?')}: schema_version {version!r}, expected {SCHEMA_VERSION!r}"
        )
    hid = d.get("id", "?")
    required = ("id", "source", "rooms", "walls", "doors", "lights", "furniture", "objects")
    missing = [k for k in required if k not in d]
    if missing:
        raise HouseFormatError(f"house {hid}: missing {', '.join(missing)}")

    def many(key: str, kind: type) -> list:
        if not isinstance(d[key], list):
            raise HouseFormatError(f"house {hid}: {key} must be a list")
        return [_build(kind, x, f"house {hid}: {key}[{i}]") for i, x in enumerate(d[key])]

    furniture = []
    for i, f in enumerate(d["furniture"]):
        where = f"house {hid}: furniture[{i}]"
        if not isinstance(f, dict):
            raise HouseFormatError(f"{where}: expected an object")
        f = dict(f)
        f["surfaces"] = [
            _build(Surface, s, f"{where}.surfaces[{j}]")
            for j, s in enumerate(f.get("surfaces", []))
        ]
        f["joints"] = [
            _build(Joint, s, f"{where}.joints[{j}]") for j, s in enumerate(f.get("joints", []))
        ]
        furniture.append(_build(Furniture, f, where))
    nav = d.get("navgrid")
    return House(
        id=d["id"],
        seed=d.get("seed"),
        source=d["source"],
        rooms=many("rooms", Room),
        walls=many("walls", Wall),
        doors=many("doors", Door),
        lights=many("lights", Light),
        furniture=furniture,
        objects=many("objects", PlacedObject),
        navgrid=_build(NavGrid, nav, f"house {hid}: navgrid") if nav is not None else None,
        room_spec=d.get("room_spec", []),
        schema_version=version,
    )
