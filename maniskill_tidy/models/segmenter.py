"""The pixels track's segmenter: a small U-Net from RGB-D to a class per pixel.

A stand-in for the paper's Mask R-CNN, trained from scratch on the project's own renders
(no detector weights install offline, and torchvision's wheels do not load beside the CPU
torch these machines use). Semantic classes per pixel (``perception/seg_classes.py``);
instances come after, from connected components split at depth edges
(``perception/instances.py``). The logits come out at half the input's resolution: on 2 CPU
cores, full-resolution logits over ~100 classes cost more than the rest of the network
(``shared/reference/segmenter-feasibility.md``). Agents make their instances on that grid too
(a quarter of the pixels to label, split and locate) and upsample the result by nearest
neighbour.
Agents run it through ONNX Runtime (:class:`Runtime`), about 2.5x faster than eager torch here
for the same weights, as the int8 graph shipped beside the weights (:func:`int8_graph`) when
there is one; training uses torch (:func:`predict`), the cards score what agents run.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

DEPTH_SCALE = 5.0  # metres: depth enters the network divided by this
# ``relief``: depth less its mean over these windows (px), through tanh at this scale (metres)
RELIEF_WINDOWS = (7, 21)
RELIEF_SCALE = 0.05


def box_mean(x: torch.Tensor, k: int) -> torch.Tensor:
    """Mean over a k x k window (over the frame's pixels only at its borders), as two 1-D
    passes: 2k additions per pixel in ONNX Runtime, not k * k."""
    x = F.avg_pool2d(x, (1, k), 1, (0, k // 2), count_include_pad=False)
    return F.avg_pool2d(x, (k, 1), 1, (k // 2, 0), count_include_pad=False)


def relief(depth: torch.Tensor) -> torch.Tensor:
    """How far each pixel stands in front of (negative) or behind the surface around it, in
    metres along its ray, per window of ``RELIEF_WINDOWS``, squashed to -1..1: an object a few
    centimetres tall on a table is 0.005 of depth / ``DEPTH_SCALE``, a difference the first
    convolution hardly weighs next to colour (ranking masks by that contrast lifted val AP50:
    research log). The surround is averaged in disparity, which is linear across the image on
    any plane, so floors, walls and table tops seen at a slant read 0, not their curvature:
    ``d * d * mean(1 / d) - d``."""
    d = depth.clamp(min=0.05)
    return torch.cat(
        [torch.tanh((d * d * box_mean(1.0 / d, k) - d) / RELIEF_SCALE) for k in RELIEF_WINDOWS],
        dim=1,
    )


def block(cin: int, cout: int, stride: int = 1) -> nn.Sequential:
    """Conv, norm, ReLU, twice (the first may stride)."""
    return nn.Sequential(
        nn.Conv2d(cin, cout, 3, stride, 1, bias=False),
        nn.BatchNorm2d(cout),
        nn.ReLU(inplace=True),
        nn.Conv2d(cout, cout, 3, 1, 1, bias=False),
        nn.BatchNorm2d(cout),
        nn.ReLU(inplace=True),
    )


class Segmenter(nn.Module):
    """RGB (uint8-valued floats) and depth (metres) -> class logits at half resolution."""

    def __init__(
        self,
        classes: int,
        widths: tuple[int, ...] = (24, 32, 32, 48, 64),
        stem: int = 0,
        head: int = 0,
        relief: bool = False,
        make_block=block,
    ) -> None:
        """``make_block(cin, cout, stride)``: each level's layers (:func:`block`; a probe
        times other ones, torchvision's ResNet takes its block the same way)."""
        super().__init__()
        self.classes, self.widths, self.stem_width, self.head_width = (
            classes, tuple(widths), stem, head
        )  # fmt: skip
        # ``relief``: the depth's local relief (:func:`relief`) enters beside RGB-D
        self.relief = relief
        inputs = 4 + (len(RELIEF_WINDOWS) if relief else 0)
        # ``stem`` > 0: one convolution at the frame's full resolution before the first stride,
        # so that a small object's detail reaches a learned filter before it is subsampled
        self.stem = nn.Identity() if not stem else nn.Sequential(
            nn.Conv2d(inputs, stem, 3, 1, 1, bias=False), nn.BatchNorm2d(stem),
            nn.ReLU(inplace=True),
        )  # fmt: skip
        self.down = nn.ModuleList()
        cin = stem or inputs
        for w in widths:  # stride 2, 4, 8, 16, 32
            self.down.append(make_block(cin, w, stride=2))
            cin = w
        self.up = nn.ModuleList(
            make_block(widths[i + 1] + widths[i], widths[i])
            for i in reversed(range(len(widths) - 1))
        )
        # ``head`` > 0: a hidden 1 x 1 layer this wide before the class logits, so that ~100
        # classes are told apart from more than the first level's few channels per pixel
        self.head = nn.Conv2d(widths[0], classes, 1) if not head else nn.Sequential(
            nn.Conv2d(widths[0], head, 1, bias=False), nn.BatchNorm2d(head),
            nn.ReLU(inplace=True), nn.Conv2d(head, classes, 1),
        )  # fmt: skip

    def forward(self, rgb: torch.Tensor, depth: torch.Tensor) -> torch.Tensor:
        """``rgb`` (B, 3, H, W) in 0..255, ``depth`` (B, 1, H, W) in metres."""
        parts = [rgb / 127.5 - 1.0, depth / DEPTH_SCALE]
        if self.relief:
            parts.append(relief(depth))
        x = self.stem(torch.cat(parts, dim=1))
        skips = []
        for down in self.down:
            x = down(x)
            skips.append(x)
        x = skips.pop()
        for up in self.up:
            skip = skips.pop()
            x = F.interpolate(x, size=skip.shape[-2:], mode="nearest")
            x = up(torch.cat([x, skip], dim=1))
        return self.head(x)  # (B, classes, H / 2, W / 2)

    def config(self) -> dict:
        return {"classes": self.classes, "widths": list(self.widths), "stem": self.stem_width,
                "head": self.head_width, "relief": self.relief}  # fmt: skip


def predict(model: Segmenter, rgb: np.ndarray, depth_m: np.ndarray, batch: int = 16):
    """Labels (N, H/2, W/2) uint8 and their confidence (N, H/2, W/2) float32, at the network's
    resolution, in torch: what :class:`Runtime` gives agents. Each frame's output depends on
    that frame alone (the network is in eval mode)."""
    head = LabelHead(model.eval())
    labels, probs = [], []
    with torch.inference_mode():
        for s in range(0, len(rgb), batch):
            r = torch.from_numpy(np.array(rgb[s : s + batch])).permute(0, 3, 1, 2).float()
            d = torch.from_numpy(np.array(depth_m[s : s + batch], dtype=np.float32))
            label, prob = head(r, d.reshape(len(d), 1, *rgb.shape[1:3]))
            labels.append(label.numpy())
            probs.append(prob.numpy())
    return np.concatenate(labels), np.concatenate(probs)


def upsample(label: np.ndarray, prob: np.ndarray, size) -> tuple[np.ndarray, np.ndarray]:
    """Nearest-neighbour to ``size`` (H, W): each output pixel takes its source cell's value."""
    h, w = size
    rows, cols = np.arange(h) * label.shape[1] // h, np.arange(w) * label.shape[2] // w
    prows, pcols = np.arange(h) * prob.shape[1] // h, np.arange(w) * prob.shape[2] // w
    return label[:, rows][:, :, cols], prob[:, prows][:, :, pcols]


class LabelHead(nn.Module):
    """The segmenter ending in each pixel's label (at half resolution) and a confidence: the
    sigmoid of the margin between the two best logits, 0.5 (a tie) to 1. It ranks masks and
    weighs their votes as the softmax's maximum would, for the price of a top-2 instead of
    ~100 exponentials per cell (half a millisecond per frame less on 2 cores); on val it ranks
    masks as well (mask AP50 0.217 against 0.211), where the softmax sampled on a coarser grid
    to save time fell to 0.127 (small objects took their neighbours' confidence)."""

    def __init__(self, model: Segmenter) -> None:
        super().__init__()
        self.model = model

    def forward(self, rgb: torch.Tensor, depth: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        best, label = self.model(rgb, depth).topk(2, dim=1)
        return label[:, 0].to(torch.uint8), torch.sigmoid(best[:, 0] - best[:, 1])


class _Served(nn.Module):
    """:class:`LabelHead` on the frames as the env gives them, (N, H, W, 3) uint8 and (N, H, W)
    metres: the layout change and the cast run inside the graph, not in numpy per step."""

    def __init__(self, model: Segmenter) -> None:
        super().__init__()
        self.head = LabelHead(model)

    def forward(self, rgb: torch.Tensor, depth: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return self.head(rgb.permute(0, 3, 1, 2).float(), depth.unsqueeze(1))


INT8_CALIBRATION = 96  # val frames whose activations set the int8 graph's ranges (MinMax)


def onnx_graph(model: Segmenter) -> bytes:
    """:class:`_Served` as an fp32 ONNX graph, exported from the torch weights."""
    import io
    import warnings

    rgb, depth = torch.zeros(1, 64, 64, 3, dtype=torch.uint8), torch.zeros(1, 64, 64)
    buf = io.BytesIO()
    with warnings.catch_warnings():  # the TorchScript exporter's deprecation notice
        warnings.simplefilter("ignore")
        torch.onnx.export(
            _Served(model.eval()), (rgb, depth), buf, dynamo=False, opset_version=17,
            input_names=["rgb", "depth"], output_names=["label", "prob"],
            dynamic_axes={"rgb": {0: "batch", 1: "height", 2: "width"},
                          "depth": {0: "batch", 1: "height", 2: "width"}},
        )  # fmt: skip
    return buf.getvalue()


def int8_graph(model: Segmenter, rgb: np.ndarray, depth_m: np.ndarray,
               fp32: tuple[str, ...] = ("first", "head")) -> bytes:  # fmt: skip
    """The served graph with int8 convolutions (ONNX Runtime's static QDQ quantization:
    per-channel int8 weights, uint8 activations whose ranges are the min and max seen on
    ``rgb``/``depth_m``, val frames); the same frames give the same graph. The convolutions
    in ``fp32`` stay so: by default the first (RGB-D in: 8 bits of depth are 2 cm steps over
    5 m, coarser than the relief that tells an object from the table it lies on) and the label
    head (the margin between two logits is the masks' confidence): with them in int8 the
    shipped v2 segmenter lost 0.016 of val mask AP50, without them 0.001
    (``docs/research/probes/int8_segmenter.py``)."""
    if unknown := set(fp32) - {"first", "head"}:
        raise ValueError(f"fp32 {sorted(unknown)}: expected 'first' and/or 'head'")
    import tempfile

    import onnx
    from onnxruntime import quantization as q

    class Frames(q.CalibrationDataReader):
        def __init__(self) -> None:
            self.starts = iter(range(0, len(rgb), 4))

        def get_next(self):
            s = next(self.starts, None)
            if s is None:
                return None
            return {
                "rgb": np.ascontiguousarray(rgb[s : s + 4], dtype=np.uint8),
                "depth": np.ascontiguousarray(depth_m[s : s + 4], dtype=np.float32),
            }

    with tempfile.TemporaryDirectory() as tmp:
        full, pre, out = (Path(tmp) / n for n in ("fp32.onnx", "pre.onnx", "int8.onnx"))
        full.write_bytes(onnx_graph(model))
        q.quant_pre_process(str(full), str(pre), skip_symbolic_shape=True)
        convs = [n.name for n in onnx.load(str(pre)).graph.node if n.op_type == "Conv"]
        q.quantize_static(
            str(pre), str(out), Frames(), quant_format=q.QuantFormat.QDQ, per_channel=True,
            activation_type=q.QuantType.QUInt8, weight_type=q.QuantType.QInt8,
            calibrate_method=q.CalibrationMethod.MinMax, op_types_to_quantize=["Conv"],
            # in graph order: RGB-D in, labels out
            nodes_to_exclude=[n for n, k in ((convs[0], "first"), (convs[-1], "head"))
                              if k in fp32],
        )  # fmt: skip
        return out.read_bytes()


class Runtime:
    """The segmenter served by ONNX Runtime with ``threads`` threads: what agents call on
    their frames. From the torch weights (exported in memory, nothing written; labels equal
    :func:`predict`'s up to float rounding) or from a graph's bytes (the shipped int8 one)."""

    def __init__(self, model: Segmenter | bytes, threads: int = 1) -> None:
        import onnxruntime as ort

        graph = model if isinstance(model, bytes) else onnx_graph(model)
        options = ort.SessionOptions()
        options.intra_op_num_threads, options.inter_op_num_threads = threads, 1
        # no spinning between calls: the renderer needs those cores the moment a call returns
        options.add_session_config_entry("session.intra_op.allow_spinning", "0")
        self.session = ort.InferenceSession(graph, options, providers=["CPUExecutionProvider"])

    def __call__(self, rgb: np.ndarray, depth_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Frames (N, H, W, 3) uint8 and depth (N, H, W) metres -> labels (N, H/2, W/2) uint8
        and their confidence, at the network's resolution (:func:`upsample` for the frames')."""
        n, h, w = rgb.shape[:3]
        feed = {
            "rgb": np.ascontiguousarray(rgb, dtype=np.uint8),
            "depth": np.ascontiguousarray(depth_m, dtype=np.float32).reshape(n, h, w),
        }
        label, prob = self.session.run(None, feed)
        return label, prob

    def predict(self, rgb: np.ndarray, depth_m: np.ndarray, batch: int = 16):
        """:func:`predict` through this graph: many frames, ``batch`` at a time."""
        starts = range(0, len(rgb), batch)
        parts = [self(rgb[s : s + batch], depth_m[s : s + batch]) for s in starts]
        return tuple(np.concatenate(p) for p in zip(*parts, strict=True))
