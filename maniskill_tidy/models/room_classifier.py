"""The room classifier (Table 2: Linear(256, 256) -> Linear(256, 4)) and sr, its hidden layer.

Input: the detected objects (the share of the image each category covers) and sv, joined by
one linear layer into the table's 256. Trained first with Loss_cla, then frozen (Eq. 1).
"""

from __future__ import annotations

import torch
from torch import nn


class RoomClassifier(nn.Module):
    def __init__(self, categories: int, dim: int = 256, rooms: int = 4) -> None:
        super().__init__()
        self.fuse = nn.Sequential(nn.Linear(categories + dim, dim), nn.ReLU())
        self.hidden = nn.Sequential(nn.Linear(dim, dim), nn.ReLU())  # sr
        self.head = nn.Linear(dim, rooms)

    def embed(self, seen: torch.Tensor, sv: torch.Tensor) -> torch.Tensor:
        """sr: (B, dim)."""
        return self.hidden(self.fuse(torch.cat([seen.float() * 10.0, sv], dim=-1)))

    def forward(self, seen: torch.Tensor, sv: torch.Tensor) -> torch.Tensor:
        return self.head(self.embed(seen, sv))
