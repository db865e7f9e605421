"""Masks at the frame's resolution from labels at half of it: does letting depth guide the
upsampling (each pixel takes the label of the neighbouring cell whose depth matches its own,
a joint bilateral upsampling) find more objects than repeating each cell? The segmenter's
masks spill over an object or cover too little of it about equally often (``mask_misses.py``),
and half of its pixels' labels are a neighbour's guess. Mask AP over the pickupable types on
val frames, the best-F1 threshold's precision and recall, for:

- ``cells``: as agents made masks before, on the grid, each cell repeated;
- ``cells, instances at full resolution``: labels repeated, then split at full resolution;
- ``guided labels, w``: every label upsampled with depth's guidance (``w`` metres per pixel of
  distance), then split at full resolution;
- ``refined masks, w``: masks made on the grid, each refined (``instances.refined``): cheaper,
  as only the objects' windows are upsampled.

    .venv/bin/python docs/research/probes/guided_masks.py agents/segmenter-v2 \\
        --data data/segmenter/HeteroTidy-v2/val --frames 400
"""

from __future__ import annotations

import numpy as np
import segmenter_probe

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.perception.instances import coarse, refined, scored_by_relief, split_instances


def guided_labels(labels, probs, depth, step: int, weight: float):
    """Every label and its confidence at full resolution, each pixel from the cell of the
    3 x 3 around its own whose depth is nearest its own (plus ``weight`` per pixel away)."""
    grid = coarse(depth, step)
    h, w = depth.shape
    rows, cols = np.arange(h)[:, None], np.arange(w)[None, :]
    best = np.full((h, w), np.inf)
    out_l, out_p = np.zeros((h, w), labels.dtype), np.zeros((h, w), np.float32)
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            gr = np.clip(rows // step + dr, 0, grid.shape[0] - 1)
            gc = np.clip(cols // step + dc, 0, grid.shape[1] - 1)
            far = np.hypot(rows - step * gr, cols - step * gc)
            cost = np.abs(grid[gr, gc] - depth) + weight * far
            better = cost < best
            best = np.where(better, cost, best)
            out_l = np.where(better, labels[gr, gc], out_l)
            out_p = np.where(better, probs[gr, gc], out_p)
    return out_l, out_p


def main() -> None:
    args = segmenter_probe.arguments(__doc__)
    g = segmenter_probe.GridLogits.load(args)
    step, depth, labels, type_m = g.step, g.depth, g.labels, g.type_margin

    def full(lab, prob, k):
        return scored_by_relief(
            split_instances(lab, depth[k], g.classes, prob, MIN_PIXELS), depth[k], g.classes
        )

    def repeated(a):
        return np.repeat(np.repeat(a, step, axis=0), step, axis=1)

    variants = {
        "cells": lambda k: [m.upscaled(step) for m in g.masks(k)],
        "cells, instances at full resolution": lambda k: full(
            repeated(labels[k]), repeated(type_m[k]), k
        ),
    }
    for w in (0.01, 0.03):
        variants[f"guided labels, {w}"] = lambda k, w=w: full(
            *guided_labels(labels[k], type_m[k], depth[k], step, w), k
        )
    for w in (0.003, 0.01, 0.03, 0.1):
        variants[f"refined masks, {w}"] = lambda k, w=w: refined(
            g.masks(k), depth[k], step, MIN_PIXELS, w
        )
    for name, made in variants.items():
        pairs = [(g.truth(k), made(k)) for k in range(len(g))]
        print(f"{name:36s} {segmenter_probe.scored(pairs, g.classes, g.shape)}", flush=True)


if __name__ == "__main__":
    main()
