"""Would a second stage that names each object mask's type (a crop classifier, as Mask R-CNN's
box head names a proposal) find more objects than the segmenter's own labels? The segmenter
calls 0.7-0.99 of most types' pixels some object, yet finds under half of them at IoU 0.5:
this bounds what typing the masks again can give, with the renderer's types in place of the
classifier (a perfect second stage), on the same val frames:

- ``labels``: as agents made masks before ``refined-masks`` (per predicted type, each cell
  repeated, confidence the top-2 margin);
- ``labels, true type``: the same masks, each given the type of the object it overlaps most;
- ``objects, majority type``: one mask per depth-continuous part of pixels labelled any
  pickupable type, typed by its commonest label, confidence the object-or-not margin;
- ``objects, true type``: those masks, each given the type of the object it overlaps most.

    .venv/bin/python docs/research/probes/two_stage_ceiling.py agents/segmenter-v2 \\
        --data data/segmenter/HeteroTidy-v2/val --frames 400
"""

from __future__ import annotations

import numpy as np
import segmenter_probe
from objectness_confidence import logits_of

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.eval.mask_ap import mask_ap, score_threshold
from maniskill_tidy.perception.instances import Mask2D, coarse, scored_by_relief, split_instances
from maniskill_tidy.perception.seg_classes import seg_classes
from maniskill_tidy.training.segmenter_trainer import truth_masks


def true_type(mask: Mask2D, truth: list[Mask2D]) -> Mask2D:
    """The mask with the type of the object whose pixels it covers most (its own if none)."""
    best, cls = 0, mask.cls
    for t in truth:
        n = int((t.mask & mask.mask).sum())
        if n > best:
            best, cls = n, t.cls
    return Mask2D(cls, mask.mask, mask.score, mask.box)


def commonest(mask: Mask2D, labels: np.ndarray) -> Mask2D:
    types, counts = np.unique(labels[mask.mask], return_counts=True)
    return Mask2D(int(types[np.argmax(counts)]), mask.mask, mask.score, mask.box)


def main() -> None:
    args = segmenter_probe.arguments(__doc__)
    c = seg_classes()
    classes = [i for i in range(len(c.names)) if c.is_pickupable(i)]
    pickupable = segmenter_probe.pickupable_table()
    first = c.first_pickupable
    frames = segmenter_probe.frames(args)
    model = segmenter_probe.segmenter(args)[0]
    depth = frames["depth_mm"].astype(np.float32) / 1000.0
    labels, type_m, obj_m = logits_of(model, frames["rgb"], depth)
    step = depth.shape[1] // labels.shape[1]
    least = -(-MIN_PIXELS // step**2)
    shape = depth.shape[1:3]
    runs: dict[str, list] = {
        k: []
        for k in ("labels", "labels, true type", "objects, majority type", "objects, true type")
    }
    for k in range(len(labels)):
        grid, lab = coarse(depth[k], step), labels[k]
        truth = truth_masks(frames["cls"][k], frames["instance"][k], classes)
        per_type = scored_by_relief(split_instances(lab, grid, classes, type_m[k], least), grid,
                                    classes)  # fmt: skip
        per_type = [m.upscaled(step) for m in per_type]
        runs["labels"].append((truth, per_type))
        runs["labels, true type"].append((truth, [true_type(m, truth) for m in per_type]))
        merged = np.where(pickupable[lab], first, lab).astype(np.uint8)
        parts = scored_by_relief(split_instances(merged, grid, [first], obj_m[k], least), grid,
                                 [first])  # fmt: skip
        up = np.repeat(np.repeat(lab, step, axis=0), step, axis=1)
        parts = [m.upscaled(step) for m in parts]
        runs["objects, majority type"].append((truth, [commonest(m, up) for m in parts]))
        runs["objects, true type"].append((truth, [true_type(m, truth) for m in parts]))
    for name, pairs in runs.items():
        ap = mask_ap(pairs, classes, shape, ignore_below=MIN_PIXELS)
        t = score_threshold(pairs, classes, shape, ignore_below=MIN_PIXELS)
        print(f"{name:24s} AP50 {ap['AP50']:.3f} AP {ap['AP']:.3f} small {ap['AP_small']:.3f} "
              f"| threshold {t['threshold']:.3f}: F1 {t['f1']:.3f} P {t['precision']:.2f} "
              f"R {t['recall']:.2f}", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
