"""Who asks whom for memory entries: HanGrCom's query and key over an agent's memory summary.

The object-memory team with links (``policies/memory_links.py``) runs the paper's handshake
(``models/hangrcom.py``): ``T_ij = softmax_j(qry_j . key_i / sqrt(d))`` says how useful
A_j's memory is to A_i; A_i asks when ``T_ii < delta`` and each A_j with ``T_ij > mu`` sends it
a few memory entries. The query and key come from a small summary of the agent's own memory
(``policies/memory_links.summary``), through one hidden layer shared by both generators.

It is trained on labels only centralised training can see (``training/memory_links.py``):
``useful[i, j]`` when A_i is a manipulator and A_j remembers a misplaced object A_i neither
knows of nor was told of. Each present agent's row of T is fitted to its labels made a
distribution (the useful teammates share the row; with none, all of it stays on A_i, which then
does not ask). Agents share these weights; what goes in is each agent's own.
"""

from __future__ import annotations

import torch
from torch import nn

from maniskill_tidy.models.hangrcom import attention


class MemoryLinks(nn.Module):
    def __init__(self, features: int, hidden: int = 32, key: int = 8) -> None:
        super().__init__()
        self.summary = nn.Sequential(nn.Linear(features, hidden), nn.ReLU())
        self.query = nn.Linear(hidden, key)
        self.key = nn.Linear(hidden, key)

    def forward(self, sf: torch.Tensor) -> dict[str, torch.Tensor]:
        h = self.summary(sf.float())
        return {"qry": self.query(h), "key": self.key(h)}

    def rows(self, sf: torch.Tensor, present: torch.Tensor) -> torch.Tensor:
        """T (B, N, N) of a batch of team steps: summaries (B, N, F), ``present`` (B, N)."""
        g = self(sf)
        return attention(g["qry"], g["key"], present)


def target_rows(useful: torch.Tensor, present: torch.Tensor) -> torch.Tensor:
    """Each agent's wanted row of T (B, N, N): its useful teammates, shared equally; itself
    when it has none. Rows of absent agents are 0."""
    n = useful.shape[-1]
    useful = useful.bool() & present.unsqueeze(-2) & present.unsqueeze(-1)
    useful = useful & ~torch.eye(n, dtype=torch.bool)
    none = ~useful.any(-1, keepdim=True)
    wanted = (useful | (none & torch.eye(n, dtype=torch.bool))).float()
    return wanted / wanted.sum(-1, keepdim=True) * present.unsqueeze(-1)


def link_loss(t: torch.Tensor, wanted: torch.Tensor, present: torch.Tensor) -> torch.Tensor:
    """Cross-entropy of the rows of T against the wanted rows, over the present agents."""
    each = -(wanted * torch.log(t.clamp(min=1e-8))).sum(-1)
    return (each * present).sum() / present.sum().clamp(min=1)
