"""Is it finding objects or naming them that a segmenter gets wrong? Per object of the
renderer (20 px or more, by size): the share of its pixels labelled as some pickupable type, and
as its own; then mask AP with every pickupable type merged into one (class-agnostic instances,
made as agents make them), beside the typed AP.

    .venv/bin/python docs/research/probes/object_recall.py agents/segmenter-v2 \\
        --data data/segmenter/HeteroTidy-v2/val --frames 400
"""

from __future__ import annotations

import dataclasses

import numpy as np
import segmenter_probe

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.eval.mask_ap import mask_ap
from maniskill_tidy.perception.seg_classes import seg_classes
from maniskill_tidy.training.segmenter_trainer import instance_pairs

SIZES = ((20, 100), (100, 400), (400, 1600), (1600, None))  # pixels of the 224 px frame


def main() -> None:
    args = segmenter_probe.arguments(__doc__)
    c = seg_classes()
    pickupable = segmenter_probe.pickupable_table()
    frames = segmenter_probe.frames(args)
    model = segmenter_probe.segmenter(args)[0]
    # (area, share called an object, share called its type)
    rows = [(len(got), pickupable[got].mean(), (got == t).mean())
            for t, got in segmenter_probe.labelled_objects(model, frames)]  # fmt: skip
    rows = np.array(rows)
    for lo, hi in SIZES:
        s = rows[(rows[:, 0] >= lo) & (rows[:, 0] < (hi or np.inf))]
        print(f"{lo}-{hi or ''} px: {len(s)} objects; of their pixels {s[:, 1].mean():.2f} "
              f"called an object, {s[:, 2].mean():.2f} their type; {np.mean(s[:, 2] >= 0.5):.2f} "
              "of them with half their pixels of their type")  # fmt: skip
    first = c.first_pickupable

    def merged(lab, prob, grid):
        out = lab.copy()
        out[pickupable[lab]] = first
        return out

    shape = frames["rgb"].shape[1:3]
    typed = mask_ap(instance_pairs(model, frames)[0], [i for i in range(len(c.names))
                    if c.is_pickupable(i)], shape, ignore_below=MIN_PIXELS)  # fmt: skip
    pairs = [([dataclasses.replace(m, cls=first) for m in truth], masks)
             for truth, masks in instance_pairs(model, frames, merged)[0]]  # fmt: skip
    agnostic = mask_ap(pairs, [first], shape, ignore_below=MIN_PIXELS)
    print(f"mask AP50 typed {typed['AP50']:.3f}, class-agnostic {agnostic['AP50']:.3f} "
          f"(AP {typed['AP']:.3f}, {agnostic['AP']:.3f})")  # fmt: skip


if __name__ == "__main__":
    main()
