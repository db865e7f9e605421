"""Milliseconds per 224 px frame of the pixels track's segmenter, eager torch against ONNX
Runtime, for a few widths (random weights: the cost does not depend on them).

    python scripts/segmenter_speed.py --threads 2 --batch 3

Run it on an idle machine; docs/pixels.md quotes it.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from maniskill_tidy.models.segmenter import LabelHead, Runtime, Segmenter
from maniskill_tidy.perception.seg_classes import seg_classes

WIDTHS = ((16, 24, 48, 64, 96), (16, 24, 32, 48, 64), (12, 16, 32, 48, 64), (8, 16, 24, 32, 48))


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
    args = p.parse_args()
    torch.set_num_threads(args.threads)
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, (args.batch, 224, 224, 3), dtype=np.uint8)
    depth = rng.uniform(0.3, 5.0, (args.batch, 224, 224)).astype(np.float32)
    r = torch.from_numpy(rgb).permute(0, 3, 1, 2).float()
    d = torch.from_numpy(depth)[:, None]
    n = len(seg_classes().names)
    print(f"{args.batch} frames per call, {args.threads} threads: ms per frame")
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


if __name__ == "__main__":
    main()
