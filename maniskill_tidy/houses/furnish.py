"""Furnishing: put furniture in rooms as the placement annotations say, keeping the house navigable.

Each piece is tried at random poses for its stance (against a wall, in a corner, in the middle,
on a counter, mounted on a wall). A pose is kept only when the footprint stays inside the room,
clear of other pieces, of door approaches and of the space in front of other pieces, and when
afterwards every free cell is still 4-connected to every other and every surface (old and new)
still has a free cell within reach. Pieces that find no such pose are left out.
"""

from __future__ import annotations

import math

import numpy as np

from maniskill_tidy.houses.furniture import ON_HOST, ROOM_FURNITURE, TEMPLATES, parts_for
from maniskill_tidy.houses.navgrid import (
    GridFrame,
    components,
    furniture_blocked,
    reach_cells,
)
from maniskill_tidy.houses.schema import WALL_THICKNESS, Door, Furniture, Room, rotated_bounds

FRONT_CLEARANCE = 0.6  # free floor kept in front of pieces with doors, drawers or surfaces
DOOR_KEEPOUT = 1.0  # free floor kept on both sides of a doorway
TRIES = 25
GAP = 0.02
# yaw that makes a piece's front (local +y) face into the room from each wall side
SIDE_YAW = {"south": 0.0, "north": math.pi, "west": -math.pi / 2, "east": math.pi / 2}


def overlaps(
    a: tuple[float, float, float, float], b: tuple[float, float, float, float], gap: float = 0.0
) -> bool:
    return a[0] < b[2] + gap and b[0] < a[2] + gap and a[1] < b[3] + gap and b[1] < a[3] + gap


def front_zone(f: Furniture) -> tuple[float, float, float, float] | None:
    if not (f.surfaces or f.joints) or TEMPLATES.get(f.type, None) is None:
        return None
    depth = FRONT_CLEARANCE
    c, s = math.cos(f.yaw), math.sin(f.yaw)
    off = f.size[1] / 2 + depth / 2
    center = [f.position[0] - s * off, f.position[1] + c * off]
    return rotated_bounds(center, f.size[0], depth, f.yaw)


class RoomFurnisher:
    """Places furniture into one house, room by room, sharing one navigation grid."""

    def __init__(
        self,
        frame: GridFrame,
        free: np.ndarray,
        rooms: list[Room],
        doors: list[Door],
        door_axes: dict[str, str],
        rng: np.random.Generator,
    ) -> None:
        self.frame, self.free, self.rng = frame, free, rng
        self.rooms, self.doors, self.door_axes = rooms, doors, door_axes
        self.placed: list[Furniture] = []
        self.reach_needed: list[tuple[float, float, float, float]] = []

    # -- poses -------------------------------------------------------------------------------
    def _pose(self, room: Room, stance: str, size: list[float]) -> tuple[list[float], float] | None:
        x0, y0, x1, y1 = room.bounds()
        m = WALL_THICKNESS / 2 + 0.01
        w, d = size[0], size[1]
        rng = self.rng
        if stance == "middle":
            yaw = float(rng.choice([0.0, math.pi / 2, math.pi, -math.pi / 2]))
            bx0, by0, bx1, by1 = rotated_bounds([0, 0], w, d, yaw)
            lo_x, hi_x = x0 + 0.9 - bx0, x1 - 0.9 - bx1
            lo_y, hi_y = y0 + 0.9 - by0, y1 - 0.9 - by1
            if lo_x > hi_x or lo_y > hi_y:
                return None
            return [_q(rng.uniform(lo_x, hi_x)), _q(rng.uniform(lo_y, hi_y))], yaw
        side = str(rng.choice(list(SIDE_YAW)))
        yaw = SIDE_YAW[side]
        along_lo, along_hi = (x0, x1) if side in ("south", "north") else (y0, y1)
        lo, hi = along_lo + m + w / 2, along_hi - m - w / 2
        if lo > hi:
            return None
        if stance == "corner":
            t = lo if rng.uniform() < 0.5 else hi
        else:
            t = _q(rng.uniform(lo, hi))
        depth_at = {
            "south": y0 + m + d / 2,
            "north": y1 - m - d / 2,
            "west": x0 + m + d / 2,
            "east": x1 - m - d / 2,
        }[side]
        xy = [t, depth_at] if side in ("south", "north") else [depth_at, t]
        return xy, yaw

    # -- checks ------------------------------------------------------------------------------
    def _fits(self, f: Furniture, room: Room, keepout: list[tuple]) -> bool:
        x0, y0, x1, y1 = room.bounds()
        fp = f.footprint()
        m = WALL_THICKNESS / 2
        if (
            fp[0] < x0 + m - 1e-6
            or fp[2] > x1 - m + 1e-6
            or fp[1] < y0 + m - 1e-6
            or (fp[3] > y1 - m + 1e-6)
        ):
            return False
        zone = front_zone(f)
        if zone and (zone[0] < x0 or zone[2] > x1 or zone[1] < y0 or zone[3] > y1):
            return False
        floor_piece = f.position[2] == 0.0
        for other in self.placed:
            if other.parent is not None:
                continue
            both_on_floor = floor_piece and other.position[2] == 0.0
            if not both_on_floor and (
                f.position[2] > other.size[2] or other.position[2] > f.size[2]
            ):
                continue  # a wall-mounted piece above a low one
            ofp = other.footprint()
            if overlaps(fp, ofp, GAP):
                return False
            ozone = front_zone(other)
            if ozone and overlaps(fp, ozone) and floor_piece:
                return False
            if zone and overlaps(zone, ofp) and other.position[2] == 0.0:
                return False
        if floor_piece and any(overlaps(fp, k) for k in keepout):
            return False
        return True

    def _navigable_with(self, f: Furniture, blocks: bool) -> np.ndarray | None:
        free = self.free & ~furniture_blocked(self.frame, f) if blocks else self.free
        _, n = components(free)
        if n != 1:
            return None
        needed = list(self.reach_needed)
        needed += [f.surface_world(s)[1] for s in f.surfaces]
        for bounds in needed:
            if not reach_cells(self.frame, free, bounds).any():
                return None
        return free

    # -- placement ---------------------------------------------------------------------------
    def add(self, room: Room, type_name: str, keepout: list[tuple]) -> Furniture | None:
        template = TEMPLATES[type_name]
        size = template.sample_size(self.rng)
        surfaces, joints = parts_for(type_name, size)
        for _ in range(TRIES):
            pose = self._pose(
                room, "wall" if template.stance == "wall_mounted" else template.stance, size
            )
            if pose is None:
                continue
            xy, yaw = pose
            f = Furniture(
                id=f"{type_name}_{len(self.placed)}",
                type=type_name,
                room=room.id,
                position=[xy[0], xy[1], template.elevation],
                yaw=yaw,
                size=size,
                surfaces=surfaces,
                joints=joints,
            )
            if not self._fits(f, room, keepout):
                continue
            free = self._navigable_with(f, template.blocks_navigation)
            if free is None:
                continue
            self.free = free
            self.placed.append(f)
            self.reach_needed += [f.surface_world(s)[1] for s in f.surfaces]
            self._add_children(f)
            return f
        return None

    def _add_children(self, host: Furniture) -> None:
        top = next((s for s in host.surfaces if s.name == "top"), None)
        if top is None:
            return
        cursor = -top.size[0] / 2
        for child_type, p in ON_HOST.get(host.type, []):
            if self.rng.uniform() >= p:
                continue
            t = TEMPLATES[child_type]
            size = t.sample_size(self.rng)
            if t.stance == "on_stand":
                local_x = 0.0
            else:
                local_x = cursor + size[0] / 2 + 0.05
                if local_x + size[0] / 2 > top.size[0] / 2:
                    continue
                cursor = local_x + size[0] / 2
            local_y = -host.size[1] / 2 + size[1] / 2 + 0.04
            c, s = math.cos(host.yaw), math.sin(host.yaw)
            x = host.position[0] + c * local_x - s * local_y
            y = host.position[1] + s * local_x + c * local_y
            surfaces, joints = parts_for(child_type, size)
            child = Furniture(
                id=f"{child_type}_{len(self.placed)}",
                type=child_type,
                room=host.room,
                position=[_q(x, 0.001), _q(y, 0.001), host.position[2] + top.center[2]],
                yaw=host.yaw,
                size=size,
                surfaces=surfaces,
                joints=joints,
                parent=host.id,
            )
            self.placed.append(child)

    def furnish(self, room: Room, walls_of_room: set[str]) -> None:
        keepout = [
            _door_zone(d, self.door_axes[d.id]) for d in self.doors if d.wall in walls_of_room
        ]
        for type_name, p, max_count in ROOM_FURNITURE[room.type]:
            count = sum(self.rng.uniform() < p for _ in range(max_count))
            if p >= 1:
                count = max(count, 1)
            for _ in range(count):
                self.add(room, type_name, keepout)


def _door_zone(door: Door, axis: str) -> tuple[float, float, float, float]:
    half_w = door.width / 2 + 0.2
    if axis == "x":  # wall runs along x: keep clear in +-y
        return (
            door.center[0] - half_w,
            door.center[1] - DOOR_KEEPOUT,
            door.center[0] + half_w,
            door.center[1] + DOOR_KEEPOUT,
        )
    return (
        door.center[0] - DOOR_KEEPOUT,
        door.center[1] - half_w,
        door.center[0] + DOOR_KEEPOUT,
        door.center[1] + half_w,
    )


def _q(v: float, step: float = 0.05) -> float:
    return round(round(float(v) / step) * step, 4)
