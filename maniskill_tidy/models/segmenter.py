"""The pixels track's segmenter: a small U-Net from RGB-D to a class per pixel.

A stand-in for the paper's Mask R-CNN, trained from scratch on the project's own renders
(no detector weights install offline, and torchvision's wheels do not load beside the CPU
torch these machines use). Semantic classes per pixel (``perception/seg_classes.py``);
instances come after, from connected components split at depth edges
(``perception/instances.py``). The logits come out at half the input's resolution: on 2 CPU
cores, full-resolution logits over ~100 classes cost more than the rest of the network
(``shared/reference/segmenter-feasibility.md``), and labels upsample by nearest neighbour.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

DEPTH_SCALE = 5.0  # metres: depth enters the network divided by this


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

    def __init__(self, classes: int, widths: tuple[int, ...] = (24, 32, 64, 96, 128)) -> None:
        super().__init__()
        self.classes, self.widths = classes, tuple(widths)
        self.down = nn.ModuleList()
        cin = 4
        for w in widths:  # stride 2, 4, 8, 16, 32
            self.down.append(block(cin, w, stride=2))
            cin = w
        self.up = nn.ModuleList(
            block(widths[i + 1] + widths[i], widths[i]) for i in reversed(range(len(widths) - 1))
        )
        self.head = nn.Conv2d(widths[0], classes, 1)

    def forward(self, rgb: torch.Tensor, depth: torch.Tensor) -> torch.Tensor:
        """``rgb`` (B, 3, H, W) in 0..255, ``depth`` (B, 1, H, W) in metres."""
        x = torch.cat([rgb / 127.5 - 1.0, depth / DEPTH_SCALE], dim=1)
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
        return {"classes": self.classes, "widths": list(self.widths)}


def predict(model: Segmenter, rgb: np.ndarray, depth_m: np.ndarray, batch: int = 16):
    """Labels (N, H, W) uint8 and the probability of each pixel's label (N, H, W) float32, at
    the frames' resolution (nearest-upsampled from the network's half resolution). Each
    frame's output depends on that frame alone (the network is in eval mode)."""
    labels, probs = [], []
    size = rgb.shape[1:3]
    with torch.inference_mode():
        for s in range(0, len(rgb), batch):
            r = torch.from_numpy(np.array(rgb[s : s + batch])).permute(0, 3, 1, 2)
            d = torch.from_numpy(np.array(depth_m[s : s + batch], dtype=np.float32))
            d = d.reshape(len(d), 1, *size)
            p, lab = F.softmax(model(r.float(), d), dim=1).max(dim=1)
            labels.append(F.interpolate(lab[:, None].float(), size=size, mode="nearest")[:, 0])
            probs.append(F.interpolate(p[:, None], size=size, mode="nearest")[:, 0])
    return torch.cat(labels).numpy().astype(np.uint8), torch.cat(probs).numpy()
