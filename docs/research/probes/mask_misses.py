"""How the segmenter's masks miss objects, by size: per object of the renderer (``MIN_PIXELS``
or more) on val frames, the best IoU of a mask of its type and of any type, whether that mask
clears the agents' threshold, whether any mask touches it at all, and the share of its pixels
labelled some pickupable type. Masks as agents made them before ``refined-masks`` (each cell
repeated; ``guided_masks.py`` measures the refinement). Objects labelled as objects (0.8 of
their pixels or more) that no mask covers at IoU 0.5 are split by why: the best mask spills
over (its precision under 0.5), covers too little of it (recall under 0.5), or both.

    .venv/bin/python docs/research/probes/mask_misses.py agents/segmenter-v2 \\
        --data data/segmenter/HeteroTidy-v2/val --frames 400
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import segmenter_probe

from maniskill_tidy.envs.actions import MIN_PIXELS

SIZES = {"all": (MIN_PIXELS, np.inf), "20-100 px": (MIN_PIXELS, 100), "100-400 px": (100, 400),
         "400 px or more": (400, np.inf)}  # fmt: skip


def census(truth, masks, labels_full, pickupable) -> list[dict]:
    """Per object of ``truth``: its area, the best IoU, precision and recall of a mask of its
    type and of any type, the same-type mask's score, and its pixels' share labelled objects."""
    out = []
    for t in truth:
        area = int(t.mask.sum())
        if area < MIN_PIXELS:
            continue
        row = {"area": area, "same": 0.0, "any": 0.0, "score": 0.0, "precision": 0.0,
               "recall": 0.0, "touching": 0,
               "objectish": float(pickupable[labels_full[t.mask]].mean())}  # fmt: skip
        for m in masks:
            inter = int((m.mask & t.mask).sum())
            if not inter:
                continue
            row["touching"] += 1
            size = int(m.mask.sum())
            iou = inter / (area + size - inter)
            if iou > row["any"]:
                row.update(any=iou, precision=inter / size, recall=inter / area)
            if m.cls == t.cls and iou > row["same"]:
                row.update(same=iou, score=m.score)
        out.append(row)
    return out


def main() -> None:
    args = segmenter_probe.arguments(__doc__)
    pickupable = segmenter_probe.pickupable_table()
    threshold = json.loads((Path(args.weights) / "card.json").read_text())["agent_threshold"]
    threshold = float(threshold["threshold"])
    g = segmenter_probe.GridLogits.load(args)
    labels, step = g.labels, g.step
    rows = []
    for k in range(len(g)):
        full = np.repeat(np.repeat(labels[k], step, axis=0), step, axis=1)
        rows += census(g.truth(k), [m.upscaled(step) for m in g.masks(k)], full, pickupable)
    print(
        f"{len(rows)} objects on {len(labels)} frames of {args.data}; agent threshold "
        f"{threshold:.3f}\n"
    )
    print("| size | objects | its type at IoU 0.5 | and above the threshold | any type at IoU 0.5 "
          "| no mask touches it | pixels labelled objects |")  # fmt: skip
    print("|---|---:|---:|---:|---:|---:|---:|")
    for name, (lo, hi) in SIZES.items():
        r = [x for x in rows if lo <= x["area"] < hi]

        def share(f, r=r) -> float:
            return float(np.mean([f(x) for x in r]))

        print(f"| {name} | {len(r)} | {share(lambda x: x['same'] >= 0.5):.2f} | "
              f"{share(lambda x: x['same'] >= 0.5 and x['score'] >= threshold):.2f} | "
              f"{share(lambda x: x['any'] >= 0.5):.2f} | {share(lambda x: x['touching'] == 0):.2f} "
              f"| {share(lambda x: x['objectish']):.2f} |")  # fmt: skip
    missed = [x for x in rows if x["objectish"] >= 0.8 and x["any"] < 0.5]
    spill = np.mean([x["precision"] < 0.5 <= x["recall"] for x in missed])
    short = np.mean([x["recall"] < 0.5 <= x["precision"] for x in missed])
    both = np.mean([x["recall"] < 0.5 and x["precision"] < 0.5 for x in missed])
    print(f"\n{len(missed)} objects with 0.8 of their pixels or more labelled objects, no mask at "
          f"IoU 0.5: the best mask spills over {spill:.2f}, covers too little {short:.2f}, both "
          f"{both:.2f} (median masks touching one: "
          f"{np.median([x['touching'] for x in missed]):.0f})")  # fmt: skip


if __name__ == "__main__":
    main()
