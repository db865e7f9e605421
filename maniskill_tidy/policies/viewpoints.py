"""Where a robot can stand to see and reach a point: free cells, heading and camera pitch.

Privileged geometry for the expert (and for tests): it reads the house spec, not the cameras,
so a viewpoint still has to be confirmed by what the agent's camera actually sees.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from maniskill_tidy.envs.actions import HORIZON_RANGE, LOOK, REACH
from maniskill_tidy.houses.navgrid import frame_of, grid_array
from maniskill_tidy.houses.schema import House


@dataclass(frozen=True)
class Viewpoint:
    cell: tuple[int, int]
    rotation: int  # degrees, multiple of 90
    horizon: int  # degrees, multiple of 30, positive looks down
    distance: float  # metres, horizontal


def viewpoints(
    house: House,
    point: np.ndarray,
    camera_height: float,
    reach: float = REACH - 0.05,
    side_views: bool = False,
) -> list[Viewpoint]:
    """Free cells within ``reach`` of ``point`` (x, y, z), nearest first, facing it.

    Headings are multiples of 90 degrees: the one nearest the point's direction, and with
    ``side_views`` also the second nearest when the point lies well off to that side too.
    """
    frame, free = frame_of(house.navgrid), grid_array(house.navgrid)
    rows, cols = np.nonzero(free)
    xs, ys = frame.x[cols], frame.y[rows]
    dist = np.hypot(xs - point[0], ys - point[1])
    out = []
    for i in np.argsort(dist, kind="stable"):
        if dist[i] > reach:
            break
        dx, dy = point[0] - xs[i], point[1] - ys[i]
        heading = math.degrees(math.atan2(dy, dx))
        rotation = int(round(heading / 90.0)) * 90 % 360
        rotations = [rotation]
        if side_views and min(abs(dx), abs(dy)) > 0.1:
            other = (int(math.floor(heading / 90.0)) * 90) % 360
            rotations.append(other if other != rotation else (other + 90) % 360)
        for rot in rotations:
            ahead = max(abs(dx) if rot in (0, 180) else abs(dy), 0.05)
            pitch = math.degrees(math.atan2(camera_height - point[2], ahead))
            horizon = int(np.clip(round(pitch / LOOK) * LOOK, *HORIZON_RANGE))
            out.append(Viewpoint((int(rows[i]), int(cols[i])), rot, horizon, float(dist[i])))
    return out
