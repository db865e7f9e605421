"""How a segmenter's mask confidence ranks masks, and what it costs (the pixels track's label
head, models/segmenter.py: LabelHead). On val frames: mask AP50 over the pickupable types with
each confidence (the softmax's maximum at half resolution, the same on every other cell, the
sigmoid of the two best logits' margin) and with masks under 8 or 20 pixels kept; then each
head's time per frame in ONNX Runtime, 2 threads, batches of 3 (run it on an idle machine);
first, which pixels it calls objects and with which type.

Its instances are split from the labels upsampled to the frames' full resolution, as the
pipeline did before agents made them on the network's half-resolution grid
(`perception/instances.py: coarse`); the research log's figures of this probe were measured so.
Its AP is therefore not the card's (`train-segmenter` scores instances as agents now make them).

    .venv/bin/python docs/research/probes/segmenter_confidence.py agents/segmenter-v2 \
        --data data/segmenter/HeteroTidy-v2/val --frames 400
"""

from __future__ import annotations

import io
import time
import warnings

import numpy as np
import segmenter_probe
import torch
from torch import nn

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.eval.mask_ap import mask_ap
from maniskill_tidy.models.segmenter import upsample
from maniskill_tidy.perception.instances import split_instances
from maniskill_tidy.perception.seg_classes import seg_classes
from maniskill_tidy.training.segmenter_trainer import truth_masks


def confidence(logits: torch.Tensor, kind: str) -> tuple[torch.Tensor, torch.Tensor]:
    """Labels and one kind of confidence, computing only what that kind needs (timed alone)."""
    if kind == "margin":
        best, label = logits.topk(2, dim=1)
        return label[:, 0].to(torch.uint8), torch.sigmoid(best[:, 0] - best[:, 1])
    label = logits.argmax(dim=1).to(torch.uint8)
    if kind == "softmax":
        return label, 1 / torch.exp(logits - logits.amax(1, keepdim=True)).sum(1)
    coarse = logits[:, :, ::2, ::2]
    return label, 1 / torch.exp(coarse - coarse.amax(1, keepdim=True)).sum(1)


KINDS = ("softmax", "softmax, every other cell", "margin")


class Head(nn.Module):
    def __init__(self, model: nn.Module, kind: str) -> None:
        super().__init__()
        self.model, self.kind = model, kind

    def forward(self, rgb, depth):
        return confidence(self.model(rgb, depth), self.kind)


def ms_per_frame(model: nn.Module, kind: str, repeats: int = 6) -> float:
    import onnxruntime as ort

    buf = io.BytesIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(
            Head(model, kind),
            (torch.zeros(1, 3, 64, 64), torch.zeros(1, 1, 64, 64)),
            buf,
            dynamo=False,
            opset_version=17,
            input_names=["rgb", "depth"],
            dynamic_axes={n: {0: "b", 2: "h", 3: "w"} for n in ("rgb", "depth")},
        )
    options = ort.SessionOptions()
    options.intra_op_num_threads, options.inter_op_num_threads = 2, 1
    session = ort.InferenceSession(buf.getvalue(), options, providers=["CPUExecutionProvider"])
    rng = np.random.default_rng(0)
    feed = {
        "rgb": rng.uniform(0, 255, (3, 3, 224, 224)).astype(np.float32),
        "depth": rng.uniform(0.3, 4, (3, 1, 224, 224)).astype(np.float32),
    }
    for _ in range(5):
        session.run(None, feed)
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        for _ in range(10):
            session.run(None, feed)
        times.append((time.perf_counter() - t) / 30 * 1000)
    return float(np.median(times))


def main() -> None:
    args = segmenter_probe.arguments(__doc__)
    model = segmenter_probe.segmenter(args)[0]
    frames = segmenter_probe.frames(args)
    classes = seg_classes()
    pick = [i for i in range(len(classes.names)) if classes.is_pickupable(i)]
    depth = frames["depth_mm"].astype(np.float32) / 1000
    labels, conf = [], {}
    with torch.inference_mode():
        for s in range(0, len(depth), 16):
            rgb = torch.from_numpy(frames["rgb"][s : s + 16]).permute(0, 3, 1, 2).float()
            logits = model(rgb, torch.from_numpy(depth[s : s + 16])[:, None])
            labels.append(confidence(logits, "margin")[0].numpy())
            for kind in KINDS:
                conf.setdefault(kind, []).append(confidence(logits, kind)[1].numpy())
    truth = [truth_masks(frames["cls"][i], frames["instance"][i], pick) for i in range(len(depth))]
    full = upsample(np.concatenate(labels), np.concatenate(labels), depth.shape[1:])[0]
    on = classes.is_pickupable(frames["cls"]) & (frames["cls"] > 0)
    said = classes.is_pickupable(full) & (full > 0)
    both = on & said
    print(
        f"object pixels labelled as some object: {said[on].mean():.2f}; "
        f"pixels labelled as objects that are one: {on[said].mean():.2f}; right type where "
        f"both say object: {(full[both] == frames['cls'][both]).mean():.2f}"
    )
    print("confidence | masks kept from | val mask AP50 | AP | ms per frame")
    for kind, parts in conf.items():
        lab, prob = upsample(np.concatenate(labels), np.concatenate(parts), depth.shape[1:])
        cost = ms_per_frame(model, kind)
        for keep in (8, MIN_PIXELS):
            pairs = [
                (truth[i], split_instances(lab[i], depth[i], pick, prob[i], keep))
                for i in range(len(depth))
            ]
            r = mask_ap(pairs, pick, depth.shape[1:], ignore_below=MIN_PIXELS)
            print(f"{kind} | {keep} px | {r['AP50']:.3f} | {r['AP']:.3f} | {cost:.2f}")


if __name__ == "__main__":
    main()
