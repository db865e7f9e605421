"""Frontiers: free, explored cells next to unexplored ones, where exploring goes next."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from maniskill_tidy.perception.map_grid import EXPLORED, OBSTACLE, MapFrame


@dataclass(frozen=True)
class Frontier:
    """A connected stretch of explored free cells bordering unexplored ones."""

    cells: np.ndarray  # (N, 2) map (row, col)
    centroid: tuple[float, float]  # world (x, y) of the frontier cell nearest the mean

    @property
    def size(self) -> int:
        return len(self.cells)


def find_frontiers(top_down: np.ndarray, frame: MapFrame, min_cells: int = 5) -> list[Frontier]:
    """Frontiers, largest first; clusters under ``min_cells`` cells (noise) are dropped."""
    explored = top_down[..., EXPLORED].astype(bool)
    free = explored & ~top_down[..., OBSTACLE].astype(bool)
    unexplored_near = ndimage.binary_dilation(~explored, structure=np.ones((3, 3), bool))
    edge = free & unexplored_near
    labels, n = ndimage.label(edge, structure=np.ones((3, 3), bool))
    out = []
    for i in range(1, n + 1):
        cells = np.argwhere(labels == i)
        if len(cells) < min_cells:
            continue
        mean = cells.mean(axis=0)
        r, c = cells[np.argmin(((cells - mean) ** 2).sum(axis=1))]
        x, y = frame.centres(np.array(r), np.array(c))
        out.append(Frontier(cells, (float(x), float(y))))
    return sorted(out, key=lambda f: -f.size)
