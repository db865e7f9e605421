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

from maniskill_tidy.perception.instances import Mask2D
from maniskill_tidy.perception.seg_classes import seg_classes


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
    pickupable = segmenter_probe.pickupable_table()
    first = seg_classes().first_pickupable
    g = segmenter_probe.GridLogits.load(args)
    step = g.step
    runs: dict[str, list] = {
        k: []
        for k in ("labels", "labels, true type", "objects, majority type", "objects, true type")
    }
    for k in range(len(g)):
        lab, truth = g.labels[k], g.truth(k)
        per_type = [m.upscaled(step) for m in g.masks(k)]
        runs["labels"].append((truth, per_type))
        runs["labels, true type"].append((truth, [true_type(m, truth) for m in per_type]))
        merged = np.where(pickupable[lab], first, lab).astype(np.uint8)
        parts = [m.upscaled(step) for m in g.masks(k, merged, g.object_margin[k], [first])]
        up = np.repeat(np.repeat(lab, step, axis=0), step, axis=1)
        runs["objects, majority type"].append((truth, [commonest(m, up) for m in parts]))
        runs["objects, true type"].append((truth, [true_type(m, truth) for m in parts]))
    for name, pairs in runs.items():
        print(f"{name:24s} {segmenter_probe.scored(pairs, g.classes, g.shape)}", flush=True)


if __name__ == "__main__":
    main()
