"""Does depth contrast tell object masks from false ones, and does it drop real thin objects?
Val mask AP50 and best F1 of a segmenter's object masks (made as agents make them, on the
network's grid) scored by confidence alone, kept only above a contrast, and scored by
confidence times the logistic of a relief over a scale: the median depth contrast with the
ring around the mask (``perception/instances.py: depth_contrast``) or its height above the
ring's plane (``plane_relief``, the median contrast where no plane fits). Then, for the masks a
perfect segmenter gives (the frames' own classes, each mask's score 1), the share of real
objects each gate keeps at ``KEEP_THRESHOLD``: for all objects and for thin ones (every asset
of the type under 1.5 cm in some dimension: credit cards, CDs, pens, pencils).

    .venv/bin/python docs/research/probes/depth_contrast.py agents/segmenter-v2 \\
        --data data/segmenter/HeteroTidy-v2/val --frames 400
"""

from __future__ import annotations

import dataclasses
from collections import defaultdict

import numpy as np
import segmenter_probe

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.eval.mask_ap import mask_ap, score_threshold
from maniskill_tidy.knowledge.catalog import load_assets
from maniskill_tidy.models.segmenter import predict
from maniskill_tidy.perception.instances import (
    coarse,
    depth_contrast,
    plane_relief,
    split_instances,
)
from maniskill_tidy.perception.seg_classes import seg_classes
from maniskill_tidy.policies.pixels import KEEP_THRESHOLD
from maniskill_tidy.training.segmenter_trainer import truth_masks

THIN = 0.015  # metres


def thin_types() -> set[str]:
    smallest: dict[str, float] = defaultdict(float)
    for kind, *size in load_assets().values():
        smallest[kind] = max(smallest[kind], min(size))
    return {k for k, s in smallest.items() if s < THIN}


def logistic(x: float, scale: float) -> float:
    return 1.0 / (1.0 + np.exp(-x / scale))


GATES = {  # name -> gate of (median contrast, plane relief)
    "median contrast / 1 cm (shipped)": lambda con, rel: logistic(con, 0.01),
    **{f"plane relief / {s * 1000:.0f} mm": lambda con, rel, s=s: logistic(
        con if np.isnan(rel) else rel, s) for s in (0.002, 0.003, 0.005, 0.01)},
    **{f"median contrast / {s * 1000:.0f} mm": lambda con, rel, s=s: logistic(con, s)
       for s in (0.003, 0.005)},
}  # fmt: skip


def reliefs(masks, grid) -> list[tuple]:
    return [(m, depth_contrast(m, grid), plane_relief(m, grid)) for m in masks]


def main() -> None:
    args = segmenter_probe.arguments(__doc__)
    c = seg_classes()
    pick = [i for i in range(len(c.names)) if c.is_pickupable(i)]
    thin = {i for i in pick if c.names[i] in thin_types()}
    frames = segmenter_probe.frames(args)
    depth = frames["depth_mm"].astype(np.float32) / 1000
    model = segmenter_probe.segmenter(args)[0]
    labels, probs = predict(model, frames["rgb"], depth)
    step = depth.shape[1] // labels.shape[1]
    least = -(-MIN_PIXELS // step**2)
    rows = []  # per frame: truth, [(mask on the grid, contrast, relief)]
    perfect = []  # (class, contrast, relief) of each perfect-label mask over a real object
    for k in range(len(labels)):
        grid = coarse(depth[k], step)
        masks = split_instances(labels[k], grid, pick, probs[k], least)
        rows.append((truth_masks(frames["cls"][k], frames["instance"][k], pick),
                     reliefs(masks, grid)))  # fmt: skip
        truth_labels = coarse(frames["cls"][k], step)
        for m, con, rel in reliefs(split_instances(truth_labels, grid, pick, None, least), grid):
            if m.cls:
                perfect.append((m.cls, con, rel))
    shape = depth.shape[1:3]
    print(f"{len(labels)} frames; {len(perfect)} perfect-label object masks, "
          f"{sum(p[0] in thin for p in perfect)} of thin types")  # fmt: skip

    def scored(name: str, f) -> None:
        pairs = [(t, [dataclasses.replace(m.upscaled(step), score=f(m.score, con, rel))
                      for m, con, rel in masks if f(m.score, con, rel) > 0])
                 for t, masks in rows]  # fmt: skip
        r = mask_ap(pairs, pick, shape, ignore_below=MIN_PIXELS)
        b = score_threshold(pairs, pick, shape, ignore_below=MIN_PIXELS)
        print(f"{name}: AP50 {r['AP50']:.3f}, AP {r['AP']:.3f}; best F1 {b['f1']:.3f} "
              f"(P {b['precision']:.2f}, R {b['recall']:.2f})")  # fmt: skip

    scored("confidence", lambda s, con, rel: s)
    for t in (0.0, 0.01, 0.02):
        scored(f"kept above {t:.2f} m", lambda s, con, rel, t=t: s if con > t else 0.0)
    for name, gate in GATES.items():
        scored(f"times {name}", lambda s, con, rel, g=gate: s * g(con, rel))
    print(f"perfect labels, share kept at {KEEP_THRESHOLD} (all / thin types):")
    for name, gate in GATES.items():
        kept = np.array([gate(con, rel) >= KEEP_THRESHOLD for _, con, rel in perfect])
        is_thin = np.array([cls in thin for cls, _, _ in perfect])
        print(f"  {name}: {kept.mean():.3f} / {kept[is_thin].mean():.3f}")


if __name__ == "__main__":
    main()
