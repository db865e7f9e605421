"""What a segmenter's widths cost as agents run it: ms per 224 px frame of the int8 graph
(``int8_graph``, calibrated on a few val frames; 3-frame batches, 2 threads), for the shipped
widths and candidates, with plain 3 x 3 convolutions or depthwise-separable ones (a depthwise
3 x 3 and a 1 x 1, MobileNet's way of buying width for fewer multiply-adds). Random weights:
the cost does not depend on them. Run it on an idle machine; the rows are interleaved three
times over, so their spread is the machine's noise.

    .venv/bin/python docs/research/probes/segmenter_widths_cost.py
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch
from torch import nn

from maniskill_tidy.models import segmenter
from maniskill_tidy.models.segmenter import Runtime, Segmenter, int8_graph
from maniskill_tidy.perception.seg_classes import seg_classes
from maniskill_tidy.training.segmenter_trainer import load_split

CANDIDATES = (
    ("plain", (24, 32, 32, 48, 64)),  # shipped
    ("plain", (32, 32, 32, 48, 64)),
    ("plain", (32, 32, 48, 64, 96)),
    ("plain", (32, 32, 64, 96, 128)),
    ("plain", (32, 40, 64, 96, 128)),
    ("plain", (32, 48, 48, 64, 96)),
    ("plain", (48, 48, 48, 64, 96)),
    ("separable", (24, 32, 32, 48, 64)),
    ("separable", (32, 48, 64, 96, 128)),
    ("separable", (48, 64, 64, 96, 128)),
)


def separable_block(cin: int, cout: int, stride: int = 1) -> nn.Sequential:
    """``segmenter.block`` with each 3 x 3 convolution depthwise then 1 x 1 (the first of the
    network, from 4 input channels, stays plain)."""

    def conv(ci: int, co: int, s: int) -> list[nn.Module]:
        if ci < 8:
            return [nn.Conv2d(ci, co, 3, s, 1, bias=False)]
        return [nn.Conv2d(ci, ci, 3, s, 1, groups=ci, bias=False), nn.BatchNorm2d(ci),
                nn.ReLU(inplace=True), nn.Conv2d(ci, co, 1, bias=False)]  # fmt: skip

    norm = (nn.BatchNorm2d(cout), nn.ReLU(inplace=True))
    return nn.Sequential(*conv(cin, cout, stride), *norm, *conv(cout, cout, 1),
                         nn.BatchNorm2d(cout), nn.ReLU(inplace=True))  # fmt: skip


def build(kind: str, widths: tuple[int, ...]) -> Segmenter:
    torch.manual_seed(0)
    make = separable_block if kind == "separable" else segmenter.block
    return Segmenter(len(seg_classes().names), widths, make_block=make).eval()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default="data/segmenter/HeteroTidy-v2/val",
                    help="frames to calibrate and time on")  # fmt: skip
    args = ap.parse_args()
    frames = load_split(args.data, 24)
    rgb, depth = frames["rgb"], frames["depth_mm"] / np.float32(1000.0)
    runtimes = {}
    for kind, widths in CANDIDATES:
        model = build(kind, widths)
        params = sum(p.numel() for p in model.parameters())
        runtimes[kind, widths] = (Runtime(int8_graph(model, rgb, depth), threads=2), params)
    feed = (rgb[:3], depth[:3])
    ms: dict = {k: [] for k in runtimes}
    for runtime, _ in runtimes.values():
        for _ in range(5):
            runtime(*feed)
    for _ in range(3):
        for k, (runtime, _) in runtimes.items():
            start = time.perf_counter()
            for _ in range(40):
                runtime(*feed)
            ms[k].append((time.perf_counter() - start) / 120 * 1000)
    print("| convolutions | widths | parameters | ms per frame (int8, three runs) |")
    print("|---|---|---:|---|")
    for (kind, widths), (_, params) in runtimes.items():
        spread = " ".join(f"{m:.2f}" for m in sorted(ms[kind, widths]))
        print(f"| {kind} | {', '.join(map(str, widths))} | {params:,} | {spread} |")


if __name__ == "__main__":
    main()
