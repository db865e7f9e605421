"""Where a pixels row's Success comes from: per number of misplaced objects in an episode (k),
the episodes, their Success from pixels and on ground truth, and the objects placed; then the
share of objects a team would have to place for Success to reach a given level if each object
were placed independently with one chance (Success = mean of p ** k over the row's episodes).
Reads two rows' records (a pixels row and its ground-truth partner), plays nothing.

    python docs/research/probes/success_by_count.py eval/results/setting_I/memory-v2-pixels \\
        eval/results/setting_I/memory-v2
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

import numpy as np
from scipy.optimize import brentq


def records(run: str) -> dict[str, dict]:
    lines = (Path(run) / "episodes.jsonl").read_text().splitlines()
    return {r["episode"]: r for r in map(json.loads, lines)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("pixels", help="a pixels row's folder")
    ap.add_argument("truth", help="the same team's ground-truth row in the same look")
    args = ap.parse_args()
    px, gt = records(args.pixels), records(args.truth)
    shared = sorted(set(px) & set(gt))
    rows = defaultdict(lambda: np.zeros(5, int))  # episodes, px success, gt success, placed, k
    for e in shared:
        r = px[e]
        rows[r["k"]] += [1, r["success"], gt[e]["success"], r["reasonable"], r["k"]]
    print("| k | episodes | Success (pixels) | Success (ground truth) | placed (pixels) |")
    print("|---:|---:|---:|---:|---:|")
    for k, (n, s_px, s_gt, placed, objects) in sorted(rows.items()):
        print(f"| {k} | {n} | {s_px / n:.2f} | {s_gt / n:.2f} | {placed} / {objects} |")
    ks = np.array([px[e]["k"] for e in shared])

    def independent(p: float) -> float:
        return float(np.mean(p**ks))

    placed = sum(px[e]["reasonable"] for e in shared) / ks.sum()
    placed_gt = sum(gt[e]["reasonable"] for e in shared) / ks.sum()
    gt_success = np.mean([gt[e]["success"] for e in shared])
    print(f"\nobjects placed: pixels {placed:.2f} (independent objects: Success "
          f"{independent(placed):.3f}), ground truth {placed_gt:.2f} "
          f"({independent(placed_gt):.3f}); ground truth's Success {gt_success:.3f}")  # fmt: skip
    for share in (0.5, 0.8):
        p = brentq(lambda p, s=share: independent(p) - s * gt_success, 1e-6, 1.0)
        print(f"Success {share:.1f} of ground truth's ({share * gt_success:.3f}) needs about "
              f"{p:.2f} of objects placed")  # fmt: skip


if __name__ == "__main__":
    main()
