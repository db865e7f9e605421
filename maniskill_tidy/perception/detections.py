"""Objects and robots in one agent's frame, read off the semantic map's back-projected points.

Approximation, stated everywhere results are shown: the segmentation is the renderer's ground
truth (instance ids with their type), standing in for a trained detector such as the paper's
Mask R-CNN. Positions are measured, not looked up: they come from the pixels that
``SemanticMap.update`` back-projected with the depth and the camera matrices (the project's
one back-projection path, ``SemanticMap.last_frame``). Where an object rests is read from the
house's furniture spec (public information, like a floor plan): the surface under the measured
position.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.houses.schema import House
from maniskill_tidy.knowledge import FLOOR
from maniskill_tidy.perception.semantic_map import FramePoints

ON_FLOOR = 0.05  # an object whose lowest point is below this lies on the floor
ON_SURFACE = 0.08  # vertical tolerance between an object's lowest point and a surface
EDGE = 0.05  # metres around a surface's rectangle where a position still counts as over it


@dataclass(frozen=True)
class Detection:
    seg_id: int
    object_id: str
    type: str
    position: np.ndarray  # median of the object's back-projected pixels (x, y, z)
    bottom: float  # low percentile of their heights
    pixels: int
    distance: float  # metres from the camera to ``position``


LOW = 5  # percentile of an object's heights taken as its lowest point (robust to stray pixels)


def _instances(frame: FramePoints, instances: dict, kind: str) -> list[tuple[int, object]]:
    """(segmentation id, instance) of every instance of ``kind`` covering at least MIN_PIXELS
    pixels (a point of a strided back-projection stands for stride^2 pixels), ids ascending."""
    ids, counts = frame.id_counts
    out = []
    for sid, n in zip(ids.tolist(), counts.tolist(), strict=True):  # Python ints: cheaper
        inst = instances.get(sid)
        if inst is not None and inst.kind == kind and n * frame.stride**2 >= MIN_PIXELS:
            out.append((sid, inst))
    return out


@njit(cache=True, nogil=True)
def point_stats(seg, points, ids, q):
    """Per id of ``ids`` (ascending, each in ``seg``): how many points carry it, their median
    and the ``q`` quantile of their heights, in one pass over the points instead of a mask,
    ``np.median`` and ``np.percentile`` per instance (their overhead was most of a detection's
    cost). The values are numpy's: the median is the middle value, or the float32 mean of the
    two middle ones; the quantile is ``np.percentile``'s default ('linear') with a Python
    number as q (``tests/test_semantic_map.py`` compares both). Which of several equal values
    a sort picks does not matter: back-projected points never carry -0.0, so they are equal bits."""
    slot = np.full(ids[-1] + 1, -1, np.int64)
    for i in range(len(ids)):
        slot[ids[i]] = i
    count = np.zeros(len(ids), np.int64)
    for j in range(len(seg)):
        s = seg[j]
        if 0 <= s < len(slot) and slot[s] >= 0:
            count[slot[s]] += 1
    start = np.zeros(len(ids) + 1, np.int64)
    for i in range(len(ids)):
        start[i + 1] = start[i] + count[i]
    grouped = np.empty((start[-1], 3), points.dtype)
    fill = start[:-1].copy()
    for j in range(len(seg)):
        s = seg[j]
        if 0 <= s < len(slot) and slot[s] >= 0:
            grouped[fill[slot[s]]] = points[j]
            fill[slot[s]] += 1
    median = np.empty((len(ids), 3), points.dtype)
    low = np.empty(len(ids), points.dtype)
    for i in range(len(ids)):
        n, half = count[i], count[i] // 2
        for axis in range(3):
            v = np.sort(grouped[start[i] : start[i + 1], axis])
            median[i, axis] = v[half] if n % 2 else (v[half - 1] + v[half]) / v.dtype.type(2)
        # np.percentile's linear method: the virtual index (n - 1) q in float64, its floor
        # (the last value at or past the end), the weight in the values' precision
        virtual = (n - 1) * q
        below = -1 if virtual >= n - 1 else np.int64(np.floor(virtual))
        a, b = v[below], v[below + 1 if below >= 0 else -1]
        gamma = virtual - below
        diff = b - a
        if gamma >= 0.5:
            low[i] = b - diff * v.dtype.type(1 - gamma)
        else:
            low[i] = a + diff * v.dtype.type(gamma)
    return count, median, low


def detect_objects(frame: FramePoints, instances: dict) -> list[Detection]:
    """Every object covering at least MIN_PIXELS pixels (with a depth) of the frame."""
    found = _instances(frame, instances, "object")
    if not found:
        return []
    ids = np.array([sid for sid, _ in found])
    count, median, low = point_stats(frame.seg, frame.points, ids, LOW / 100)
    return [
        Detection(
            sid,
            inst.id,
            inst.type,
            median[i],
            float(low[i]),
            int(count[i]) * frame.stride**2,
            float(np.linalg.norm(median[i] - frame.camera)),
        )
        for i, (sid, inst) in enumerate(found)
    ]


def seen_robots(frame: FramePoints, instances: dict) -> dict[str, np.ndarray]:
    """Robot name -> (x, y) of the robots in view (the middle of their visible surface)."""
    found = _instances(frame, instances, "robot")
    if not found:
        return {}
    ids = np.array([sid for sid, _ in found])
    _, median, _ = point_stats(frame.seg, frame.points, ids, LOW / 100)
    return {inst.id: median[i, :2] for i, (_, inst) in enumerate(found)}


@dataclass(frozen=True)
class SurfaceSpot:
    furniture: str
    surface: str
    room: str
    height: float
    bounds: tuple[float, float, float, float]


def surface_table(house: House) -> list[SurfaceSpot]:
    """Every surface of the house in world coordinates, computed once per house."""
    out = []
    for f in house.furniture:
        for s in f.surfaces:
            centre, bounds = f.surface_world(s)
            out.append(SurfaceSpot(f.id, s.name, f.room, centre[2], bounds))
    return out


def surfaces_under(x: float, y: float, surfaces: list[SurfaceSpot]) -> list[SurfaceSpot]:
    """The surfaces whose rectangle, widened by EDGE, holds (x, y): a measured position near a
    surface's edge may fall just outside it."""
    return [s for s in surfaces
            if s.bounds[0] - EDGE <= x <= s.bounds[2] + EDGE
            and s.bounds[1] - EDGE <= y <= s.bounds[3] + EDGE]  # fmt: skip


def resting_place(
    house: House, d: Detection, surfaces: list[SurfaceSpot]
) -> tuple[str, str | None, str | None]:
    """(receptacle id or Floor, surface name, room id) under a detection; ("", None, None) if
    it rests on nothing known (e.g. it is being carried)."""
    x, y = float(d.position[0]), float(d.position[1])
    if d.bottom < ON_FLOOR:
        return FLOOR, None, house.room_at(x, y)
    best = None
    for s in surfaces_under(x, y, surfaces):
        gap = abs(d.bottom - s.height)
        if gap < ON_SURFACE and (best is None or gap < best[0]):
            best = (gap, s)
    if best is None:
        return "", None, None
    return best[1].furniture, best[1].surface, best[1].room
