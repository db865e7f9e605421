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

    @property
    def area(self) -> int:
        return int(self.mask.sum())


def depth_edges(depth: np.ndarray) -> np.ndarray:
    """Pixels whose depth differs from a 4-neighbour's by more than the jump allowed there."""
    d = depth.reshape(depth.shape[:2]).astype(np.float32)
    edge = np.zeros(d.shape, dtype=bool)
    for axis in (0, 1):
        diff = np.abs(np.diff(d, axis=axis))
        limit = DEPTH_JUMP + 0.05 * np.minimum(
            d.take(range(d.shape[axis] - 1), axis), d.take(range(1, d.shape[axis]), axis)
        )
        jump = diff > limit
        if axis == 0:
            edge[:-1] |= jump
            edge[1:] |= jump
        else:
            edge[:, :-1] |= jump
            edge[:, 1:] |= jump
    return edge


def split_instances(
    labels: np.ndarray,
    depth: np.ndarray,
    classes: list[int] | np.ndarray,
    probabilities: np.ndarray | None = None,
    min_pixels: int = MIN_PIXELS,
) -> list[Mask2D]:
    """The instances of ``classes`` in a label image (H, W). ``probabilities`` (H, W): the
    segmenter's probability of the label it chose per pixel, for each instance's score."""
    edges = depth_edges(depth)
    out = []
    for c in np.intersect1d(np.unique(labels), np.asarray(classes)):
        mask = labels == c
        parts, n = ndimage.label(mask & ~edges)
        if n == 0:
            parts, n = ndimage.label(mask)
        elif (mask & edges).any():  # edge pixels join the part of their nearest pixel
            _, (iy, ix) = ndimage.distance_transform_edt(parts == 0, return_indices=True)
            parts = np.where(mask, parts[iy, ix], 0)
        for k in range(1, n + 1):
            m = parts == k
            if m.sum() < min_pixels:
                continue
            score = float(probabilities[m].mean()) if probabilities is not None else 1.0
            out.append(Mask2D(int(c), m, score))
    return out
