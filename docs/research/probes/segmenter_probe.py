"""What the segmenter probes share: their command line (a trained segmenter's folder, the
frames to read and how many, evenly spaced), loading both, the network's labels and margins on
its grid with the masks agents make from them (:class:`GridLogits`), and the line that scores
a way of making masks (:func:`scored`). The probes study the network, so they run its fp16
weights in torch, not the int8 graph agents run."""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.eval.mask_ap import mask_ap, score_threshold
from maniskill_tidy.models import checkpoints
from maniskill_tidy.models.segmenter import Segmenter, predict, upsample
from maniskill_tidy.perception.instances import Mask2D, coarse, scored_by_relief, split_instances
from maniskill_tidy.perception.seg_classes import seg_classes
from maniskill_tidy.training.segmenter_trainer import load_split, truth_masks

VAL = "data/segmenter/HeteroTidy-v2/val"


def arguments(doc: str, data: str = VAL) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("weights", help="a trained segmenter's folder, e.g. agents/segmenter-v2")
    ap.add_argument("--data", default=data, help="segmenter-data frames")
    ap.add_argument("--frames", type=int, default=400, help="evenly spaced frames to read")
    return ap.parse_args()


def segmenter(args: argparse.Namespace) -> tuple[Segmenter, dict]:
    return checkpoints.load_segmenter(Path(args.weights))


def frames(args: argparse.Namespace, split: str = "") -> dict:
    return load_split(Path(args.data) / split, args.frames)


def labelled_objects(model: Segmenter, data: dict) -> Iterator[tuple[int, np.ndarray]]:
    """Each of the renderer's pickupable objects of ``MIN_PIXELS`` or more on the frames: its
    type and the segmenter's labels of its pixels (upsampled to the frame), for the probes
    that ask what the segmenter calls an object's pixels."""
    pickupable = pickupable_table()
    depth = data["depth_mm"].astype(np.float32) / 1000
    labels = upsample(*predict(model, data["rgb"], depth), depth.shape[1:3])[0]
    for k in range(len(labels)):
        inst, cls = data["instance"][k], data["cls"][k]
        for i in np.unique(inst[inst > 0]):
            m = inst == i
            t = int(cls[m][0])
            if pickupable[t] and m.sum() >= MIN_PIXELS:
                yield t, labels[k][m]


def pickupable_table() -> np.ndarray:
    """Label -> is it a pickupable type (background excluded), for indexing label arrays."""
    c = seg_classes()
    return np.array([c.is_pickupable(i) and i > 0 for i in range(256)])


def logits_of(model: Segmenter, rgb: np.ndarray, depth: np.ndarray, batch: int = 16):
    """Labels, type margins and object margins (sigmoids), on the network's grid: the type
    margin is what agents' masks are scored by (``LabelHead``), the object margin is between a
    pixel's best pickupable logit and its best other one (is it an object at all?)."""
    obj = torch.from_numpy(pickupable_table()[: len(seg_classes().names)])
    labels, type_m, obj_m = [], [], []
    with torch.inference_mode():
        for s in range(0, len(rgb), batch):
            r = torch.from_numpy(np.array(rgb[s : s + batch])).permute(0, 3, 1, 2).float()
            d = torch.from_numpy(np.array(depth[s : s + batch])).unsqueeze(1)
            z = model.eval()(r, d)
            best, label = z.topk(2, dim=1)
            best_obj = z[:, obj].max(dim=1).values
            best_other = z[:, ~obj].max(dim=1).values
            labels.append(label[:, 0].to(torch.uint8).numpy())
            type_m.append(torch.sigmoid(best[:, 0] - best[:, 1]).numpy())
            obj_m.append(torch.sigmoid((best_obj - best_other).abs()).numpy())
    return np.concatenate(labels), np.concatenate(type_m), np.concatenate(obj_m)


@dataclass
class GridLogits:
    """The chosen frames and the segmenter's output on them (:func:`logits_of`), with what the
    mask probes derive from both: the grid's step, the least mask size on it, the pickupable
    classes, the renderer's object masks."""

    frames: dict
    depth: np.ndarray  # (N, H, W) metres
    labels: np.ndarray  # (N, H / step, W / step)
    type_margin: np.ndarray
    object_margin: np.ndarray

    @classmethod
    def load(cls, args: argparse.Namespace) -> GridLogits:
        data, model = frames(args), segmenter(args)[0]
        depth = data["depth_mm"].astype(np.float32) / 1000.0
        return cls(data, depth, *logits_of(model, data["rgb"], depth))

    def __len__(self) -> int:
        return len(self.labels)

    @property
    def step(self) -> int:
        return self.depth.shape[1] // self.labels.shape[1]

    @property
    def least(self) -> int:
        """``MIN_PIXELS`` in cells of the grid."""
        return -(-MIN_PIXELS // self.step**2)

    @property
    def shape(self) -> tuple[int, int]:
        return self.depth.shape[1:3]

    @property
    def classes(self) -> list[int]:
        c = seg_classes()
        return [i for i in range(len(c.names)) if c.is_pickupable(i)]

    def grid(self, k: int) -> np.ndarray:
        return coarse(self.depth[k], self.step)

    def masks(self, k: int, labels: np.ndarray | None = None, prob: np.ndarray | None = None,
              classes: list[int] | None = None) -> list[Mask2D]:  # fmt: skip
        """Frame ``k``'s object masks on the grid as agents make them before refinement
        (instances per label, scored by the type margin and the relief), from its own labels
        and margins unless others are given."""
        classes = self.classes if classes is None else classes
        labels = self.labels[k] if labels is None else labels
        prob = self.type_margin[k] if prob is None else prob
        grid = self.grid(k)
        return scored_by_relief(split_instances(labels, grid, classes, prob, self.least), grid,
                                classes)  # fmt: skip

    def truth(self, k: int) -> list[Mask2D]:
        return truth_masks(self.frames["cls"][k], self.frames["instance"][k], self.classes)


def scored(pairs: list, classes: list[int], shape: tuple[int, int]) -> str:
    """One way of making masks, scored as the cards score agents' masks: mask AP50, AP and AP
    for small objects over ``classes``, and the best-F1 threshold with its precision and
    recall."""
    ap = mask_ap(pairs, classes, shape, ignore_below=MIN_PIXELS)
    t = score_threshold(pairs, classes, shape, ignore_below=MIN_PIXELS)
    return (f"AP50 {ap['AP50']:.3f} AP {ap['AP']:.3f} small {ap['AP_small']:.3f} "
            f"| threshold {t['threshold']:.3f}: F1 {t['f1']:.3f} P {t['precision']:.2f} "
            f"R {t['recall']:.2f}")  # fmt: skip
