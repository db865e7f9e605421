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


class VisualEncoder(nn.Module):
    def __init__(self, dim: int = 256) -> None:
        super().__init__()
        self.conv = nn.Sequential(
            nn.Conv2d(3, 32, 5, stride=2, padding=2), nn.ReLU(),  # 32
            nn.Conv2d(32, 64, 3, stride=2, padding=1), nn.ReLU(),  # 16
            nn.Conv2d(64, 96, 3, stride=2, padding=1), nn.ReLU(),  # 8
            nn.Conv2d(96, 128, 3, stride=2, padding=1), nn.ReLU(),  # 4
        )  # fmt: skip
        self.out = nn.Sequential(nn.Flatten(), nn.Linear(128 * 4 * 4, dim), nn.ReLU())

    def forward(self, rgb: torch.Tensor) -> torch.Tensor:
        """``rgb``: (B, 64, 64, 3) uint8 as the views store it -> (B, dim)."""
        x = rgb.permute(0, 3, 1, 2).float() / 127.5 - 1.0
        return self.out(self.conv(x))
