"""v2's environment map, made by the project: a room seen from its middle, as a lat-long image.

SAPIEN lights v2's glossy and rough surfaces from an environment map. No map that installs
offline states its origin and a licence this package may ship (mani-skill's ``default.hdr``
names neither), so the derivation paints one: a dim ceiling with a lamp at the zenith, walls
that brighten towards four windows of daylight, a warm floor below the horizon. svulkan2 reads
the ``.hdr`` as 8-bit, so radiance is kept in [0, 1]: the windows and the lamp at 1.
"""

from __future__ import annotations

import numpy as np

CEILING = np.array([0.18, 0.185, 0.2])
WALL_TOP = np.array([0.22, 0.22, 0.24])
WALL_LOW = np.array([0.19, 0.19, 0.205])
FLOOR_NEAR = np.array([0.2, 0.195, 0.19])  # the floor at the walls
FLOOR = np.array([0.32, 0.31, 0.295])  # under the robot
DAYLIGHT = np.array([1.0, 1.0, 1.0])
WINDOWS = (0.0, 90.0, 180.0, 270.0)  # azimuths of the window centres, degrees
WINDOW_WIDTH = 16.0  # degrees of azimuth
WINDOW_SPAN = (6.0, 38.0)  # elevations of the sill and the lintel, degrees
LAMP = 8.0  # degrees from the zenith that the ceiling lamp covers
EDGE = 3.0  # degrees over which one band fades into the next


def _step(x: np.ndarray, at: float) -> np.ndarray:
    """0 below ``at``, 1 above, a smoothstep over :data:`EDGE` degrees between."""
    t = np.clip((x - at) / EDGE + 0.5, 0.0, 1.0)
    return t * t * (3 - 2 * t)


def room_map(width: int = 256, height: int = 128) -> np.ndarray:
    """The map as linear RGB in [0, 1], (height, width, 3) float32; row 0 looks straight up."""
    elevation = 90.0 - (np.arange(height) + 0.5) * 180.0 / height  # degrees, per row
    azimuth = (np.arange(width) + 0.5) * 360.0 / width  # degrees, per column
    e = elevation[:, None, None]
    a = azimuth[None, :, None]
    wall = WALL_LOW + (WALL_TOP - WALL_LOW) * np.clip(e / 60.0, 0.0, 1.0)
    floor = FLOOR + (FLOOR_NEAR - FLOOR) * np.clip((e + 90.0) / 80.0, 0.0, 1.0)
    image = floor + (wall - floor) * _step(e, -8.0)  # floor below, walls above
    image = image + (CEILING - image) * _step(e, 62.0)
    image = image + (DAYLIGHT - image) * _step(e, 90.0 - LAMP)
    off = np.min([np.abs((a - c + 180.0) % 360.0 - 180.0) for c in WINDOWS], axis=0)
    window = (1 - _step(off, WINDOW_WIDTH / 2)) * _step(e, WINDOW_SPAN[0])
    window = window * (1 - _step(e, WINDOW_SPAN[1]))
    image = image + (DAYLIGHT - image) * window
    image = np.broadcast_to(image, (height, width, 3))
    return np.ascontiguousarray(image.clip(0.0, 1.0), dtype=np.float32)
