"""Would a threshold per type let agents find the types one threshold leaves out? With the one
best-F1 threshold, a few types are never kept (their masks score low even when right: Mug,
TissueBox, AlarmClock, HandTowel, PaperTowelRoll on val). Each type's own best-F1 threshold,
for the types with at least ``--least`` objects, is chosen on half of the val houses (every
other shard) and scored on the other half, against the one threshold chosen on the same half:
precision, recall and F1 at IoU 0.5 of the masks kept, made as agents make them through the
int8 graph agents run. Both halves in turn.

    .venv/bin/python docs/research/probes/type_thresholds.py agents/segmenter-v2 \\
        --data data/segmenter/HeteroTidy-v2/val
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.eval.mask_ap import best_f1, matches_by_class
from maniskill_tidy.models.checkpoints import served_segmenter
from maniskill_tidy.training.segmenter_trainer import instance_pairs


def scored(m: dict, common: float, own: dict[int, float]) -> str:
    """Precision, recall and F1 of the masks kept: each type's own threshold, else ``common``."""
    tp = sum(int(h[s >= own.get(c, common)].sum()) for c, (s, h, _) in m.items())
    kept = sum(int((s >= own.get(c, common)).sum()) for c, (s, _, _) in m.items())
    truths = sum(t for _, _, t in m.values())
    p, r = tp / max(kept, 1), tp / max(truths, 1)
    return f"P {p:.3f} R {r:.3f} F1 {2 * p * r / max(p + r, 1e-12):.3f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("weights", help="a trained segmenter's folder, e.g. agents/segmenter-v2")
    ap.add_argument("--data", default="data/segmenter/HeteroTidy-v2/val")
    ap.add_argument(
        "--least",
        type=int,
        nargs="+",
        default=[5, 10, 20],
        help="objects a type needs on the choosing half for its own threshold",
    )
    args = ap.parse_args()
    runtime = served_segmenter(Path(args.weights), 2)[0]
    shards = sorted(Path(args.data).glob("house_*.npz"))
    halves = []
    for part in (shards[0::2], shards[1::2]):
        frames = {}
        for shard in part:
            with np.load(shard) as z:
                for k in ("rgb", "depth_mm", "cls", "instance"):
                    frames.setdefault(k, []).append(z[k])
        frames = {k: np.concatenate(v) for k, v in frames.items()}
        pairs, classes, labels = instance_pairs(runtime, frames)
        halves.append(matches_by_class(pairs, classes, labels.shape[1:3], MIN_PIXELS))
    print(f"{args.weights} on {args.data}: {len(shards)} houses in two halves")
    print("| chosen on | types with their own | one threshold | per type |")
    print("|---|---:|---|---|")
    for least in args.least:
        for name, (choose, score) in (("even", halves), ("odd", halves[::-1])):
            scores = np.concatenate([s for s, _, _ in choose.values()])
            hits = np.concatenate([h for _, h, _ in choose.values()])
            common = best_f1(scores, hits, sum(t for *_, t in choose.values()))["threshold"]
            own = {c: best_f1(s, h, t) for c, (s, h, t) in choose.items()
                   if t >= least and len(s)}  # fmt: skip
            own = {c: b["threshold"] for c, b in own.items() if b["f1"] > 0}
            print(f"| {name} houses (types of {least}+) | {len(own)} | "
                  f"{scored(score, common, {})} | {scored(score, common, own)} |")  # fmt: skip


if __name__ == "__main__":
    main()
