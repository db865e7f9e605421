"""What the decision modules read of a map: the egocentric crop (the paper's G x G), the same
crop folded into one label per cell (what a map message carries), the coarse wide layout, and
the planner grid pooled from the map."""

from __future__ import annotations

import math

import numpy as np

from maniskill_tidy.perception.map_grid import (
    EXPLORED,
    FIRST_CATEGORY,
    FIRST_CHANNEL,
    OBSTACLE,
    MapFrame,
)
from maniskill_tidy.perception.map_kernels import (
    egocentric_cells,
    pooled_bits,
    pooled_ranks,
    pooled_samples,
    sample_shares,
)

UNKNOWN_CODE, FREE_CODE, OBSTACLE_CODE = 0, 1, 2  # crop labels; category k is FIRST_CATEGORY + k


def pool_to_planner(top_down: np.ndarray, planner_shape: tuple[int, int]) -> np.ndarray:
    rows, cols = planner_shape
    n = top_down.shape[0] // rows
    if n * rows != top_down.shape[0] or n * cols != top_down.shape[1]:
        raise ValueError(
            f"map of {top_down.shape[:2]} cells does not tile a {planner_shape} planner grid"
        )
    return top_down.reshape(rows, n, cols, n, -1).max(axis=(1, 3))


def egocentric_crop(
    top_down: np.ndarray, frame: MapFrame, pose, size: int = 20, cell: float = 0.25
) -> np.ndarray:
    """(size, size, channels) crop centred on the agent and turned to its heading.

    Row 0 is the far end ahead of the agent, column 0 its left; the agent stands at the centre.
    A crop cell holds the maximum of the map cells whose centres fall in it (sampled on a grid
    of map-cell spacing), so a 5 cm object is not lost in a 25 cm crop cell. Cells outside the
    map are 0.
    """
    rows, cols, sub = _crop_samples(frame, pose, size, cell)
    return pooled_samples(top_down, rows, cols, size, sub)


def egocentric_bits(
    bits: np.ndarray,
    explored: np.ndarray,
    channels: int,
    frame: MapFrame,
    pose,
    size: int = 20,
    cell: float = 0.25,
) -> np.ndarray:
    """:func:`egocentric_crop` of a 0/1 top-down map of ``channels`` channels held as bits
    per map cell (``bits``, 64 channels a word, the explored channel left out) and its
    ``explored`` cells: the same crop, OR-ing a few words per sample instead of taking the
    maximum of every channel."""
    rows, cols, sub = _crop_samples(frame, pose, size, cell)
    return pooled_bits(bits, explored, rows, cols, size, sub, channels, EXPLORED)


class LabelRanks:
    """Which label a crop cell gets when its samples hold several: small (pickupable) objects
    first, in catalog order, then the other categories, an obstacle, explored free, unknown.

    A column's rank is the lowest of its labels' (the map keeps one per column as it refreshes
    columns), and a crop cell's the lowest of its samples'. That is the label the crop's
    channels, max-pooled and then folded in this order, give: the order is total, so the best
    of the union is the best of the bests.
    """

    def __init__(self, small: np.ndarray) -> None:
        k = len(small)
        self.obstacle, self.free, self.nothing = 2 * k, 2 * k + 1, 2 * k + 2
        categories = np.arange(k)
        self.table = np.full(256, self.nothing, dtype=np.int16)  # voxel label -> rank
        self.table[FIRST_CATEGORY + categories] = np.where(small, categories, k + categories)
        codes = np.empty(2 * k + 3, dtype=np.float32)  # rank -> crop label
        codes[:k] = FIRST_CATEGORY + categories
        codes[k : 2 * k] = FIRST_CATEGORY + categories
        codes[self.obstacle :] = OBSTACLE_CODE, FREE_CODE, UNKNOWN_CODE
        self.codes = codes


def egocentric_labels(
    ranks: np.ndarray,
    explored: np.ndarray,
    label_ranks: LabelRanks,
    frame: MapFrame,
    pose,
    size: int = 20,
    cell: float = 0.25,
) -> np.ndarray:
    """(size, size) float32: :func:`egocentric_crop`'s cells, one label each by
    :class:`LabelRanks` (``FIRST_CATEGORY + k`` for category k, else ``OBSTACLE_CODE``,
    ``FREE_CODE`` or ``UNKNOWN_CODE``), from the map's per-column ranks: one value per sample
    instead of every channel."""
    rows, cols, sub = _crop_samples(frame, pose, size, cell)
    best = pooled_ranks(
        ranks, explored, rows, cols, size, sub, label_ranks.nothing, label_ranks.free
    )
    return label_ranks.codes[best]


WIDE_SIZE = 20  # cells of the wide layout


WIDE_CELL = 1.0  # metres per wide-layout cell: 20 m across, most of a house


WIDE_SAMPLES = 4  # samples per cell side (every 0.25 m, the planner's grid)


def wide_layout(
    top_down: np.ndarray,
    frame: MapFrame,
    pose,
    size: int = WIDE_SIZE,
    cell: float = WIDE_CELL,
    samples: int = WIDE_SAMPLES,
) -> np.ndarray:
    """(size, size, 3) uint8: per coarse cell, the share (0-255) of obstacle, explored and
    any-object samples, oriented as :func:`egocentric_crop`.

    The 5 m crop rarely holds the frontier an exploring teacher heads for; this coarse view of
    the agent's own map does, and shares keep a half-explored cell apart from an explored one.
    """
    rows, cols = _egocentric_cells(frame, pose, size, cell, samples)
    return sample_shares(top_down, rows, cols, size, samples, OBSTACLE, EXPLORED, FIRST_CHANNEL)


def _crop_samples(frame: MapFrame, pose, size: int, cell: float):
    """The crop's sample cells at map-cell spacing, ``sub`` x ``sub`` per crop cell: (rows,
    cols, sub) for the pooling kernels."""
    sub = max(int(round(cell / frame.cell)), 1)
    return (*_egocentric_cells(frame, pose, size, cell, sub), sub)


def _egocentric_cells(frame: MapFrame, pose, size: int, cell: float, sub: int):
    """Map rows and columns (may lie off the map) of the ``sub`` x ``sub`` sample points per
    crop cell, in (size, sub, size, sub) order."""
    x, y, rotation = (float(v) for v in pose)
    yaw = math.radians(rotation)
    fwd = np.array([math.cos(yaw), math.sin(yaw)])
    right = np.array([math.sin(yaw), -math.cos(yaw)])
    offsets = (np.arange(size * sub) + 0.5) / sub - size / 2  # crop cells from the centre
    ahead = -offsets * cell  # row index grows away from "ahead"
    side = offsets * cell
    origin = np.asarray(frame.origin, dtype=np.float64)
    return egocentric_cells(x, y, fwd, right, ahead, side, origin, float(frame.cell))
