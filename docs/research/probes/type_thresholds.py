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
from maniskill_tidy.eval.mask_ap import _evaluated
from maniskill_tidy.models.checkpoints import served_segmenter
from maniskill_tidy.training.segmenter_trainer import instance_pairs


def matches(pairs, classes, shape) -> dict[int, tuple[np.ndarray, np.ndarray, int]]:
    """Per class: the kept masks' scores, whether each matched an object, and the objects."""
    ev = _evaluated(pairs, classes, shape, MIN_PIXELS)[0]
    out: dict[int, tuple[list, list, list]] = {}
    for e in ev.evalImgs:
        if e is None or e["aRng"] != ev.params.areaRng[0]:  # "all" sizes only
            continue
        scores, hits, truths = out.setdefault(e["category_id"], ([], [], [0]))
        keep = ~e["dtIgnore"][0].astype(bool)  # IoU 0.5
        scores += list(np.asarray(e["dtScores"])[keep])
        hits += list(e["dtMatches"][0][keep] > 0)
        truths[0] += int((~e["gtIgnore"].astype(bool)).sum())
    return {c: (np.array(s), np.array(h, bool), t[0]) for c, (s, h, t) in out.items()}


def best_threshold(scores: np.ndarray, hits: np.ndarray, truths: int) -> tuple[float, float]:
    """The score at the best F1 of the masks ranked by it, and that F1."""
    order = np.argsort(-scores, kind="stable")
    tp = np.cumsum(hits[order])
    f1 = 2 * tp / (np.arange(1, len(tp) + 1) + truths)
    k = int(np.argmax(f1))
    return float(scores[order][k]), float(f1[k])


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
        halves.append(matches(pairs, classes, labels.shape[1:3]))
    print(f"{args.weights} on {args.data}: {len(shards)} houses in two halves")
    print("| chosen on | types with their own | one threshold | per type |")
    print("|---|---:|---|---|")
    for least in args.least:
        for name, (choose, score) in (("even", halves), ("odd", halves[::-1])):
            scores = np.concatenate([s for s, _, _ in choose.values()])
            hits = np.concatenate([h for _, h, _ in choose.values()])
            common = best_threshold(scores, hits, sum(t for *_, t in choose.values()))[0]
            own = {c: best_threshold(s, h, t) for c, (s, h, t) in choose.items()
                   if t >= least and len(s)}  # fmt: skip
            own = {c: thr for c, (thr, f1) in own.items() if f1 > 0}
            print(f"| {name} houses (types of {least}+) | {len(own)} | "
                  f"{scored(score, common, {})} | {scored(score, common, own)} |")  # fmt: skip


if __name__ == "__main__":
    main()
