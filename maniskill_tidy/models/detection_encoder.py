"""sl: the feature of one detected object.

Stand-in: detections come from the renderer's ground-truth segmentation (type and pixels), in
place of the paper's Mask R-CNN. The feature joins the type (its word vector and a learned
embedding), where it rests (the receptacle type under it, or "unknown") and the numbers of
``training/perception_data.py``: image box, distance, sqrt of image share, lowest point.
"""

from __future__ import annotations

import torch
from torch import nn


class DetectionEncoder(nn.Module):
    def __init__(
        self, type_vectors: torch.Tensor, receptacles: int, numeric: int = 7, dim: int = 256
    ) -> None:
        super().__init__()
        self.register_buffer("type_vectors", type_vectors.float())  # (K, word dim), frozen
        self.kind = nn.Embedding(len(type_vectors), 32)
        self.rest = nn.Embedding(receptacles + 1, 32)  # the last: rests on nothing known
        width = type_vectors.shape[1] + 32 + 32 + numeric
        self.mlp = nn.Sequential(nn.Linear(width, dim), nn.ReLU(), nn.Linear(dim, dim), nn.ReLU())

    def forward(
        self, kind: torch.Tensor, rest: torch.Tensor, numeric: torch.Tensor
    ) -> torch.Tensor:
        x = torch.cat(
            [self.type_vectors[kind], self.kind(kind), self.rest(rest), numeric.float()], dim=-1
        )
        return self.mlp(x)
