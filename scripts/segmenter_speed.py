"""Milliseconds per 224 px frame of the pixels track's segmenter, eager torch against ONNX
Runtime, for a few widths (random weights: the cost does not depend on them); with
``--segmenters``, trained segmenters' fp32 graphs against the int8 graphs their agents run.

    python scripts/segmenter_speed.py --threads 2 --batch 3
    python scripts/segmenter_speed.py --segmenters agents/segmenter-v2 agents/segmenter-v1

Run it on an idle machine; docs/pixels.md quotes it.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from maniskill_tidy.models.segmenter import LabelHead, Runtime, Segmenter
from maniskill_tidy.perception.seg_classes import seg_classes

WIDTHS = ((24, 32, 32, 48, 64), (16, 24, 32, 48, 64), (12, 16, 32, 48, 64), (8, 16, 24, 32, 48))


def per_call(fn, repeats: int) -> float:
    fn()
    fn()
    start = time.perf_counter()
    for _ in range(repeats):
        fn()
    return (time.perf_counter() - start) / repeats


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--batch", type=int, default=3, help="frames per call (one per agent)")
    p.add_argument("--repeats", type=int, default=20)
    p.add_argument("--segmenters", nargs="*", default=[],
                   help="trained segmenters: fp32 against the graph agents run (int8)")  # fmt: skip
    args = p.parse_args()
    torch.set_num_threads(args.threads)
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, (args.batch, 224, 224, 3), dtype=np.uint8)
    depth = rng.uniform(0.3, 5.0, (args.batch, 224, 224)).astype(np.float32)
    r = torch.from_numpy(rgb).permute(0, 3, 1, 2).float()
    d = torch.from_numpy(depth)[:, None]
    n = len(seg_classes().names)
    print(f"{args.batch} frames per call, {args.threads} threads: ms per frame")
    if args.segmenters:
        served(args, rgb, depth)
        return
    for widths in WIDTHS:
        model = Segmenter(n, widths).eval()
        head = LabelHead(model)
        with torch.inference_mode():
            eager = per_call(lambda h=head: h(r, d), args.repeats)
        runtime = Runtime(model, args.threads)
        onnx = per_call(lambda rt=runtime: rt(rgb, depth), args.repeats)
        params = sum(x.numel() for x in model.parameters()) / 1e6
        print(f"widths {widths}: {params:.2f} M parameters, torch {eager / args.batch * 1e3:.1f}, "
              f"ONNX Runtime {onnx / args.batch * 1e3:.1f}")  # fmt: skip


def served(args, rgb: np.ndarray, depth: np.ndarray) -> None:
    """Each segmenter's fp32 export and the graph its agents run, three rounds interleaved (the
    spread between rounds is the machine's noise)."""
    from maniskill_tidy.models.checkpoints import load_segmenter, served_segmenter

    runs = {}
    for folder in args.segmenters:
        runs[f"{folder} fp32"] = Runtime(load_segmenter(folder)[0], args.threads)
        runs[f"{folder} served"] = served_segmenter(folder, args.threads)[0]
    times: dict[str, list[float]] = {k: [] for k in runs}
    for _ in range(3):
        for k, rt in runs.items():
            times[k].append(per_call(lambda rt=rt: rt(rgb, depth), args.repeats) / args.batch)
    for k, t in times.items():
        print(f"{k}: {np.median(t) * 1e3:.2f} ms (rounds {', '.join(f'{x * 1e3:.2f}' for x in t)})")


if __name__ == "__main__":
    main()
