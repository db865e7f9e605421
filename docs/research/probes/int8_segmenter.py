"""What int8 static quantization in ONNX Runtime would buy the pixels track's segmenter: ms per
frame (3-frame batches, 2 threads, as agents call it) of the fp32 graph and of QDQ int8 graphs
calibrated on val frames (MinMax, Percentile), and each one's val mask AP50 scored as the card
scores (the quantized graph standing in for torch). Run it on an idle machine.

    .venv/bin/python docs/research/probes/int8_segmenter.py agents/segmenter-v2 \\
        --data data/segmenter/HeteroTidy-v2/val --out out/int8
"""

from __future__ import annotations

import argparse
import io
import time
import warnings
from pathlib import Path

import numpy as np
import onnxruntime as ort
import torch
from onnxruntime import quantization as q

from maniskill_tidy.models import checkpoints
from maniskill_tidy.models.segmenter import _Served
from maniskill_tidy.training import segmenter_trainer


def session(path: Path) -> ort.InferenceSession:
    options = ort.SessionOptions()
    options.intra_op_num_threads, options.inter_op_num_threads = 2, 1
    options.add_session_config_entry("session.intra_op.allow_spinning", "0")
    return ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("weights")
    ap.add_argument("--data", default="data/segmenter/HeteroTidy-v2/val")
    ap.add_argument("--out", default="out/int8", help="where the graphs are written")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    model = checkpoints.load_segmenter(Path(args.weights))[0]
    buf = io.BytesIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(
            _Served(model.eval()), (torch.zeros(1, 64, 64, 3, dtype=torch.uint8),
            torch.zeros(1, 64, 64)), buf, dynamo=False, opset_version=17,
            input_names=["rgb", "depth"], output_names=["label", "prob"],
            dynamic_axes={k: {0: "batch", 1: "height", 2: "width"} for k in ("rgb", "depth")},
        )  # fmt: skip
    (out / "fp32.onnx").write_bytes(buf.getvalue())
    q.quant_pre_process(str(out / "fp32.onnx"), str(out / "pre.onnx"), skip_symbolic_shape=True)
    val = segmenter_trainer.load_split(Path(args.data), 400)
    depth = val["depth_mm"].astype(np.float32) / 1000.0

    class Calibration(q.CalibrationDataReader):
        """96 val frames, 4 at a time."""

        def __init__(self) -> None:
            self.i = 0

        def get_next(self):
            if self.i >= 96:
                return None
            s = slice(self.i, self.i + 4)
            self.i += 4
            return {"rgb": val["rgb"][s], "depth": depth[s]}

    graphs = {"fp32": out / "fp32.onnx"}
    for method in (q.CalibrationMethod.MinMax, q.CalibrationMethod.Percentile):
        graphs[method.name] = out / f"int8_{method.name}.onnx"
        q.quantize_static(str(out / "pre.onnx"), str(graphs[method.name]), Calibration(),
                          quant_format=q.QuantFormat.QDQ, per_channel=True,
                          activation_type=q.QuantType.QUInt8, weight_type=q.QuantType.QInt8,
                          calibrate_method=method, op_types_to_quantize=["Conv"])  # fmt: skip
    sessions = {name: session(path) for name, path in graphs.items()}
    feed = {"rgb": val["rgb"][:3], "depth": depth[:3]}
    for s in sessions.values():
        for _ in range(5):
            s.run(None, feed)
    for _ in range(2):  # twice over, interleaved: the spread is the machine's noise
        for name, s in sessions.items():
            start = time.perf_counter()
            for _ in range(60):
                s.run(None, feed)
            print(f"{name}: {(time.perf_counter() - start) / 180 * 1000:.2f} ms per frame")
    for name, s in sessions.items():

        def predict(model, rgb, depth_m, batch=16, s=s):
            parts = [s.run(None, {"rgb": np.ascontiguousarray(rgb[i : i + batch]),
                                  "depth": np.ascontiguousarray(depth_m[i : i + batch])})
                     for i in range(0, len(rgb), batch)]  # fmt: skip
            return tuple(np.concatenate(p) for p in zip(*parts, strict=True))

        segmenter_trainer.predict = predict  # the card's scoring through this graph
        print(f"{name}: val mask AP50 {segmenter_trainer.evaluate(model, val)['AP50']:.3f}")


if __name__ == "__main__":
    main()
