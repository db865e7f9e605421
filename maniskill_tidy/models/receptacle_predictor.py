"""F_p, the reasonable-receptacle predictor (Table 2: Linear(256, 256) -> Linear(256, P) and
Linear(256, 4)): multi-label logits over the catalog's receptacle types and the room types.

(p, r) = F_p(sv, attl, attr); fp is the second-to-last layer. The catalog has P = 46 receptacle
types (the paper's 43 are AI2-THOR's).
"""

from __future__ import annotations

import torch
from torch import nn


class ReceptaclePredictor(nn.Module):
    def __init__(self, width: int, receptacles: int, dim: int = 256, rooms: int = 4) -> None:
        super().__init__()
        self.fuse = nn.Sequential(nn.Linear(width, dim), nn.ReLU())
        self.hidden = nn.Sequential(nn.Linear(dim, dim), nn.ReLU())  # fp
        self.receptacle = nn.Linear(dim, receptacles)
        self.room = nn.Linear(dim, rooms)

    def features(self, x: torch.Tensor) -> torch.Tensor:
        return self.hidden(self.fuse(x))

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        h = self.features(x)
        return self.receptacle(h), self.room(h)
