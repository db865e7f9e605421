"""The ground truth a map is scored against: obstacles rasterised from the house spec."""

from __future__ import annotations

import math

import numpy as np

from maniskill_tidy.houses.schema import House
from maniskill_tidy.perception.map_grid import OBSTACLE, OBSTACLE_BAND, MapFrame


def box_cells(frame: MapFrame, centre, w: float, d: float, yaw: float, pad: float) -> np.ndarray:
    """(rows, cols) bool: cells whose centre lies within ``pad`` of a (w x d) box turned by
    ``yaw`` about ``centre``, measured in the box's own frame."""
    r, c = np.mgrid[0 : frame.shape[0], 0 : frame.shape[1]]
    xy = frame.centres(r, c)
    cos, sin = math.cos(yaw), math.sin(yaw)
    px, py = xy[..., 0] - centre[0], xy[..., 1] - centre[1]
    lx, ly = cos * px + sin * py, -sin * px + cos * py
    return (np.abs(lx) < w / 2 + pad) & (np.abs(ly) < d / 2 + pad)


def ground_truth_obstacles(house: House, frame: MapFrame) -> np.ndarray:
    """(rows, cols) bool: cells that walls (door openings cut out), furniture and objects
    reaching into ``OBSTACLE_BAND`` overlap, rasterised from the house spec.

    A cell counts when the box covers more than a millimetre of it, as a map cell counts when
    any hit falls in it; boxes are tested in their own frame (exact for axis-aligned ones)."""
    from maniskill_tidy.houses.navgrid import solid_wall_segments

    pad = frame.cell / 2 - 1e-3
    boxes = [
        (
            [(a[0] + b[0]) / 2, (a[1] + b[1]) / 2],
            math.dist(a, b),
            t,
            math.atan2(b[1] - a[1], b[0] - a[0]),
        )
        for a, b, t in solid_wall_segments(house)
    ]
    for f in [*house.furniture, *house.objects]:
        z0, z1 = f.position[2], f.position[2] + f.size[2]
        if z1 >= OBSTACLE_BAND[0] and z0 <= OBSTACLE_BAND[1]:
            boxes.append((f.position, f.size[0], f.size[1], f.yaw))
    for f in house.furniture:
        boxes.extend(open_links(f))
    out = np.zeros(frame.shape, dtype=bool)
    for centre, w, d, yaw in boxes:
        out |= box_cells(frame, centre, w, d, yaw, pad)
    return out


def obstacle_iou(top_down: np.ndarray, truth: np.ndarray, region: np.ndarray) -> float:
    """IoU of the map's obstacle channel with ``truth`` over the cells of ``region``."""
    mapped = (top_down[..., OBSTACLE] > 0) & region
    truth = truth & region
    return float((mapped & truth).sum() / max((mapped | truth).sum(), 1))


def open_links(f) -> list[tuple[list[float], float, float, float]]:
    """World (centre, w, d, yaw) of ``f``'s doors and drawers at the episodes' open position."""
    from maniskill_tidy.sim.house_scene import open_position

    out = []
    c, s = math.cos(f.yaw), math.sin(f.yaw)
    for j in f.joints:
        q = open_position(j)
        (lx, ly), (ox, oy) = j.link_center[:2], j.origin[:2]
        yaw = 0.0
        if j.type == "revolute":  # about a vertical hinge through the joint's origin
            angle = q * (1.0 if j.axis[2] >= 0 else -1.0)
            dx, dy = lx - ox, ly - oy
            lx = ox + math.cos(angle) * dx - math.sin(angle) * dy
            ly = oy + math.sin(angle) * dx + math.cos(angle) * dy
            yaw = angle
        else:
            lx, ly = lx + q * j.axis[0], ly + q * j.axis[1]
        centre = [f.position[0] + c * lx - s * ly, f.position[1] + s * lx + c * ly]
        out.append((centre, j.link_size[0], j.link_size[1], f.yaw + yaw))
    return out
