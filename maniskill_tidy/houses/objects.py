"""Pickupable objects: put 15-40 of them where D is true, on tops and inside containers.

Also the geometry shared with task generation: where an object of a given size can go on a
surface (or on the floor) without touching other objects, and whether an agent can reach it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from maniskill_tidy.houses.furnish import GAP, overlaps
from maniskill_tidy.houses.navgrid import GridFrame, main_component, reach_cells
from maniskill_tidy.houses.schema import (
    CELL,
    Furniture,
    House,
    PlacedObject,
    Surface,
    rotated_bounds,
)
from maniskill_tidy.knowledge import FLOOR, load_catalog, load_placement

MIN_OBJECTS, MAX_OBJECTS = 15, 40
ATTEMPTS = 600


def is_hanging(surface: Surface) -> bool:
    """Towel bars and paper hangers: objects hang below the bar instead of resting on it."""
    return surface.name == "bar"


@dataclass
class SurfaceSlot:
    furniture: Furniture
    surface: Surface
    room_type: str
    center: list[float]
    bounds: tuple[float, float, float, float]


def surface_slots(house: House) -> list[SurfaceSlot]:
    room_types = {r.id: r.type for r in house.rooms}
    slots = []
    for f in house.furniture:
        for s in f.surfaces:
            center, bounds = f.surface_world(s)
            slots.append(SurfaceSlot(f, s, room_types[f.room], center, bounds))
    return slots


def object_size(type_name: str) -> list[float]:
    size = load_catalog().info(type_name).size
    return list(size) if size else [0.15, 0.15, 0.15]


def fits(slot: SurfaceSlot, size: list[float]) -> bool:
    w, d = slot.surface.size
    if slot.surface.clearance is not None and size[2] > slot.surface.clearance:
        return False
    return (size[0] <= w and size[1] <= d) or (size[1] <= w and size[0] <= d)


def open_footprint(f) -> tuple[float, float, float, float]:
    """World bounds of ``f`` with its doors and drawers open (they swing out at the front, +y):
    the floor there is hidden from the robots' cameras once the env opens them."""
    extra = 0.0
    for j in f.joints:
        extra = max(extra, j.limits[1] if j.type == "prismatic" else j.link_size[0])
    if extra == 0.0:
        return f.footprint()
    c, s = math.cos(f.yaw), math.sin(f.yaw)
    centre = [f.position[0] - s * extra / 2, f.position[1] + c * extra / 2]
    return rotated_bounds(centre, f.size[0], f.size[1] + extra, f.yaw)


def stacked_footprints(house: House) -> dict[str, list[tuple[float, float, float, float]]]:
    """Footprints of the pieces standing on each piece's top (a microwave on a counter): they
    take room there as objects do. A piece that overhangs its parent onto a neighbouring top
    (a microwave across the joint of an L-shaped counter's two strips) takes room on both."""
    tops = [
        (g.id, *g.surface_world(s)) for g in house.furniture for s in g.surfaces if s.name == "top"
    ]
    out: dict[str, list] = {}
    for f in house.furniture:
        if not f.parent:
            continue
        fp, base, top = f.footprint(), f.position[2], f.position[2] + f.size[2]
        under = {f.parent} | {
            gid
            for gid, centre, bounds in tops
            if gid != f.id and base - 0.05 <= centre[2] < top and overlaps(fp, bounds, -1e-3)
        }
        for gid in sorted(under):
            out.setdefault(gid, []).append(fp)
    return out


class ObjectPlacer:
    """Finds free spots for objects on surfaces and on the floor of one house."""

    def __init__(
        self, house: House, frame: GridFrame, free: np.ndarray, rng: np.random.Generator
    ) -> None:
        self.house, self.frame, self.rng = house, frame, rng
        self.walkable = main_component(free)
        self.free = free
        self.slots = surface_slots(house)
        self.children = stacked_footprints(house)

    def obstacles(self, receptacle: str, surface: str | None, ignore: str | None = None) -> list:
        out = [
            o.footprint()
            for o in self.house.objects
            if o.receptacle == receptacle and o.surface == surface and o.id != ignore
        ]
        if surface == "top":
            out += self.children.get(receptacle, [])
        return out

    def spot_on(
        self, slot: SurfaceSlot, size: list[float], ignore: str | None = None
    ) -> tuple[list[float], float] | None:
        """A free pose for an object of ``size`` on ``slot``, or None."""
        if not fits(slot, size):
            return None
        others = self.obstacles(slot.furniture.id, slot.surface.name, ignore)
        x0, y0, x1, y1 = slot.bounds
        for _ in range(12):
            yaw = float(self.rng.choice([0.0, math.pi / 2]))
            w, d = (size[0], size[1]) if yaw == 0.0 else (size[1], size[0])
            if w > x1 - x0 or d > y1 - y0:
                continue
            x = float(self.rng.uniform(x0 + w / 2, x1 - w / 2))
            y = float(self.rng.uniform(y0 + d / 2, y1 - d / 2))
            fp = (x - w / 2, y - d / 2, x + w / 2, y + d / 2)
            if any(overlaps(fp, o, GAP) for o in others):
                continue
            if not reach_cells(self.frame, self.walkable, fp).any():
                continue
            z = slot.center[2] - size[2] if is_hanging(slot.surface) else slot.center[2]
            return [x, y, z], yaw
        return None

    def floor_spot(
        self, room_id: str, size: list[float], ignore: str | None = None
    ) -> tuple[list[float], float] | None:
        """A spot on the floor of ``room_id`` that is not on a walkable cell (so the object does
        not change the navigation grid), clear of furniture and objects, next to a walkable cell.
        """
        room = self.house.room(room_id)
        inner = self.frame.room_mask(room, margin=max(size[0], size[1]) / 2 + 0.06)
        candidates = np.argwhere(inner & ~self.free)
        if len(candidates) == 0:
            return None
        floor_fps = [open_footprint(f) for f in self.house.furniture if f.parent is None]
        floor_fps += [
            o.footprint() for o in self.house.objects if o.receptacle == FLOOR and o.id != ignore
        ]
        for idx in self.rng.permutation(len(candidates))[:40]:
            r, c = candidates[idx]
            x, y = float(self.frame.x[c]), float(self.frame.y[r])
            yaw = float(self.rng.choice([0.0, math.pi / 2]))
            w, d = (size[0], size[1]) if yaw == 0.0 else (size[1], size[0])
            fp = (x - w / 2, y - d / 2, x + w / 2, y + d / 2)
            if any(overlaps(fp, o, GAP) for o in floor_fps):
                continue
            if not reach_cells(self.frame, self.walkable, fp, reach=CELL * 1.5).any():
                continue
            return [x, y, 0.0], yaw
        return None

    def populate(self) -> None:
        """Add MIN_OBJECTS..MAX_OBJECTS objects, each where D is true."""
        catalog, knowledge = load_catalog(), load_placement()
        target = int(self.rng.integers(MIN_OBJECTS, MAX_OBJECTS + 1))
        weights = np.array(
            [math.sqrt(max(s.surface.size[0] * s.surface.size[1], 1e-3)) for s in self.slots]
        )
        if len(self.slots) == 0:
            return
        p = weights / weights.sum()
        counts: dict[str, int] = {}
        for _ in range(ATTEMPTS):
            if len(self.house.objects) >= target:
                break
            slot = self.slots[int(self.rng.choice(len(self.slots), p=p))]
            types = [
                o
                for o in catalog.tidyable
                if knowledge.D(o, slot.surface.receptacle_type, slot.room_type)
                and fits(slot, object_size(o))
            ]
            if not types:
                continue
            tw = np.array([1.0 / (1 + counts.get(t, 0)) ** 2 for t in types])
            type_name = types[int(self.rng.choice(len(types), p=tw / tw.sum()))]
            size = object_size(type_name)
            spot = self.spot_on(slot, size)
            if spot is None:
                continue
            pos, yaw = spot
            counts[type_name] = counts.get(type_name, 0) + 1
            self.house.objects.append(
                PlacedObject(
                    id=f"{type_name}_{counts[type_name] - 1}",
                    type=type_name,
                    room=slot.furniture.room,
                    receptacle=slot.furniture.id,
                    surface=slot.surface.name,
                    position=pos,
                    yaw=yaw,
                    size=size,
                )
            )
