"""HanGrCom: handshake-based group communication (the paper's Section 5.3).

Each agent turns its state feature ``sf`` into a query, a key, a value and an inter-group
vector with four linear generators. ``attc_ij = qry_j . key_i / sqrt(d)`` says how useful
A_j's information is to A_i; ``T`` is its row-wise softmax over the agents present.

- Training (``soft``, differentiable; the trainer may read every agent's ``sf``):
  ``inn_i = sum_j T_ij val_j`` and ``int_i = sum_j (1 - T_ij) inv_j``.
- Inference (:func:`handshake`, :func:`hard`): A_i asks for messages when ``T_ii < delta``; it
  then receives ``val_j`` from every A_j with ``T_ij > mu`` (a *link*). Groups are the
  connected components of the links. ``inn_i = T_ii val_i + sum_{linked j} T_ij val_j`` (its
  own value costs nothing; with every link present this is the soft sum) and
  ``int_i = inv_j*`` with ``j* = argmax_j mean_{k in group(i)} T_kj`` over the agents outside
  the group (zero when the group is the whole team).

The paper's two modes differ (the soft ``int`` weighs every agent by ``1 - T_ij``, the hard one
takes one agent's vector); the trainer can mix hard steps into training
(``DecisionConfig.hard_fraction``) so that the model meets at evaluation what it was trained on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

MU, DELTA = 0.2, 0.8  # the paper's thresholds


class HanGrCom(nn.Module):
    """The four generators of one agent (agents do not share them)."""

    def __init__(self, state: int, key: int = 32, value: int = 64, inter: int = 64) -> None:
        super().__init__()
        self.query = nn.Linear(state, key)
        self.key = nn.Linear(state, key)
        self.value = nn.Linear(state, value)
        self.inter = nn.Linear(state, inter)

    def forward(self, sf: torch.Tensor) -> dict[str, torch.Tensor]:
        return {"qry": self.query(sf), "key": self.key(sf), "val": self.value(sf),
                "inv": self.inter(sf)}  # fmt: skip


def attention(qry: torch.Tensor, key: torch.Tensor, present: torch.Tensor) -> torch.Tensor:
    """T (..., N, N) from queries and keys (..., N, d) of the agents ``present`` (..., N):
    row i is agent i's softmax over the present agents; rows of absent agents are 0."""
    attc = torch.einsum("...id,...jd->...ij", key, qry) / math.sqrt(qry.shape[-1])
    attc = attc.masked_fill(~present.unsqueeze(-2), float("-inf"))
    t = torch.softmax(attc, dim=-1)
    return torch.nan_to_num(t * present.unsqueeze(-1), nan=0.0)


def soft(t: torch.Tensor, val: torch.Tensor, inv: torch.Tensor) -> tuple[torch.Tensor, ...]:
    """Training-mode ``inn`` and ``int`` (..., N, d) from T (..., N, N)."""
    present = (t.sum(-1) > 0).to(t.dtype)  # (..., N)
    inn = t @ val
    inter = ((1 - t) * present.unsqueeze(-2) * present.unsqueeze(-1)) @ inv
    return inn, inter


def hard_links(
    t: torch.Tensor, present: torch.Tensor, mu: float = MU, delta: float = DELTA
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The handshake, batched over leading dims: (links, same_group, inter) from T (..., N, N).

    ``links[i, j]``: A_i asked (T_ii < delta) and receives val_j (T_ij > mu, j != i);
    ``same_group[i, j]``: i and j are connected by links (either way); ``inter[i]``: one-hot of
    the agent outside i's group that the group attends to most (all zero when none)."""
    n = t.shape[-1]
    eye = torch.eye(n, dtype=torch.bool)
    asks = present & (torch.diagonal(t, dim1=-2, dim2=-1) < delta)
    links = asks.unsqueeze(-1) & (t > mu) & present.unsqueeze(-2) & ~eye
    reach = links | links.transpose(-1, -2) | (eye & present.unsqueeze(-1))
    for _ in range(n):  # transitive closure: groups are the connected components
        reach = reach | ((reach.float() @ reach.float()) > 0)
    members = reach.to(t.dtype)
    score = (members @ t) / members.sum(-1, keepdim=True).clamp(min=1)
    outside = present.unsqueeze(-2) & ~reach
    score = score.masked_fill(~outside, float("-inf"))
    best = torch.nn.functional.one_hot(score.argmax(-1), n).bool()
    inter = best & outside.any(-1, keepdim=True) & present.unsqueeze(-1)
    return links, reach, inter


def hard(
    t: torch.Tensor, val: torch.Tensor, inv: torch.Tensor, present: torch.Tensor,
    mu: float = MU, delta: float = DELTA,
) -> tuple[torch.Tensor, torch.Tensor]:  # fmt: skip
    """Inference-mode ``inn`` and ``int`` (..., N, d), batched like :func:`soft`."""
    links, _, inter = hard_links(t, present, mu, delta)
    eye = torch.eye(t.shape[-1], dtype=torch.bool)
    inn = (t * (links | eye).to(t.dtype)) @ val
    return inn, inter.to(inv.dtype) @ inv


@dataclass(frozen=True)
class Handshake:
    """One step's handshake among the agents present (for the agents, the channel and the
    recordings)."""

    asks: np.ndarray  # (N,) bool: T_ii < delta
    links: np.ndarray  # (N, N) bool: i receives val_j
    groups: list[list[int]]  # connected components of the links, each sorted
    inter: np.ndarray  # (N,) the agent j* whose inv i receives, -1 for none


def handshake(t, present, mu: float = MU, delta: float = DELTA) -> Handshake:
    """:func:`hard_links` for one step's T (N, N), as numpy arrays and lists of groups."""
    t = torch.as_tensor(np.asarray(t), dtype=torch.float64)
    present = torch.as_tensor(np.asarray(present, dtype=bool))
    links, reach, inter = hard_links(t, present, mu, delta)
    groups = sorted({tuple(np.flatnonzero(r)) for r in reach.numpy() if r.any()})
    asks = (present & (torch.diagonal(t) < delta)).numpy()
    index = np.where(inter.any(-1).numpy(), inter.float().argmax(-1).numpy(), -1)
    return Handshake(asks, links.numpy(), [list(map(int, g)) for g in groups], index)
