"""The map's grid and what its cells and voxels hold: the frame that the map, its crops,
its frontiers and the ground truth share."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from maniskill_tidy.houses.schema import House

UNKNOWN, FLOOR_LABEL, WALL_LABEL, FIRST_CATEGORY = 0, 1, 2, 3


OBSTACLE, EXPLORED, FIRST_CHANNEL = 0, 1, 2


OBSTACLE_BAND = (0.05, 1.6)  # metres above the floor that block a robot (the tallest is ~1.1 m)


@dataclass(frozen=True)
class MapFrame:
    """Where the map's cells lie: (x0, y0) of cell (0, 0)'s corner; rows run along +y."""

    origin: tuple[float, float]
    shape: tuple[int, int]
    cell: float

    @classmethod
    def of_house(cls, house: House, cell: float) -> MapFrame:
        nav = house.navgrid
        if nav is None:
            raise ValueError(f"house {house.id} has no navigation grid; generate it first")
        ratio = nav.cell / cell
        if abs(ratio - round(ratio)) > 1e-6:
            raise ValueError(
                f"map cell {cell} m must divide the planner cell {nav.cell} m "
                "(e.g. 0.05 or 0.125) so that map cells nest in planner cells"
            )
        n = round(ratio)
        return cls((nav.origin[0], nav.origin[1]), (nav.shape[0] * n, nav.shape[1] * n), cell)

    def cells_of(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(rows, cols) of world points (N, 2); may lie outside the map."""
        cols = np.floor((xy[:, 0] - self.origin[0]) / self.cell).astype(np.int64)
        rows = np.floor((xy[:, 1] - self.origin[1]) / self.cell).astype(np.int64)
        return rows, cols

    def centres(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        return np.stack(
            [self.origin[0] + (cols + 0.5) * self.cell, self.origin[1] + (rows + 0.5) * self.cell],
            axis=-1,
        )


def label_table(instances: dict, categories: tuple[str, ...]) -> np.ndarray:
    """Segmentation id -> voxel label: floor, wall, 3 + category index; robots and empty 0."""
    index = {name: i for i, name in enumerate(categories)}
    table = np.zeros(max(instances, default=0) + 1, dtype=np.uint8)
    for sid, inst in instances.items():
        if inst.kind == "floor":
            table[sid] = FLOOR_LABEL
        elif inst.kind == "wall":
            table[sid] = WALL_LABEL
        elif inst.type in index:
            table[sid] = FIRST_CATEGORY + index[inst.type]
    return table


def id_counts(seg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The segmentation ids present, ascending, and their counts: ``np.unique(seg,
    return_counts=True)`` by a histogram, several times cheaper for ids as small as ours."""
    counts = np.bincount(np.asarray(seg).ravel())
    ids = np.flatnonzero(counts)
    return ids, counts[ids]
