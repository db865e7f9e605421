"""Does depth contrast tell object masks from false ones? Val mask AP50 and best F1 of a
segmenter's object masks (made as agents make them, on the network's grid) scored by
confidence alone, kept only above a contrast, and scored by confidence times the logistic of
contrast over a scale (what ``perception/instances.py: scored_by_contrast`` does at 1 cm).

    .venv/bin/python docs/research/probes/depth_contrast.py agents/segmenter-v2 \\
        --data data/segmenter/HeteroTidy-v2/val --frames 400
"""

from __future__ import annotations

import dataclasses

import numpy as np
import segmenter_probe

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.eval.mask_ap import mask_ap, score_threshold
from maniskill_tidy.models.segmenter import predict
from maniskill_tidy.perception.instances import coarse, depth_contrast, split_instances
from maniskill_tidy.perception.seg_classes import seg_classes
from maniskill_tidy.training.segmenter_trainer import truth_masks


def main() -> None:
    args = segmenter_probe.arguments(__doc__)
    c = seg_classes()
    pick = [i for i in range(len(c.names)) if c.is_pickupable(i)]
    frames = segmenter_probe.frames(args)
    depth = frames["depth_mm"].astype(np.float32) / 1000
    model = segmenter_probe.segmenter(args)[0]
    labels, probs = predict(model, frames["rgb"], depth)
    step = depth.shape[1] // labels.shape[1]
    rows = []  # per frame: truth, [(mask on the grid, its contrast)]
    for k in range(len(labels)):
        grid = coarse(depth[k], step)
        masks = split_instances(labels[k], grid, pick, probs[k], -(-MIN_PIXELS // step**2))
        rows.append((truth_masks(frames["cls"][k], frames["instance"][k], pick),
                     [(m, depth_contrast(m, grid)) for m in masks]))  # fmt: skip
    shape = depth.shape[1:3]

    def scored(name: str, f) -> None:
        pairs = [(t, [dataclasses.replace(m.upscaled(step), score=f(m.score, con))
                      for m, con in masks if f(m.score, con) > 0])
                 for t, masks in rows]  # fmt: skip
        r = mask_ap(pairs, pick, shape, ignore_below=MIN_PIXELS)
        b = score_threshold(pairs, pick, shape, ignore_below=MIN_PIXELS)
        print(f"{name}: AP50 {r['AP50']:.3f}, AP {r['AP']:.3f}; best F1 {b['f1']:.3f} "
              f"(P {b['precision']:.2f}, R {b['recall']:.2f})")  # fmt: skip

    scored("confidence", lambda s, con: s)
    for t in (0.0, 0.01, 0.02, 0.04):
        scored(f"kept above {t:.2f} m", lambda s, con, t=t: s if con > t else 0.0)
    for w in (0.01, 0.03):
        scored(f"times logistic(contrast / {w:.2f} m)",
               lambda s, con, w=w: s / (1.0 + np.exp(-con / w)))  # fmt: skip


if __name__ == "__main__":
    main()
