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
import torch

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.eval.mask_ap import mask_ap, score_threshold
from maniskill_tidy.perception.instances import coarse, scored_by_relief, split_instances
from maniskill_tidy.perception.seg_classes import seg_classes
from maniskill_tidy.training.segmenter_trainer import truth_masks


def logits_of(model, rgb: np.ndarray, depth: np.ndarray, batch: int = 16):
    """Labels, type margins and object margins (sigmoids), on the network's grid."""
    c = seg_classes()
    obj = torch.tensor([c.is_pickupable(i) and i > 0 for i in range(len(c.names))])
    labels, type_m, obj_m = [], [], []
    with torch.inference_mode():
        for s in range(0, len(rgb), batch):
            r = torch.from_numpy(np.array(rgb[s : s + batch])).permute(0, 3, 1, 2).float()
            d = torch.from_numpy(np.array(depth[s : s + batch])).unsqueeze(1)
            z = model.eval()(r, d)
            best, label = z.topk(2, dim=1)
            best_obj = z[:, obj].max(dim=1).values
            best_other = z[:, ~obj].max(dim=1).values
            labels.append(label[:, 0].to(torch.uint8).numpy())
            type_m.append(torch.sigmoid(best[:, 0] - best[:, 1]).numpy())
            obj_m.append(torch.sigmoid((best_obj - best_other).abs()).numpy())
    return np.concatenate(labels), np.concatenate(type_m), np.concatenate(obj_m)


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
    classes = [i for i in range(len(c.names)) if c.is_pickupable(i)]
    pickupable = np.zeros(256, dtype=bool)
    pickupable[[i for i in classes if i > 0]] = True
    frames = segmenter_probe.frames(args)
    model = segmenter_probe.segmenter(args)[0]
    depth = frames["depth_mm"].astype(np.float32) / 1000.0
    labels, type_m, obj_m = logits_of(model, frames["rgb"], depth)
    step = depth.shape[1] // labels.shape[1]
    least = -(-MIN_PIXELS // step**2)
    variants = {"type margin": (False, False), "object margin": (False, True),
                "majority type": (True, False), "both": (True, True)}  # fmt: skip
    shape = depth.shape[1:3]
    for name, (vote, objectness) in variants.items():
        pairs = []
        for k in range(len(labels)):
            grid = coarse(depth[k], step)
            lab = majority(labels[k], grid, c.first_pickupable, pickupable) if vote else labels[k]
            prob = obj_m[k] if objectness else type_m[k]
            masks = scored_by_relief(split_instances(lab, grid, classes, prob, least), grid,
                                     classes)  # fmt: skip
            truth = truth_masks(frames["cls"][k], frames["instance"][k], classes)
            pairs.append((truth, [m.upscaled(step) for m in masks]))
        ap = mask_ap(pairs, classes, shape, ignore_below=MIN_PIXELS)
        t = score_threshold(pairs, classes, shape, ignore_below=MIN_PIXELS)
        print(f"{name:14s} AP50 {ap['AP50']:.3f} AP {ap['AP']:.3f} small {ap['AP_small']:.3f} "
              f"| threshold {t['threshold']:.3f}: F1 {t['f1']:.3f} P {t['precision']:.2f} "
              f"R {t['recall']:.2f}", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
