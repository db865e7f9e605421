"""What the int8 graph saves on this machine: ms per 224 px frame of a segmenter's shipped int8
graph and of the fp32 graph of the same weights (ONNX Runtime, 3-frame batches, 2 threads,
random frames), interleaved three times. Where the CPU has no int8 dot-product instructions
(AVX-512 VNNI, AVX-VNNI), the two cost about the same. Run it on an idle machine.

    .venv/bin/python docs/research/probes/int8_vs_fp32_cost.py agents/segmenter-v2
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from maniskill_tidy.models.checkpoints import INT8, load_segmenter
from maniskill_tidy.models.segmenter import Runtime


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("weights", type=Path, help="a trained segmenter's folder")
    ap.add_argument("--calls", type=int, default=50, help="timed batches per round")
    args = ap.parse_args()
    model, _ = load_segmenter(args.weights)
    graphs = {
        "int8": Runtime((args.weights / INT8).read_bytes(), 2),
        "fp32": Runtime(model.float().eval(), 2),
    }
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 255, (3, 224, 224, 3), dtype=np.uint8)
    depth = rng.uniform(0.5, 4.0, (3, 224, 224)).astype(np.float32)
    for round_ in range(3):
        for name, runtime in graphs.items():
            runtime(rgb, depth)  # warm
            start = time.perf_counter()
            for _ in range(args.calls):
                runtime(rgb, depth)
            ms = (time.perf_counter() - start) / (3 * args.calls) * 1000
            print(f"round {round_}: {name} {ms:.2f} ms a frame")


if __name__ == "__main__":
    main()
