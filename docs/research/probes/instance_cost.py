"""What splitting a segmenter's labels into instances costs per frame, as agents split them
(on the network's grid; robots, furniture and pickupable types; object parts on depth edges
joined), with the masks made and the classes present per frame: the cost follows how many types
a segmenter calls in a frame, not its weights' size. Run it on an idle machine.

    .venv/bin/python docs/research/probes/instance_cost.py agents/segmenter-v2 \\
        agents/experiments/segmenter-v2-wp075 --frames 200
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from maniskill_tidy.models import checkpoints
from maniskill_tidy.models.segmenter import predict
from maniskill_tidy.perception.instances import coarse, split_instances
from maniskill_tidy.perception.seg_classes import seg_classes
from maniskill_tidy.training.segmenter_trainer import load_split


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("weights", nargs="+")
    ap.add_argument("--data", default="data/segmenter/HeteroTidy-v2/val")
    ap.add_argument("--frames", type=int, default=200)
    args = ap.parse_args()
    c = seg_classes()
    split = [i for i, n in enumerate(c.names)
             if n == "robot" or n.startswith("furniture:") or c.is_pickupable(i)]  # fmt: skip
    frames = load_split(Path(args.data), args.frames)
    depth = frames["depth_mm"].astype(np.float32) / 1000.0
    for folder in args.weights:
        labels, probs = predict(checkpoints.load_segmenter(Path(folder))[0], frames["rgb"], depth)
        step = depth.shape[1] // labels.shape[1]
        grids = [coarse(d, step) for d in depth]
        start, masks = time.perf_counter(), 0
        for k in range(len(labels)):
            masks += len(split_instances(labels[k], grids[k], split, probs[k], 5))
        ms = (time.perf_counter() - start) / len(labels) * 1000
        present = np.mean([len(np.unique(x)) for x in labels])
        print(
            f"{folder}: {ms:.2f} ms per frame, {masks / len(labels):.1f} masks, "
            f"{present:.1f} classes present"
        )


if __name__ == "__main__":
    main()
