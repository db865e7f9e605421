"""What the object typer (``models/object_typer.py``) reads of one mask: a square crop of the
frame around it at a fixed size (RGB, the mask, the depth about the mask's median), and numbers
a crop loses: the mask's size in metres and in pixels, and the segmenter's votes over the
pickupable types (``object_space.object_masks``' votes, as shares)."""

from __future__ import annotations

import numpy as np

from maniskill_tidy.perception.instances import Mask2D

SIZE = 32  # pixels of a crop's side
MARGIN = 1.25  # a crop's side over the mask's longer side
DEPTH_SPAN = 0.1  # metres: depth about the mask's median, clipped to +-1 at this distance
CHANNELS = 5  # RGB, mask, depth


def scalar_width(types: int) -> int:
    """Numbers per mask beside its crop: metric width and height, log pixels, votes per type."""
    return 3 + types


def crop_inputs(masks: list[Mask2D], rgb: np.ndarray, depth: np.ndarray, focal: float,
                labels: np.ndarray, margins: np.ndarray,
                type_index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """``masks`` at the frame's resolution -> crops (N, CHANNELS, SIZE, SIZE) float32 and
    numbers (N, scalar_width(T)) float32. ``labels`` and ``margins`` on the segmenter's grid;
    ``type_index``: label -> 0..T-1 for the pickupable types, -1 for the others; ``focal``:
    the camera's focal length in pixels."""
    types = int(type_index.max()) + 1
    h, w = depth.shape[:2]
    step = h // labels.shape[0]
    d = depth.reshape(h, w)
    crops = np.zeros((len(masks), CHANNELS, SIZE, SIZE), np.float32)
    numbers = np.zeros((len(masks), scalar_width(types)), np.float32)
    for k, m in enumerate(masks):
        rows, cols = np.nonzero(m.mask[m.window])
        rows, cols = rows + (m.window[0].start or 0), cols + (m.window[1].start or 0)
        r0, r1, c0, c1 = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
        side = max(r1 - r0, c1 - c0) * MARGIN + 2
        centre_r, centre_c = (r0 + r1) / 2, (c0 + c1) / 2
        # nearest-neighbour sampling of the square; outside the frame: zeros
        at = (np.arange(SIZE) + 0.5) / SIZE * side - side / 2
        rr = np.floor(centre_r + at).astype(int)
        cc = np.floor(centre_c + at).astype(int)
        inside = ((rr >= 0) & (rr < h))[:, None] & ((cc >= 0) & (cc < w))[None, :]
        rr_c, cc_c = np.clip(rr, 0, h - 1), np.clip(cc, 0, w - 1)
        median = float(np.median(d[rows, cols]))
        patch = rgb[rr_c][:, cc_c].astype(np.float32) / 127.5 - 1.0
        crops[k, :3] = np.where(inside[..., None], patch, 0.0).transpose(2, 0, 1)
        crops[k, 3] = np.where(inside, m.mask[rr_c][:, cc_c], False)
        rel = np.clip((d[rr_c][:, cc_c] - median) / DEPTH_SPAN, -1.0, 1.0)
        crops[k, 4] = np.where(inside, rel, 0.0)
        numbers[k, 0] = (c1 - c0) * median / focal
        numbers[k, 1] = (r1 - r0) * median / focal
        numbers[k, 2] = np.log(len(rows)) / 8.0
        lab, mar = labels[rows // step, cols // step], margins[rows // step, cols // step]
        t = type_index[lab]
        voted = t >= 0
        if voted.any():
            votes = np.bincount(t[voted], weights=mar[voted], minlength=types)
            numbers[k, 3:] = votes / len(rows)
    return crops, numbers
