"""The classes a learned segmenter predicts, and the renderer's labels turned into them.

The ground-truth track reads the renderer's instance segmentation, whose ids name each
instance's type through the env's label table. The pixels track replaces it with a segmenter
trained on the project's own renders; this table is what that segmenter outputs: the structure
the maps need (floor, wall, ceiling), robots, every furniture type and every pickupable type.
Index 0 is background (nothing drawn there). The order is fixed by sorted names, so a trained
segmenter's weights keep their meaning as long as the catalogue does; ``digest`` names it.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from functools import cache

import numpy as np

STRUCTURE = ("floor", "wall", "ceiling", "robot")  # the renderer's instance kinds of these


@dataclass(frozen=True)
class SegClasses:
    names: tuple[str, ...]  # index -> class name: "background", structure, then types
    furniture: tuple[str, ...]
    pickupable: tuple[str, ...]

    @property
    def index(self) -> dict[str, int]:
        return {n: i for i, n in enumerate(self.names)}

    @property
    def digest(self) -> str:
        return hashlib.sha256("\n".join(self.names).encode()).hexdigest()[:12]

    @property
    def first_pickupable(self) -> int:
        """The pickupable types' classes are this one and every one after it, so that a loss
        or a probe takes the objects' logits as one slice (``logits[:, first:]``)."""
        return 1 + len(STRUCTURE) + len(self.furniture)

    def is_pickupable(self, cls: np.ndarray | int) -> np.ndarray | bool:
        return np.asarray(cls) >= self.first_pickupable

    def of_instance(self, kind: str, type_name: str) -> int:
        """The class of one renderer instance (``sim/house_scene.py``'s Instance kind and type)."""
        if kind in STRUCTURE:
            return self.index[kind]
        if kind == "furniture":
            return self.index[f"furniture:{type_name}"]
        if kind == "object":
            return self.index[type_name]
        raise ValueError(f"instance kind {kind!r}: expected one of {STRUCTURE} or furniture/object")

    def lookup(self, instances: dict) -> np.ndarray:
        """A table from segmentation id to class (ids the table does not name: background)."""
        top = max(instances, default=0)
        table = np.zeros(top + 1, dtype=np.uint8)
        for sid, inst in instances.items():
            table[sid] = self.of_instance(inst.kind, inst.type)
        return table

    def labels(self, segmentation: np.ndarray, table: np.ndarray) -> np.ndarray:
        """Per pixel class (uint8) of a segmentation image (ids), by ``lookup``'s table."""
        seg = segmentation.reshape(segmentation.shape[:2]).astype(np.int64)
        out = np.zeros(seg.shape, dtype=np.uint8)
        known = seg < len(table)
        out[known] = table[seg[known]]
        return out


@cache
def seg_classes() -> SegClasses:
    from maniskill_tidy.houses.furniture import TEMPLATES
    from maniskill_tidy.knowledge import load_catalog

    furniture = tuple(sorted(TEMPLATES))
    pickupable = tuple(sorted(load_catalog().pickupable))
    names = ("background", *STRUCTURE, *(f"furniture:{t}" for t in furniture), *pickupable)
    if len(names) > 255:
        raise ValueError(f"{len(names)} classes do not fit a uint8 label image")
    return SegClasses(names, furniture, pickupable)
