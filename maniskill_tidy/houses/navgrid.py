"""The 0.25 m navigation grid: which cells an agent can stand on, and what it can reach.

A cell is free when a disc of ``AGENT_RADIUS`` around its centre lies inside a room and touches
no wall (door openings excepted) and no floor-standing furniture. Agents move between
4-neighbouring cells (MoveAhead/Right/Left with 90 degree turns), so connectivity is 4-way.
An agent can interact with a surface or object from a free cell within ``REACH`` metres
(horizontal distance to its footprint; the 1.5 m 3-D reach of AI2-THOR leaves room for height).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from matplotlib.path import Path as PolygonPath
from scipy import ndimage

from maniskill_tidy.houses.schema import AGENT_RADIUS, CELL, House, NavGrid, Room

REACH = 1.0
# How far an arm reaches, horizontally from the robot's centre: the rule of PickUp and PutDown
# (envs/actions.py), which the house checks and repairs need too.
ARM_REACH = 1.5
EPS = 1e-3  # distance tolerance, larger than the 1e-4 rounding of saved coordinates
FOUR_WAY = ndimage.generate_binary_structure(2, 1)


@dataclass
class GridFrame:
    origin: tuple[float, float]
    shape: tuple[int, int]  # rows (y), cols (x)

    def __post_init__(self) -> None:
        rows, cols = self.shape
        self.x = self.origin[0] + (np.arange(cols) + 0.5) * CELL
        self.y = self.origin[1] + (np.arange(rows) + 0.5) * CELL
        self.X, self.Y = np.meshgrid(self.x, self.y)

    @classmethod
    def around(cls, rooms: list[Room]) -> GridFrame:
        xs = [p[0] for r in rooms for p in r.polygon]
        ys = [p[1] for r in rooms for p in r.polygon]
        x0, y0 = math.floor(min(xs) / CELL) * CELL, math.floor(min(ys) / CELL) * CELL
        cols = int(math.ceil((max(xs) - x0) / CELL - 1e-9))
        rows = int(math.ceil((max(ys) - y0) / CELL - 1e-9))
        return cls((x0, y0), (rows, cols))

    def room_mask(self, room: Room, margin: float = 0.0) -> np.ndarray:
        """Cells whose centre is inside ``room`` and at least ``margin`` from its boundary."""
        x0, y0, x1, y1 = room.bounds()
        if len(room.polygon) == 4 and _axis_aligned(room.polygon):
            return (
                (self.X > x0 + margin)
                & (self.X < x1 - margin)
                & (self.Y > y0 + margin)
                & (self.Y < y1 - margin)
            )
        pts = np.stack([self.X.ravel(), self.Y.ravel()], axis=1)
        inside = PolygonPath(room.polygon).contains_points(pts, radius=-2 * margin)
        return inside.reshape(self.shape)

    def segment_distance(self, a: list[float], b: list[float]) -> np.ndarray:
        ax, ay = a
        dx, dy = b[0] - ax, b[1] - ay
        length2 = dx * dx + dy * dy
        t = np.clip(((self.X - ax) * dx + (self.Y - ay) * dy) / max(length2, 1e-12), 0.0, 1.0)
        return np.hypot(self.X - (ax + t * dx), self.Y - (ay + t * dy))

    def rect_distance(self, center: list[float], w: float, d: float, yaw: float) -> np.ndarray:
        """Horizontal distance from every cell centre to a rotated rectangle (0 inside)."""
        c, s = math.cos(yaw), math.sin(yaw)
        px, py = self.X - center[0], self.Y - center[1]
        lx, ly = c * px + s * py, -s * px + c * py
        return np.hypot(np.maximum(np.abs(lx) - w / 2, 0), np.maximum(np.abs(ly) - d / 2, 0))

    def bounds_distance(self, b: tuple[float, float, float, float]) -> np.ndarray:
        x0, y0, x1, y1 = b
        return np.hypot(
            np.maximum(np.maximum(x0 - self.X, self.X - x1), 0),
            np.maximum(np.maximum(y0 - self.Y, self.Y - y1), 0),
        )

    def to_navgrid(self, free: np.ndarray) -> NavGrid:
        rows = ["".join("." if v else "#" for v in row) for row in free]
        return NavGrid(
            origin=[float(self.origin[0]), float(self.origin[1])], shape=list(self.shape), rows=rows
        )


def room_index(house: House) -> np.ndarray:
    """(rows, cols) int: the index in ``house.rooms`` of the room each navigation cell's centre
    lies in, -1 outside every room (a free cell lies in exactly one)."""
    grid = house.navgrid
    frame = GridFrame(tuple(grid.origin), tuple(grid.shape))
    index = np.full(frame.shape, -1, np.int64)
    for i, room in enumerate(house.rooms):
        index[frame.room_mask(room) & (index < 0)] = i
    return index


def _axis_aligned(poly: list[list[float]]) -> bool:
    return all(
        abs(p[0] - q[0]) < 1e-9 or abs(p[1] - q[1]) < 1e-9
        for p, q in zip(poly, poly[1:] + poly[:1], strict=True)
    )


def solid_wall_segments(house: House) -> list[tuple[list[float], list[float], float]]:
    """Wall pieces with door openings cut out: (start, end, thickness)."""
    pieces = []
    for w in house.walls:
        length = math.dist(w.start, w.end)
        cuts = []
        for door in house.doors:
            if door.wall != w.id:
                continue
            t = math.dist(w.start, door.center)
            cuts.append((t - door.width / 2, t + door.width / 2))
        cursor = 0.0
        for s, e in sorted(cuts) + [(length, length)]:
            if s - cursor > 1e-6:
                a = _lerp(w.start, w.end, cursor / length)
                b = _lerp(w.start, w.end, s / length)
                pieces.append((a, b, w.thickness))
            cursor = max(cursor, e)
    return pieces


def _lerp(a: list[float], b: list[float], t: float) -> list[float]:
    return [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]


def structural_free(house: House, frame: GridFrame) -> np.ndarray:
    """Free cells of the empty house: inside rooms, clear of walls."""
    free = np.zeros(frame.shape, dtype=bool)
    for room in house.rooms:
        free |= frame.room_mask(room)
    for a, b, thickness in solid_wall_segments(house):
        free &= frame.segment_distance(a, b) >= AGENT_RADIUS + thickness / 2 - EPS
    return free


def furniture_blocked(frame: GridFrame, f) -> np.ndarray:
    return frame.rect_distance(f.position, f.size[0], f.size[1], f.yaw) < AGENT_RADIUS - EPS


def blocks_navigation(f) -> bool:
    """Furniture that stands on the floor blocks; wall-mounted and stacked pieces do not."""
    from maniskill_tidy.houses.furniture import TEMPLATES

    template = TEMPLATES.get(f.type)
    if f.parent is not None:
        return False
    return template.blocks_navigation if template else f.position[2] < 0.5


def compute_free(house: House, frame: GridFrame | None = None) -> tuple[GridFrame, np.ndarray]:
    frame = frame or GridFrame.around(house.rooms)
    free = structural_free(house, frame)
    for f in house.furniture:
        if blocks_navigation(f):
            free &= ~furniture_blocked(frame, f)
    return frame, free


def components(free: np.ndarray) -> tuple[np.ndarray, int]:
    return ndimage.label(free, structure=FOUR_WAY)


def main_component(free: np.ndarray) -> np.ndarray:
    """The largest 4-connected set of free cells."""
    labels, n = components(free)
    if n == 0:
        return free.copy()
    sizes = np.bincount(labels.ravel())[1:]
    return labels == (int(np.argmax(sizes)) + 1)


def reach_cells(
    frame: GridFrame,
    walkable: np.ndarray,
    bounds: tuple[float, float, float, float],
    reach: float = REACH,
) -> np.ndarray:
    """Walkable cells from which something with footprint ``bounds`` is within reach."""
    return walkable & (frame.bounds_distance(bounds) <= reach + EPS)


def grid_array(nav: NavGrid) -> np.ndarray:
    return np.array([[c == "." for c in row] for row in nav.rows], dtype=bool)


def frame_of(nav: NavGrid) -> GridFrame:
    return GridFrame((nav.origin[0], nav.origin[1]), (nav.shape[0], nav.shape[1]))
