"""sv: the visual embedding of an agent's RGB frame.

Stand-in: the paper uses an ImageNet ResNet; no pretrained weights can be had offline, so this
small CNN is trained from scratch on frames rendered in the train houses (pre-trained to name
the categories in view, ``training/perception_trainer.py``) and then frozen, as the paper
freezes its ResNet.
"""

from __future__ import annotations

import torch
from torch import nn

IMAGE = 64
WIDTHS = (32, 64, 96, 128)  # channels of the four stride-2 convolutions (64 -> 4 pixels)


class VisualEncoder(nn.Module):
    def __init__(self, dim: int = 256, widths: tuple[int, ...] = WIDTHS) -> None:
        super().__init__()
        if len(widths) != 4:
            raise ValueError(f"VisualEncoder widths: 4 channel counts expected, got {widths}")
        layers: list[nn.Module] = []
        for i, (a, b) in enumerate(zip((3, *widths), widths, strict=False)):
            k = 5 if i == 0 else 3  # 64 -> 32 -> 16 -> 8 -> 4
            layers += [nn.Conv2d(a, b, k, stride=2, padding=k // 2), nn.ReLU()]
        self.conv = nn.Sequential(*layers)
        self.out = nn.Sequential(nn.Flatten(), nn.Linear(widths[-1] * 4 * 4, dim), nn.ReLU())

    def forward(self, rgb: torch.Tensor) -> torch.Tensor:
        """``rgb``: (B, 64, 64, 3) uint8 as the views store it -> (B, dim)."""
        x = rgb.permute(0, 3, 1, 2).float() / 127.5 - 1.0
        return self.out(self.conv(x))
