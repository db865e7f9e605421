"""sm: the map embedding of an agent's egocentric semantic-map crop (G x G x (K + 2)).

Pre-trained as the paper does: answer queries "is there a thing of category c in sub-region
R of the crop" (answers from the house spec, binary cross-entropy). ``RegionQueries`` answers
every (R, c) query of a crop at once.
"""

from __future__ import annotations

import torch
from torch import nn

WIDTHS = (32, 64, 64, 128)  # a 1 x 1 mix of the channels, then three 3 x 3 convolutions


class SceneEncoder(nn.Module):
    def __init__(
        self, channels: int, size: int = 20, dim: int = 256, widths: tuple[int, ...] = WIDTHS
    ) -> None:
        super().__init__()
        if len(widths) != 4:
            raise ValueError(f"SceneEncoder widths: 4 channel counts expected, got {widths}")
        w0, w1, w2, w3 = widths
        self.conv = nn.Sequential(
            nn.Conv2d(channels, w0, 1), nn.ReLU(),  # per-cell mix of the K + 2 channels
            nn.Conv2d(w0, w1, 3, padding=1), nn.ReLU(),
            nn.Conv2d(w1, w2, 3, stride=2, padding=1), nn.ReLU(),
            nn.Conv2d(w2, w3, 3, stride=2, padding=1), nn.ReLU(),
        )  # fmt: skip
        side = (size + 3) // 4
        self.out = nn.Sequential(nn.Flatten(), nn.Linear(w3 * side * side, dim), nn.ReLU())

    def forward(self, crop: torch.Tensor) -> torch.Tensor:
        """``crop``: (B, G, G, K + 2), 0/1 -> (B, dim)."""
        return self.out(self.conv(crop.permute(0, 3, 1, 2).float()))


class RegionQueries(nn.Module):
    """Logits of every query (sub-region r, category c) from sm: (B, R, K)."""

    def __init__(self, regions: int, categories: int, dim: int = 256) -> None:
        super().__init__()
        self.regions, self.categories = regions, categories
        self.head = nn.Linear(dim, regions * categories)

    def forward(self, sm: torch.Tensor) -> torch.Tensor:
        return self.head(sm).view(-1, self.regions, self.categories)
