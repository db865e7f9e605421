"""F_d, the misplaced-object detector (Table 2: Linear(256, 256) -> Linear(256, 2)).

det = F_d(sq, sv, sl, sr): its input joins sv with the object's and the room's commonsense
attentions (which carry sl, sr and sq; without knowledge, sl and sr themselves) through one
linear layer into the table's 256. fd is the second-to-last layer.
"""

from __future__ import annotations

import torch
from torch import nn


class MisplacedDetector(nn.Module):
    def __init__(self, width: int, dim: int = 256) -> None:
        super().__init__()
        self.fuse = nn.Sequential(nn.Linear(width, dim), nn.ReLU())
        self.hidden = nn.Sequential(nn.Linear(dim, dim), nn.ReLU())  # fd
        self.head = nn.Linear(dim, 2)  # [reasonable, misplaced]

    def features(self, x: torch.Tensor) -> torch.Tensor:
        return self.hidden(self.fuse(x))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.head(self.features(x))
