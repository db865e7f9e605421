"""Instances from a class-per-pixel image: connected components of each class, split where the
depth jumps (two mugs side by side are one component of class Mug, but one stands behind the
other). A semantic segmenter names classes, not instances; this turns its output into the
masks a detector would give (the paper's Mask R-CNN), each with a score.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

MIN_PIXELS = 8  # smaller components are noise at 224 px
DEPTH_JUMP = 0.08  # metres, plus 5 % of the depth: a step this large separates two instances


@dataclass(frozen=True)
class Mask2D:
    cls: int
    mask: np.ndarray  # bool (H, W)
    score: float  # mean probability of the class over the mask (1 for ground truth)
    box: tuple[slice, slice] | None = None  # rows and columns holding the mask, where known

    @property
    def area(self) -> int:
        return int(self.mask[self.window].sum())

    @property
    def window(self) -> tuple[slice, slice]:
        """Where to look for the mask's pixels: its box, or the whole frame."""
        return self.box if self.box is not None else (slice(None), slice(None))

    def paint(self, image: np.ndarray, value) -> None:
        """``image[mask] = value``, touching the box only."""
        image[self.window][self.mask[self.window]] = value

    def upscaled(self, step: int) -> Mask2D:
        """The mask on a grid ``step`` times finer, each cell a ``step`` x ``step`` block (as
        nearest-neighbour upsampling of the labels it came from would give)."""
        mask = np.repeat(np.repeat(self.mask, step, axis=0), step, axis=1)
        box = None if self.box is None else tuple(
            slice((b.start or 0) * step, None if b.stop is None else b.stop * step)
            for b in self.box
        )  # fmt: skip
        return Mask2D(self.cls, mask, self.score, box)


def coarse(image: np.ndarray, step: int) -> np.ndarray:
    """Every ``step``-th pixel of an image, from the first: what a label at the segmenter's
    resolution covers first (``models/segmenter.py: upsample`` maps it back)."""
    return image[::step, ::step]


def depth_edges(depth: np.ndarray) -> np.ndarray:
    """Pixels whose depth differs from a 4-neighbour's by more than the jump allowed there."""
    d = depth.reshape(depth.shape[:2]).astype(np.float32)
    edge = np.zeros(d.shape, dtype=bool)
    for a, b, ea, eb in (
        (d[:-1], d[1:], edge[:-1], edge[1:]),
        (d[:, :-1], d[:, 1:], edge[:, :-1], edge[:, 1:]),
    ):
        jump = np.abs(a - b) > DEPTH_JUMP + 0.05 * np.minimum(a, b)
        ea |= jump
        eb |= jump
    return edge


def split_instances(
    labels: np.ndarray,
    depth: np.ndarray,
    classes: list[int] | np.ndarray,
    probabilities: np.ndarray | None = None,
    min_pixels: int = MIN_PIXELS,
    joined: list[int] | np.ndarray | None = None,
) -> list[Mask2D]:
    """The instances of ``classes`` in a label image (H, W). ``probabilities`` (H, W): the
    segmenter's probability of the label it chose per pixel, for each instance's score. Each
    class is worked on inside its bounding box only. ``joined``: the classes whose pixels on a
    depth edge join the part nearest them (default all); the others' stay out of every part
    (a mask only placed, never aimed at, needs no outline)."""
    edges = depth_edges(depth)
    present = np.zeros(256, dtype=bool)
    present[np.asarray(classes, dtype=np.int64)] = True
    join = present if joined is None else np.zeros(256, dtype=bool)
    if joined is not None:
        join[np.asarray(joined, dtype=np.int64)] = True
    boxes = ndimage.find_objects(np.where(present[labels], labels, 0).astype(np.int32))
    out = []
    for index, box in enumerate(boxes):
        if box is None:
            continue
        c = index + 1
        mask = labels[box] == c
        cut = mask & ~edges[box]
        parts, n = ndimage.label(cut)
        if n == 0:
            parts, n = ndimage.label(mask)
        elif join[c] and (mask & ~cut).any():  # edge pixels join the nearest part
            _, (iy, ix) = ndimage.distance_transform_edt(parts == 0, return_indices=True)
            parts = np.where(mask, parts[iy, ix], 0)
        sizes = np.bincount(parts.ravel(), minlength=n + 1)
        for k in range(1, n + 1):
            if sizes[k] < min_pixels:
                continue
            local = parts == k
            m = np.zeros(labels.shape, dtype=bool)
            m[box] = local
            score = float(probabilities[box][local].mean()) if probabilities is not None else 1.0
            out.append(Mask2D(int(c), m, score, box))
    return out
