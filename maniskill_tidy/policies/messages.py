"""What camera-only teams put on the channel, in the paper's sizes (Section 6, ACm).

- **state** (10 values): capability ``va`` (3), pose ``(x, y, rot)`` in metres and degrees (3)
  and the sub-task ``(kind, o, p, r)`` (4): kind 0 Explore, 1 Place, 2 Park (going to stop
  for good), then the catalog index of the object type, of the receptacle type and the room
  type index, -1 where none.
- **map** (400 values): the sender's semantic-map crop ``G x G = 20 x 20`` around it
  (``SemanticMap.local_crop``, 0.25 m cells, turned to its heading), one value per cell: the
  ``(K + 2)`` channels folded into a label as the map's voxels are labelled (0 unknown,
  1 explored free, 2 obstacle, ``3 + k`` category k, small objects before furniture:
  ``SemanticMap.label_crop``), and ``-(3 + k)`` where the sender judges an object of category
  k misplaced.
- **assignment** (6 values, from a central node): ``(kind, o, x, y, z, 0)`` with kind 0 none,
  1 fetch the object of type o near (x, y, z), 2 explore around (x, y).

A broadcast of state and map to the two others of Setting I costs 2 x 410 = 820 per agent and
step, the paper's figure for BroadComm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from maniskill_tidy.knowledge import ROOM_TYPES, load_catalog
from maniskill_tidy.perception.map_grid import FIRST_CATEGORY
from maniskill_tidy.perception.semantic_map import SemanticMap
from maniskill_tidy.policies.base import EXPLORE, PLACE, SubTask

STATE_DIMS = 10
ASSIGNMENT_DIMS = 6
KINDS = (EXPLORE, PLACE, "Park")
NONE, FETCH, EXPLORE_AREA = 0, 1, 2


@dataclass(frozen=True)
class State:
    capability: tuple[int, int, int]
    pose: tuple[float, float, int]  # x, y (metres), rotation (degrees)
    subtask: SubTask

    @property
    def parking(self) -> bool:
        return self.subtask.kind == "Park"


def _index(names, name: str) -> int:
    return list(names).index(name) if name else -1


def _name(names, i: float) -> str:
    return names[int(i)] if i >= 0 else ""


def encode_state(capability, pose, subtask: SubTask) -> np.ndarray:
    categories = load_catalog().categories
    return np.array(
        [
            *capability,
            *pose,
            KINDS.index(subtask.kind),
            _index(categories, subtask.object_type),
            _index(categories, subtask.receptacle_type),
            _index(ROOM_TYPES, subtask.room_type),
        ],
        dtype=np.float32,
    )


def decode_state(v: np.ndarray) -> State:
    if v.size != STATE_DIMS:
        raise ValueError(f"a state message has {STATE_DIMS} values, got {v.size}")
    categories = load_catalog().categories
    subtask = SubTask(
        KINDS[int(v[6])], _name(categories, v[7]), _name(categories, v[8]), _name(ROOM_TYPES, v[9])
    )
    return State(tuple(int(c) for c in v[:3]), (float(v[3]), float(v[4]), int(v[5])), subtask)


# ---------------------------------------------------------------------- map crop
def crop_cell_centres(pose, size: int, cell: float) -> np.ndarray:
    """(size, size, 2) world (x, y) of the crop cells' centres (``egocentric_crop``'s layout:
    row 0 furthest ahead, column 0 on the left, the agent in the middle)."""
    x, y, rotation = (float(v) for v in pose)
    yaw = math.radians(rotation)
    return _centres(x, y, math.cos(yaw), math.sin(yaw), size, cell)


@njit(cache=True, nogil=True)
def _centres(x, y, cos, sin, size, cell):
    """:func:`crop_cell_centres` as numpy computed it from a meshgrid: (x, y) + ahead * forward
    + side * right in float64, left to right."""
    out = np.empty((size, size, 2), np.float64)
    for i in range(size):
        ahead = -((i + 0.5 - size / 2) * cell)
        for j in range(size):
            side = (j + 0.5 - size / 2) * cell
            out[i, j, 0] = (x + ahead * cos) + side * sin
            out[i, j, 1] = (y + ahead * sin) + side * -cos
    return out


def encode_crop(
    semantic_map: SemanticMap, pose, misplaced: list[tuple[str, np.ndarray]]
) -> np.ndarray:
    """The sender's crop as ``G x G`` labels; ``misplaced``: (type, position) it judges so."""
    cfg = semantic_map.config
    labels = semantic_map.label_crop(pose)
    if misplaced:
        centres = crop_cell_centres(pose, cfg.crop_size, cfg.crop_cell).reshape(-1, 2)
        index = {c: i for i, c in enumerate(semantic_map.categories)}
        for object_type, position in misplaced:
            d = np.abs(centres - np.asarray(position[:2])).max(axis=1)
            i = int(np.argmin(d))
            if d[i] <= cfg.crop_cell / 2 + 1e-6 and object_type in index:
                labels.reshape(-1)[i] = -(FIRST_CATEGORY + index[object_type])
    return labels.reshape(-1)


@dataclass(frozen=True)
class CropCells:
    """A received crop in the receiver's planner grid."""

    explored: tuple[np.ndarray, np.ndarray]  # (rows, cols) of cells the sender has seen
    misplaced: list[tuple[str, tuple[float, float]]]  # (type, world x, y of the cell centre)


def decode_crop(crop: np.ndarray, pose, navgrid, size: int = 20, cell: float = 0.25) -> CropCells:
    """Where the sender's crop lies on the planner grid: explored cells, misplaced objects."""
    if crop.size != size * size:
        raise ValueError(f"a map message has {size * size} values, got {crop.size}")
    categories = load_catalog().categories
    labels = crop.reshape(-1)
    # Crop cells straddle planner cells by half a cell: nudge each centre into one of them.
    xy = crop_cell_centres(pose, size, cell).reshape(-1, 2) + 1e-3
    rows = np.floor((xy[:, 1] - navgrid.origin[1]) / navgrid.cell).astype(np.int64)
    cols = np.floor((xy[:, 0] - navgrid.origin[0]) / navgrid.cell).astype(np.int64)
    on = (rows >= 0) & (rows < navgrid.shape[0]) & (cols >= 0) & (cols < navgrid.shape[1])
    seen = on & (labels != 0)
    explored = (rows[seen], cols[seen])
    misplaced = [
        (categories[int(-labels[i]) - FIRST_CATEGORY], (float(xy[i, 0]), float(xy[i, 1])))
        for i in np.flatnonzero(labels < 0)
    ]
    return CropCells(explored, misplaced)


def encode_assignment(kind: int, object_type: str = "", xyz=(0.0, 0.0, 0.0)) -> np.ndarray:
    categories = load_catalog().categories
    return np.array([kind, _index(categories, object_type), *xyz, 0.0], dtype=np.float32)


def decode_assignment(v: np.ndarray) -> tuple[int, str, np.ndarray]:
    if v.size != ASSIGNMENT_DIMS:
        raise ValueError(f"an assignment has {ASSIGNMENT_DIMS} values, got {v.size}")
    return int(v[0]), _name(load_catalog().categories, v[1]), np.array(v[2:5], dtype=np.float64)
