"""The object typer: a small CNN that names one mask of what the floor plan does not explain.

The segmenter sees a small object as a few cells of its half-resolution grid, and the floor
plan's masks (``perception/object_space.py``) are typed by those cells' votes, which name the
wrong type for about one object in seven on val frames. The typer reads the object itself, at
the frame's resolution: a crop around the mask with the mask and its depth, the mask's metric
size, and the segmenter's votes (``perception/object_crops.py``), and gives a type or "not an
object" (a robot, a tap over a sink). As Mask R-CNN's box head names a proposal; trained from
scratch on the train houses' frames (``training/typer_trainer.py``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from torch import nn

from maniskill_tidy.perception.object_crops import CHANNELS, crop_inputs
from maniskill_tidy.perception.seg_classes import seg_classes


def _conv(cin: int, cout: int, stride: int) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(cin, cout, 3, stride, 1, bias=False), nn.BatchNorm2d(cout),
                         nn.ReLU(inplace=True))  # fmt: skip


class ObjectTyper(nn.Module):
    """(crops (B, CHANNELS, 32, 32), numbers (B, F)) -> logits (B, types + 1); the last is
    "not an object"."""

    def __init__(self, types: int, numbers: int, width: int = 32) -> None:
        super().__init__()
        self.types, self.numbers, self.width = types, numbers, width
        self.image = nn.Sequential(
            _conv(CHANNELS, width, 1), _conv(width, width, 2),  # 16
            _conv(width, 2 * width, 2), _conv(2 * width, 2 * width, 2),  # 4
            nn.AdaptiveAvgPool2d(1), nn.Flatten(),
        )  # fmt: skip
        self.head = nn.Sequential(
            nn.Linear(2 * width + numbers, 128), nn.ReLU(inplace=True),
            nn.Linear(128, types + 1),
        )  # fmt: skip

    def forward(self, crops: torch.Tensor, numbers: torch.Tensor) -> torch.Tensor:
        return self.head(torch.cat([self.image(crops), numbers], dim=1))

    def config(self) -> dict:
        return {"types": self.types, "numbers": self.numbers, "width": self.width}


def type_index() -> tuple[np.ndarray, list[int]]:
    """Label -> 0..T-1 over the pickupable types (-1 for the others), and T's labels."""
    c = seg_classes()
    index = np.full(256, -1, np.int64)
    labels = []
    for i in range(len(c.names)):
        if i and c.is_pickupable(i):
            index[i] = len(labels)
            labels.append(i)
    return index, labels


class Typer:
    """A trained typer as agents run it: masks of a frame -> (label, probability) each."""

    def __init__(self, folder: str | Path) -> None:
        ckpt = torch.load(Path(folder) / "typer.pt", weights_only=True)
        self.model = ObjectTyper(**ckpt["config"]).eval()
        self.model.load_state_dict(ckpt["state"])
        self.index, labels = type_index()
        self.labels = np.array(labels, np.int64)

    def __call__(self, masks, rgb, depth, focal, labels, margins):
        crops, numbers = crop_inputs(masks, rgb, depth, focal, labels, margins, self.index)
        with torch.inference_mode():
            p = torch.softmax(self.model(torch.from_numpy(crops), torch.from_numpy(numbers)), 1)
        p = p.numpy()[:, : self.model.types]
        best = p.argmax(1)
        return self.labels[best], p[np.arange(len(best)), best]
