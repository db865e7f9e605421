"""Does depth contrast tell object masks from false ones, and does it drop real thin objects?
Val mask AP50 and best F1 of a segmenter's object masks (made as agents make them, on the
network's grid) scored by confidence alone, kept only above a contrast, and scored by
confidence times the logistic of a relief over a scale: the median depth contrast with the
ring around the mask (``perception/instances.py: depth_contrast``) or its height above the
ring's plane (``plane_relief``, the median contrast where no plane fits, or where the plane
holds under a given share of the ring: ``relief`` ships 0.5). Then, for the masks a
perfect segmenter gives (the frames' own classes, each mask's score 1), the share of real
objects each gate keeps at ``KEEP_THRESHOLD`` and lets start a track (at that gate's best-F1
threshold): for all objects and for thin ones (every asset of the type under 1.5 cm in some
dimension: credit cards, CDs, pens, pencils); and the learned segmenter's recall of thin
objects there.

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
from maniskill_tidy.eval.pixels_losses import IOU
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
    return float(1.0 / (1.0 + np.exp(-np.clip(x / scale, -50, 50))))


SHARES = (0.0, 0.5, 0.75, 0.9)  # least share of the ring on its plane (0: any plane)


def planar(con: float, rel: dict, share: float) -> float:
    """The plane relief where a plane holds ``share`` of the ring, else the median contrast."""
    return con if np.isnan(rel[share]) else rel[share]


GATES = {  # name -> gate of (median contrast, {share: plane relief})
    "median contrast / 1 cm (was shipped)": lambda con, rel: logistic(con, 0.01),
    **{f"median contrast / {s * 1000:.0f} mm": lambda con, rel, s=s: logistic(con, s)
       for s in (0.003, 0.005)},
    **{f"plane relief / {s * 1000:.0f} mm, any plane": lambda con, rel, s=s: logistic(
        planar(con, rel, 0.0), s) for s in (0.002, 0.003, 0.005, 0.01)},
    **{f"plane relief / {s * 1000:.0f} mm, on {share} of the ring": lambda con, rel, s=s,
       share=share: logistic(planar(con, rel, share), s)
       for s in (0.002, 0.003) for share in SHARES[1:]},
}  # fmt: skip


def reliefs(masks, grid) -> list[tuple]:
    return [(m, depth_contrast(m, grid), {s: plane_relief(m, grid, share=s) for s in SHARES})
            for m in masks]  # fmt: skip


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

    def scored(name: str, f) -> float:
        pairs = [(t, [dataclasses.replace(m.upscaled(step), score=f(m.score, con, rel))
                      for m, con, rel in masks if f(m.score, con, rel) > 0])
                 for t, masks in rows]  # fmt: skip
        r = mask_ap(pairs, pick, shape, ignore_below=MIN_PIXELS)
        b = score_threshold(pairs, pick, shape, ignore_below=MIN_PIXELS)
        print(f"{name}: AP50 {r['AP50']:.3f}, AP {r['AP']:.3f}; best F1 {b['f1']:.3f} "
              f"(P {b['precision']:.2f}, R {b['recall']:.2f}) at {b['threshold']:.3f}; "
              f"thin objects found there {found(pairs, thin, b['threshold']):.2f}")  # fmt: skip
        return b["threshold"]

    scored("confidence", lambda s, con, rel: s)
    for t in (0.0, 0.01, 0.02):
        scored(f"kept above {t:.2f} m", lambda s, con, rel, t=t: s if con > t else 0.0)
    starts = {name: scored(f"times {name}", lambda s, con, rel, g=gate: s * g(con, rel))
              for name, gate in GATES.items()}  # fmt: skip
    print(f"perfect labels, share kept at {KEEP_THRESHOLD} / starting a track at the best F1's "
          "threshold (all; thin types):")  # fmt: skip
    is_thin = np.array([cls in thin for cls, _, _ in perfect])
    for name, gate in GATES.items():
        g = np.array([gate(con, rel) for _, con, rel in perfect])
        kept, start = g >= KEEP_THRESHOLD, g >= starts[name]
        print(f"  {name}: {kept.mean():.3f} / {start.mean():.3f}; "
              f"{kept[is_thin].mean():.3f} / {start[is_thin].mean():.3f}")  # fmt: skip


def found(pairs, classes: set[int], threshold: float) -> float:
    """Share of the true objects of ``classes`` (``MIN_PIXELS`` or more) a mask of their type
    scoring ``threshold`` or more covers with IoU 0.5: the recall agents get for them."""
    hit = n = 0
    for truth, masks in pairs:
        for t in truth:
            if t.cls not in classes or t.area < MIN_PIXELS:
                continue
            n += 1
            hit += any(m.cls == t.cls and m.score >= threshold
                       and (m.mask & t.mask).sum() >= IOU * (m.mask | t.mask).sum()
                       for m in masks)  # fmt: skip
    return hit / max(n, 1)


if __name__ == "__main__":
    main()
