"""Does type confusion cost detections? A segmenter that splits one object's pixels between two
similar types (ToiletPaper and PaperTowelRoll) makes two masks, neither at IoU 0.5, and scores
each by the margin between its two best logits, which is small between those two types: the
object is never detected at the agents' threshold. Four ways of making object masks from the
same logits, each scored as the cards score agents' masks (mask AP50 over the pickupable types,
the best-F1 threshold with its precision and recall):

- ``type margin``: as agents do now (instances per label, confidence the top-2 margin);
- ``object margin``: the same masks, each pixel's confidence the margin between its best
  pickupable logit and its best other one (is it an object at all?);
- ``majority type``: each 4-connected part of pickupable pixels with no depth jump takes the
  type most of its pixels have, then instances per label, type margin;
- ``both``: majority type and object margin.

    .venv/bin/python docs/research/probes/objectness_confidence.py agents/segmenter-v2 \\
        --data data/segmenter/HeteroTidy-v2/val --frames 400
"""

from __future__ import annotations

import numpy as np
import segmenter_probe

from maniskill_tidy.perception.instances import split_instances
from maniskill_tidy.perception.seg_classes import seg_classes


def majority(lab: np.ndarray, grid: np.ndarray, first: int, pickupable: np.ndarray):
    """Each depth-continuous part of pickupable pixels relabelled with its commonest type."""
    merged = np.where(pickupable[lab], first, lab).astype(np.uint8)
    out = lab.copy()
    for part in split_instances(merged, grid, [first], None, 1):
        types, counts = np.unique(lab[part.mask], return_counts=True)
        out[part.mask] = types[np.argmax(counts)]
    return out


def main() -> None:
    args = segmenter_probe.arguments(__doc__)
    c = seg_classes()
    pickupable = segmenter_probe.pickupable_table()
    g = segmenter_probe.GridLogits.load(args)
    variants = {"type margin": (False, False), "object margin": (False, True),
                "majority type": (True, False), "both": (True, True)}  # fmt: skip
    for name, (vote, objectness) in variants.items():
        pairs = []
        for k in range(len(g)):
            lab = g.labels[k]
            if vote:
                lab = majority(lab, g.grid(k), c.first_pickupable, pickupable)
            prob = g.object_margin[k] if objectness else g.type_margin[k]
            pairs.append((g.truth(k), [m.upscaled(g.step) for m in g.masks(k, lab, prob)]))
        print(f"{name:14s} {segmenter_probe.scored(pairs, g.classes, g.shape)}", flush=True)


if __name__ == "__main__":
    main()
