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
from objectness_confidence import logits_of

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.eval.mask_ap import mask_ap, score_threshold
from maniskill_tidy.perception.instances import coarse, refined, scored_by_relief, split_instances
from maniskill_tidy.perception.seg_classes import seg_classes
from maniskill_tidy.training.segmenter_trainer import truth_masks


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
    c = seg_classes()
    classes = [i for i in range(len(c.names)) if c.is_pickupable(i)]
    frames = segmenter_probe.frames(args)
    model = segmenter_probe.segmenter(args)[0]
    depth = frames["depth_mm"].astype(np.float32) / 1000.0
    labels, type_m, _ = logits_of(model, frames["rgb"], depth)
    step = depth.shape[1] // labels.shape[1]
    least = -(-MIN_PIXELS // step**2)
    shape = depth.shape[1:3]

    def on_grid(k):
        grid = coarse(depth[k], step)
        return scored_by_relief(
            split_instances(labels[k], grid, classes, type_m[k], least), grid, classes
        )

    def full(lab, prob, k):
        return scored_by_relief(
            split_instances(lab, depth[k], classes, prob, MIN_PIXELS), depth[k], classes
        )

    def repeated(a):
        return np.repeat(np.repeat(a, step, axis=0), step, axis=1)

    variants = {
        "cells": lambda k: [m.upscaled(step) for m in on_grid(k)],
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
            on_grid(k), depth[k], step, MIN_PIXELS, w
        )
    for name, made in variants.items():
        pairs = [
            (truth_masks(frames["cls"][k], frames["instance"][k], classes), made(k))
            for k in range(len(labels))
        ]
        ap = mask_ap(pairs, classes, shape, ignore_below=MIN_PIXELS)
        t = score_threshold(pairs, classes, shape, ignore_below=MIN_PIXELS)
        print(
            f"| {name} | {ap['AP50']:.3f} | {ap['AP']:.3f} | {ap['AP_small']:.3f} | "
            f"{t['threshold']:.3f}: {t['f1']:.3f} ({t['precision']:.2f}, {t['recall']:.2f}) |",
            flush=True,
        )


if __name__ == "__main__":
    main()
