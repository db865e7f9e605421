"""Which rooms a camera can see, from the floor plan alone (portal culling in 2-D).

Walls are opaque and reach the ceiling, so a camera sees into another room only through a chain
of doorways. Starting in the camera's room with the horizontal extent of its view (an arc of
directions), every doorway whose directions overlap the arc opens the room behind it, with the
arc narrowed to that doorway; and so on. Everything is conservative: a room is dropped only when
no ray of the view can reach it (the doorway's centre line bounds every ray through a thick
doorway; a camera in or beside a doorway starts in both rooms and sees all around). Software
rendering pays for geometry behind walls as much as for geometry in view, so v2 hides the rooms
this returns no for while a camera renders (``HouseScene.show_rooms``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from matplotlib.path import Path as PolygonPath

from maniskill_tidy.houses.schema import House

FULL = math.pi  # half-width of the whole circle
MARGIN = math.radians(3)  # widening of every arc: rounding never hides what is seen
NEAR_DOOR = 0.35  # metres: a camera this close to a doorway sees both rooms all around


def wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


@dataclass(frozen=True)
class Arc:
    """Directions ``centre`` +- ``half`` (radians, world frame)."""

    centre: float
    half: float

    def meet(self, other: Arc) -> Arc | None:
        if self.half >= FULL:
            return other
        if other.half >= FULL:
            return self
        d = wrap(other.centre - self.centre)
        lo, hi = max(-self.half, d - other.half), min(self.half, d + other.half)
        if lo >= hi:
            return None
        return Arc(wrap(self.centre + (lo + hi) / 2), (hi - lo) / 2)


@dataclass(frozen=True)
class Doorway:
    rooms: tuple[str, str]
    a: np.ndarray  # end points of the opening on the wall's centre line (x, y)
    b: np.ndarray


class FloorPlan:
    """A house's rooms and doorways, for visibility queries."""

    def __init__(self, house: House) -> None:
        self.rooms = [r.id for r in house.rooms]
        self.outline = {r.id: PolygonPath(r.polygon) for r in house.rooms}
        walls = {w.id: w for w in house.walls}
        self.doorways: list[Doorway] = []
        for d in house.doors:
            if len(d.rooms) != 2 or d.wall not in walls:
                continue
            w = walls[d.wall]
            u = np.subtract(w.end, w.start, dtype=np.float64)
            u /= max(float(np.linalg.norm(u)), 1e-9)
            c = np.asarray(d.center[:2], dtype=np.float64)
            self.doorways.append(Doorway(tuple(d.rooms), c - u * d.width / 2, c + u * d.width / 2))

    def room_at(self, xy) -> str | None:
        for rid, path in self.outline.items():
            if path.contains_point((float(xy[0]), float(xy[1]))):
                return rid
        return None

    def visible_rooms(self, xy, view: Arc) -> set[str]:
        """Rooms a camera at ``xy`` (plan position) looking over ``view`` may see."""
        xy = np.asarray(xy, dtype=np.float64)[:2]
        start = {self.room_at(xy)} - {None}
        for door in self.doorways:
            if segment_distance(xy, door.a, door.b) < NEAR_DOOR:
                start |= set(door.rooms)
                view = Arc(0.0, FULL)
        if not start:
            return set(self.rooms)  # outside every room (should not happen): hide nothing
        seen = set(start)
        stack = [(room, view, frozenset()) for room in start]
        while stack:
            room, arc, used = stack.pop()
            for i, door in enumerate(self.doorways):
                if room not in door.rooms or i in used:
                    continue
                through = arc.meet(door_arc(xy, door))
                if through is None:
                    continue
                other = door.rooms[1] if door.rooms[0] == room else door.rooms[0]
                seen.add(other)
                stack.append((other, through, used | {i}))
        return seen


def door_arc(xy: np.ndarray, door: Doorway) -> Arc:
    va, vb = door.a - xy, door.b - xy
    ta, tb = math.atan2(va[1], va[0]), math.atan2(vb[1], vb[0])
    half = abs(wrap(tb - ta)) / 2
    return Arc(wrap(ta + wrap(tb - ta) / 2), half + MARGIN)


def segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    t = float(np.clip(np.dot(p - a, ab) / max(float(np.dot(ab, ab)), 1e-12), 0.0, 1.0))
    return float(np.linalg.norm(p - (a + t * ab)))


def camera_arc(yaw: float, pitch_down: float, fov: float, aspect: float = 1.0) -> Arc:
    """The plan directions a pinhole camera's view spans (``fov`` vertical, ``aspect`` width
    over height): from the corner rays; all around when a ray points down behind the camera."""
    t = math.tan(fov / 2)
    angles = []
    for right in (-t * aspect, t * aspect):
        for down in (-t, t):
            # camera frame: x forward, y left, z up; pitch down by ``pitch_down``
            x, y, z = 1.0, right, -down
            c, s = math.cos(pitch_down), math.sin(pitch_down)
            x, z = c * x + s * z, -s * x + c * z
            if x <= 1e-6:
                return Arc(0.0, FULL)
            angles.append(math.atan2(y, x))
    half = max(abs(a) for a in angles)
    return Arc(wrap(yaw), min(FULL, half + MARGIN))
