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

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.houses.schema import House
from maniskill_tidy.knowledge import FLOOR
from maniskill_tidy.perception.semantic_map import FramePoints

ON_FLOOR = 0.05  # an object whose lowest point is below this lies on the floor
ON_SURFACE = 0.08  # vertical tolerance between an object's lowest point and a surface


@dataclass(frozen=True)
class Detection:
    seg_id: int
    object_id: str
    type: str
    position: np.ndarray  # median of the object's back-projected pixels (x, y, z)
    bottom: float  # low percentile of their heights
    pixels: int
    distance: float  # metres from the camera to ``position``


def id_counts(seg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The segmentation ids present, ascending, and their counts: ``np.unique(seg,
    return_counts=True)`` by a histogram, several times cheaper for ids as small as ours."""
    counts = np.bincount(np.asarray(seg).ravel())
    ids = np.flatnonzero(counts)
    return ids, counts[ids]


def _groups(frame: FramePoints, instances: dict, kind: str):
    """(instance, points) per instance of ``kind`` covering at least MIN_PIXELS pixels (a
    point of a strided back-projection stands for stride^2 pixels)."""
    ids, counts = id_counts(frame.seg)
    for sid, n in zip(ids, counts, strict=True):
        inst = instances.get(int(sid))
        if inst is None or inst.kind != kind or n * frame.stride**2 < MIN_PIXELS:
            continue
        yield int(sid), inst, frame.points[frame.seg == sid]


def detect_objects(frame: FramePoints, instances: dict) -> list[Detection]:
    """Every object covering at least MIN_PIXELS pixels (with a depth) of the frame."""
    out = []
    for sid, inst, pts in _groups(frame, instances, "object"):
        position = np.median(pts, axis=0)
        out.append(
            Detection(
                sid,
                inst.id,
                inst.type,
                position,
                float(np.percentile(pts[:, 2], 5)),
                len(pts) * frame.stride**2,
                float(np.linalg.norm(position - frame.camera)),
            )
        )
    return out


def seen_robots(frame: FramePoints, instances: dict) -> dict[str, np.ndarray]:
    """Robot name -> (x, y) of the robots in view (the middle of their visible surface)."""
    return {
        inst.id: np.median(pts[:, :2], axis=0)
        for _, inst, pts in _groups(frame, instances, "robot")
    }


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


def resting_place(
    house: House, d: Detection, surfaces: list[SurfaceSpot]
) -> tuple[str, str | None, str | None]:
    """(receptacle id or Floor, surface name, room id) under a detection; ("", None, None) if
    it rests on nothing known (e.g. it is being carried)."""
    x, y = float(d.position[0]), float(d.position[1])
    if d.bottom < ON_FLOOR:
        return FLOOR, None, house.room_at(x, y)
    best = None
    for s in surfaces:
        x0, y0, x1, y1 = s.bounds
        if not (x0 - 0.05 <= x <= x1 + 0.05 and y0 - 0.05 <= y <= y1 + 0.05):
            continue
        gap = abs(d.bottom - s.height)
        if gap < ON_SURFACE and (best is None or gap < best[0]):
            best = (gap, s)
    if best is None:
        return "", None, None
    return best[1].furniture, best[1].surface, best[1].room
