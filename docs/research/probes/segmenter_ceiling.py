"""The mask AP50 a perfect segmenter would reach through the agents' instances: the renderer's
own classes, at the frame's resolution and on the segmenter's half-resolution grid (as agents
make instances: every other pixel, masks upsampled), scored as train-segmenter scores its
card. What is left between a segmenter and these is the segmenter's.

    .venv/bin/python docs/research/probes/segmenter_ceiling.py \
        --data data/segmenter/HeteroTidy-v2/val --frames 400
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.eval.mask_ap import mask_ap
from maniskill_tidy.perception.instances import coarse, split_instances
from maniskill_tidy.perception.seg_classes import seg_classes
from maniskill_tidy.training.segmenter_trainer import load_split, truth_masks


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default="data/segmenter/HeteroTidy-v2/val")
    ap.add_argument("--frames", type=int, default=400)
    args = ap.parse_args()
    frames = load_split(Path(args.data), args.frames)
    classes = seg_classes()
    pick = [i for i in range(len(classes.names)) if classes.is_pickupable(i)]
    depth = frames["depth_mm"].astype(np.float32) / 1000
    cls = frames["cls"]
    truth = [truth_masks(cls[k], frames["instance"][k], pick) for k in range(len(cls))]
    ones = np.ones(cls.shape[1:], dtype=np.float32)

    def full(k):
        return split_instances(cls[k], depth[k], pick, ones, MIN_PIXELS)

    def grid(k):
        masks = split_instances(coarse(cls[k], 2), coarse(depth[k], 2), pick, coarse(ones, 2),
                                -(-MIN_PIXELS // 4))  # fmt: skip
        return [m.upscaled(2) for m in masks]

    for name, make in (("full resolution", full), ("half-resolution grid", grid)):
        r = mask_ap([(truth[k], make(k)) for k in range(len(cls))], pick, cls.shape[1:],
                    ignore_below=MIN_PIXELS)  # fmt: skip
        print(
            f"the renderer's classes, {name}: mask AP50 {r['AP50']:.3f}, AP {r['AP']:.3f} "
            f"(small {r['AP_small']:.3f}, medium {r['AP_medium']:.3f})"
        )


if __name__ == "__main__":
    main()
