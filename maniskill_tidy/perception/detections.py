"""Objects and explored cells from one agent's RGB-D + segmentation frame.

Approximation, stated everywhere results are shown: the segmentation is the renderer's ground
truth (instance ids with their type), standing in for a trained detector such as the paper's
Mask R-CNN. Positions are measured, not looked up: pixels are back-projected with the depth and
the camera matrices. Where an object rests is read from the house's furniture spec (public
information, like a floor plan): the surface under the measured position.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.houses.schema import House
from maniskill_tidy.knowledge import FLOOR

MAX_RANGE = 2.0  # metres: cells further away are seen too flatly to find small objects
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


def backproject(
    depth: np.ndarray, intrinsics: np.ndarray, extrinsics: np.ndarray, mask: np.ndarray
) -> np.ndarray:
    """World points (N, 3) of the pixels in ``mask`` with a depth (OpenCV camera model)."""
    v, u = np.nonzero(mask & (depth > 0))
    z = depth[v, u].astype(np.float64)
    fx, fy, cx, cy = intrinsics[0, 0], intrinsics[1, 1], intrinsics[0, 2], intrinsics[1, 2]
    cam = np.stack([(u + 0.5 - cx) * z / fx, (v + 0.5 - cy) * z / fy, z], axis=1)
    cam_to_world = np.linalg.inv(extrinsics)
    return cam @ cam_to_world[:3, :3].T + cam_to_world[:3, 3]


def detect_objects(obs: dict, instances: dict) -> list[Detection]:
    seg, depth = obs["segmentation"], obs["depth"]
    ids, counts = np.unique(seg, return_counts=True)
    out = []
    for sid, n in zip(ids, counts, strict=True):
        inst = instances.get(int(sid))
        if inst is None or inst.kind != "object" or n < MIN_PIXELS:
            continue
        pts = backproject(depth, obs["intrinsics"], obs["extrinsics"], seg == sid)
        if len(pts) == 0:
            continue
        out.append(
            Detection(
                int(sid),
                inst.id,
                inst.type,
                np.median(pts, axis=0),
                float(np.percentile(pts[:, 2], 5)),
                int(n),
            )
        )
    return out


def explored_cells(obs: dict, house: House, stride: int = 4) -> set[tuple[int, int]]:
    """Grid cells with a back-projected point (floor, furniture or wall) within range."""
    depth = obs["depth"][::stride, ::stride]
    mask = (depth > 0) & (depth < MAX_RANGE)
    k = obs["intrinsics"].copy()
    k[:2] /= stride
    pts = backproject(depth, k, obs["extrinsics"], mask)
    nav = house.navgrid
    rows = np.floor((pts[:, 1] - nav.origin[1]) / nav.cell).astype(int)
    cols = np.floor((pts[:, 0] - nav.origin[0]) / nav.cell).astype(int)
    return set(zip(rows.tolist(), cols.tolist(), strict=True))


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
