"""Where a segmenter's object masks go wrong. Its mask AP50 on train frames beside val frames
(does it underfit or overfit?), then every object mask it makes on val frames, as agents make
them (on the network's grid, 20 px or more), sorted by what lies under it: a match (IoU >= 0.5,
right type), the wrong type, a part of an object (IoU 0.1-0.5), another object, or the structure
class or furniture most of its pixels show; with how many of each agents keep (the card's agent
threshold) and their median size and confidence.

    .venv/bin/python docs/research/probes/segmenter_errors.py agents/segmenter-v2 \\
        --data data/segmenter/HeteroTidy-v2 --frames 400
"""

from __future__ import annotations

from collections import Counter

import numpy as np
import segmenter_probe

from maniskill_tidy.perception.seg_classes import seg_classes
from maniskill_tidy.training.segmenter_trainer import evaluate, instance_pairs


def what_lies_under(mask, truth, cls, classes) -> str:
    best, best_type = 0.0, None
    for t in truth:
        iou = (mask.mask & t.mask).sum() / (mask.mask | t.mask).sum()
        if iou > best:
            best, best_type = iou, t.cls
    if best >= 0.5:
        return "match" if best_type == mask.cls else "wrong type"
    if best >= 0.1:
        return "part of an object"
    under = cls[mask.mask]
    if classes.is_pickupable(under).mean() > 0.5:
        return "another object"
    name = classes.names[np.bincount(under).argmax()]
    return "furniture" if name.startswith("furniture:") else name


def main() -> None:
    args = segmenter_probe.arguments(__doc__, "data/segmenter/HeteroTidy-v2")
    model, card = segmenter_probe.segmenter(args)
    threshold = card.get("agent_threshold", {}).get("threshold", 0.0)
    for split in ("train", "val"):
        s = evaluate(model, segmenter_probe.frames(args, split))
        print(
            f"{split}: mask AP50 {s['AP50']:.3f}, AP {s['AP']:.3f}, small {s['AP_small']:.3f}; "
            f"pixel accuracy on objects {s['pixel_accuracy_pickupable']:.2f}, overall "
            f"{s['pixel_accuracy']:.2f}; {s['predicted']} masks for {s['truth']} objects"
        )
    classes = seg_classes()
    frames = segmenter_probe.frames(args, "val")
    kinds: Counter = Counter()
    scores: dict[str, list] = {}
    areas: dict[str, list] = {}
    for k, (truth, masks) in enumerate(instance_pairs(model, frames)[0]):
        for m in masks:
            kind = what_lies_under(m, truth, frames["cls"][k], classes)
            kinds[kind] += 1
            scores.setdefault(kind, []).append(m.score)
            areas.setdefault(kind, []).append(m.area)
    total = sum(kinds.values())
    print(f"val object masks: {total}; agent threshold {threshold:.3f}")
    for kind, n in kinds.most_common():
        s = np.array(scores[kind])
        kept = int((s >= threshold).sum())
        print(f"  {kind:18s} {n:5d} ({n / total:.2f}); kept by agents {kept:4d}; median "
              f"{np.median(areas[kind]):.0f} px, confidence {np.median(s):.2f}")  # fmt: skip


if __name__ == "__main__":
    main()
