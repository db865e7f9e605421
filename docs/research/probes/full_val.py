"""Segmenters compared on every val frame, not the 400 their training selects epochs on: mask
AP and AP50 over the pickupable types and the best-F1 agent threshold's precision and recall,
each through the graph agents run (``served_segmenter``), instances made as agents make them.
Two segmenters whose 400-frame val figures tie are told apart on eight times the frames,
still without the test houses.

    .venv/bin/python docs/research/probes/full_val.py agents/segmenter-v2 \\
        agents/experiments/segmenter-v2-extra2 --data data/segmenter/HeteroTidy-v2/val
"""

from __future__ import annotations

import argparse
from pathlib import Path

from maniskill_tidy.models.checkpoints import served_segmenter
from maniskill_tidy.training.segmenter_trainer import agent_threshold, evaluate, load_split


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("weights", nargs="+", help="trained segmenters' folders")
    ap.add_argument("--data", default="data/segmenter/HeteroTidy-v2/val")
    args = ap.parse_args()
    frames = load_split(Path(args.data))
    print(f"{len(frames['rgb'])} frames of {args.data}")
    print("| segmenter | served sha256 | AP | AP50 | AP50 small / medium / large | "
          "threshold: F1 (P, R) |")  # fmt: skip
    print("|---|---|---:|---:|---|---|")
    for folder in args.weights:
        runtime, sha, _ = served_segmenter(Path(folder), 2)
        s, t = evaluate(runtime, frames), agent_threshold(runtime, frames)
        print(f"| {folder} | {sha[:12]} | {s['AP']:.3f} | {s['AP50']:.3f} | "
              f"{s['AP_small']:.3f} / {s['AP_medium']:.3f} / {s['AP_large']:.3f} | "
              f"{t['threshold']:.3f}: {t['f1']:.3f} ({t['precision']:.2f}, {t['recall']:.2f}) |",
              flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
