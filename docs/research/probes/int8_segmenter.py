"""What int8 static quantization in ONNX Runtime buys a segmenter and what it costs: ms per
frame (3-frame batches, 2 threads, as agents call it) of its fp32 graph and of int8 graphs
with every convolution in int8, with the label head in fp32, and with the first convolution
and the label head in fp32 (what ``quantize-segmenter`` ships), each calibrated as that
command calibrates; and each one's val and test mask AP50 scored as the card scores. Run it on
an idle machine.

    .venv/bin/python docs/research/probes/int8_segmenter.py agents/segmenter-v2 \\
        --data data/segmenter/HeteroTidy-v2

A segmenter no longer shipped is read from history, for example the former v2 one (16, 24,
32, 48, 64 channels): ``mkdir -p out/w16 && for f in model.pt card.json; do git show
17af2ef~1:agents/segmenter-v2/$f > out/w16/$f; done``, then this probe on ``out/w16``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from maniskill_tidy.models import checkpoints
from maniskill_tidy.models.segmenter import Runtime, int8_graph, onnx_graph
from maniskill_tidy.training import segmenter_trainer as trainer

KEPT_FP32 = {"all int8": (), "label head fp32": ("head",), "shipped": ("first", "head")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("weights")
    ap.add_argument("--data", default="data/segmenter/HeteroTidy-v2")
    args = ap.parse_args()
    folder, data = Path(args.weights), Path(args.data)
    card = json.loads((folder / "card.json").read_text())
    val, test, _ = trainer._frames(card, data)
    model = checkpoints.load_segmenter(folder)[0]
    calibration = trainer.load_split(data / "val", trainer.INT8_CALIBRATION)
    depth = calibration["depth_mm"] / np.float32(1000.0)
    graphs = {"fp32": onnx_graph(model)}
    for name, fp32 in KEPT_FP32.items():
        graphs[name] = int8_graph(model, calibration["rgb"], depth, fp32)
    runtimes = {name: Runtime(g, threads=2) for name, g in graphs.items()}
    feed = (val["rgb"][:3], val["depth_mm"][:3] / np.float32(1000.0))
    for r in runtimes.values():
        for _ in range(5):
            r(*feed)
    ms = {name: [] for name in runtimes}
    for _ in range(2):  # twice over, interleaved: the spread is the machine's noise
        for name, r in runtimes.items():
            start = time.perf_counter()
            for _ in range(60):
                r(*feed)
            ms[name].append((time.perf_counter() - start) / 180 * 1000)
    for name, r in runtimes.items():
        v, t = trainer.evaluate(r, val)["AP50"], trainer.evaluate(r, test)["AP50"]
        spread = "-".join(f"{m:.2f}" for m in sorted(ms[name]))
        print(f"{name}: {spread} ms per frame, val mask AP50 {v:.3f}, test {t:.3f}", flush=True)


if __name__ == "__main__":
    main()
