"""What the learned modules read off one agent's observation, computed one way everywhere.

The perception views (``training/perception_data.py``), the demonstrations with features
(``training/decision_data.py``) and the learned team at evaluation (``policies/learned.py``)
all call :meth:`FrameReader.read`, so a model sees at evaluation exactly what it was trained on.
A reader holds one agent's :class:`SemanticMap` and nothing else the agent could not know: the
public floor plan and the segmentation's label table.

Per frame (:class:`FrameInputs`):

- ``rgb``: the colour image area-averaged to 64 x 64 (the visual encoder's input);
- ``seen``: the share of the image each category covers (the room classifier's "detected
  objects"; segmentation is ground truth, standing in for Mask R-CNN);
- ``crop``: the map's egocentric crop, G x G x (K + 2) cells of 0.25 m (the scene encoder's);
- ``wide``: a coarse egocentric view of the same map, 20 x 20 cells of 1 m, shares of obstacle,
  explored and any-object (``crops.wide_layout``; F_g's ``sw`` with ``wide_layout``), or
  None when the reader was made with ``wide=False`` (about 1 ms per frame, 5 % of an
  env step: `make bench`, map rows);
- ``pose``: x, y, rotation and camera pitch; ``held``: the held object's type index or -1;
- one detection per pickupable object in view, not held (``sl``'s inputs): type, the receptacle
  type it rests on (back-projected pixels + the floor plan's surfaces), and 7 numbers: image
  box (4), distance / 5 m, sqrt of image share, lowest point.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numba import njit

from maniskill_tidy.houses.schema import House
from maniskill_tidy.knowledge import FLOOR, load_catalog
from maniskill_tidy.perception.detections import detect_objects, resting_place, surface_table
from maniskill_tidy.perception.map_grid import id_counts
from maniskill_tidy.perception.semantic_map import MapConfig, SemanticMap

IMAGE = 64  # visual encoder input side (pixels)
MAP_STRIDE = 2  # every other pixel, as the heuristic agents map
DETECTION_NUMERIC = 7  # box (4), distance, image share, lowest point


@dataclass(frozen=True)
class FrameInputs:
    rgb: np.ndarray  # (64, 64, 3) uint8
    seen: np.ndarray  # (K,) float32
    crop: np.ndarray  # (G, G, K + 2) bool
    wide: np.ndarray | None  # (20, 20, 3) uint8 shares, None unless the reader computes it
    pose: np.ndarray  # (4,) float32: x, y, rotation, camera pitch (degrees)
    held: int  # type index in the catalog's categories, or -1
    det_type: np.ndarray  # (n,) category indices
    det_rest: np.ndarray  # (n,) receptacle indices; len(receptacles) = rests on nothing known
    det_numeric: np.ndarray  # (n, 7) float32
    det_object: tuple[str, ...]  # (n,) object ids, read off the segmentation's label table
    det_position: np.ndarray  # (n, 3) measured positions (metres)


@njit(cache=True, nogil=True)
def image_boxes(seg, ids):
    """Per id of ``ids``: (first row, first column, last row + 1, last column + 1) of its
    pixels in ``seg``, all 0 where it has none; one pass over the image instead of a mask per
    detection."""
    boxes = np.zeros((len(ids), 4), np.int64)
    if len(ids) == 0:
        return boxes
    slot = np.full(max(ids.max(), 0) + 1, -1, np.int64)
    for i in range(len(ids)):
        slot[ids[i]] = i
    h, w = seg.shape
    for r in range(h):
        for c in range(w):
            s = seg[r, c]
            if 0 <= s < len(slot) and slot[s] >= 0:
                box = boxes[slot[s]]
                if box[2] == 0:  # its first pixel (row-major: the first row)
                    box[0], box[1], box[2], box[3] = r, c, r + 1, c + 1
                else:
                    box[1], box[2], box[3] = min(box[1], c), r + 1, max(box[3], c + 1)
    return boxes


def camera_pitch(extrinsics: np.ndarray) -> int:
    """The camera's horizon in degrees (positive looks down), read off its world pose."""
    up = np.asarray(extrinsics)[2, 2]  # the OpenCV z axis's world z (numpy's scalar type)
    # min and max clip as np.clip does (NaN too), without its dispatch on a scalar
    return int(round(np.degrees(-np.arcsin(min(max(up, -1), 1))) / 30.0)) * 30


class FrameReader:
    """One agent's map and the per-frame inputs of the learned modules (create one per episode)."""

    def __init__(
        self, house: House, instances: dict, stride: int = MAP_STRIDE, wide: bool = False
    ) -> None:
        self.house, self.instances = house, instances
        self.wide = wide
        self.catalog = load_catalog()
        self.map = SemanticMap(house, instances, MapConfig(stride=stride))
        self.surfaces = surface_table(house)
        self.furniture = house.furniture_by_id()
        self._pickupable = set(self.catalog.pickupable)

    def read(self, obs: dict, update: bool = True) -> FrameInputs:
        """Fuse ``obs`` into the map (unless ``update`` is False) and read the inputs off it."""
        if update:
            self.map.update(obs)
        catalog = self.catalog
        seg = np.asarray(obs["segmentation"])
        seen = np.zeros(len(catalog.categories), dtype=np.float32)
        ids, counts = id_counts(seg)
        for sid, n in zip(ids, counts, strict=True):
            inst = self.instances.get(int(sid))
            if inst is not None and inst.type in self.map.categories:
                seen[catalog.category_index(inst.type)] += n / seg.size
        pose = np.asarray(obs["pose"], dtype=np.float32)
        held_seg = int(obs["held"])
        held = catalog.category_index(self.instances[held_seg].type) if held_seg else -1
        rgb = np.asarray(obs["rgb"]) if "rgb" in obs else np.zeros((IMAGE, IMAGE, 3), np.uint8)
        types, rests, numeric, objects, positions = [], [], [], [], []
        h, w = seg.shape
        found = [
            d for d in detect_objects(self.map.last_frame, self.instances)
            if d.seg_id != held_seg and d.type in self._pickupable
        ]  # fmt: skip
        boxes = image_boxes(seg, np.array([d.seg_id for d in found], np.int64))
        for d, (top, left, bottom, right) in zip(found, boxes.tolist(), strict=True):
            if bottom <= top:
                continue  # no pixel at full resolution
            types.append(catalog.category_index(d.type))
            rests.append(self._rest(d))
            numeric.append(
                [
                    top / h,
                    left / w,
                    bottom / h,
                    right / w,
                    d.distance / 5.0,
                    math.sqrt(d.pixels / (h * w)),
                    d.bottom,
                ]
            )
            objects.append(d.object_id)
            positions.append(d.position)
        return FrameInputs(
            rgb=cv2.resize(rgb, (IMAGE, IMAGE), interpolation=cv2.INTER_AREA),
            seen=seen,
            crop=self.map.local_crop(pose[:3]) > 0,
            wide=self.map.wide_layout(pose[:3]) if self.wide else None,
            pose=np.array([*pose[:3], camera_pitch(obs["extrinsics"])], dtype=np.float32),
            held=held,
            det_type=np.asarray(types, dtype=np.int64),
            det_rest=np.asarray(rests, dtype=np.int64),
            det_numeric=np.asarray(numeric, dtype=np.float32).reshape(-1, DETECTION_NUMERIC),
            det_object=tuple(objects),
            det_position=np.asarray(positions, dtype=np.float32).reshape(-1, 3),
        )

    def _rest(self, d) -> int:
        receptacles = self.catalog.receptacles
        receptacle, surface, _ = resting_place(self.house, d, self.surfaces)
        if receptacle == FLOOR:
            return receptacles.index(FLOOR)
        if receptacle:
            return receptacles.index(self.furniture[receptacle].surface(surface).receptacle_type)
        return len(receptacles)  # rests on nothing the floor plan knows
