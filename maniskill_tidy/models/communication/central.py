"""CentralComm.: every agent uploads its state and map embedding (410) to a central node, which
sends each agent an assignment (value dims) computed from all uploads (all but the agent's own
last sub-task: :class:`CentralPlanner`); ``inn`` is the assignment. The paper's node generates
the sub-task itself; here the assignment is what the agent's F_a turns into its sub-task, so
that F_g reads ``se`` as in every variant."""

from __future__ import annotations

import torch
from torch import nn

from maniskill_tidy.models.communication.base import (
    MAP,
    STATE,
    TASK,
    Messenger,
    Scheme,
    StateReader,
    pool,
)


class Central(Messenger):
    """An agent's side: it only uploads (the node reads)."""

    name = "central"
    title = "CentralComm.: uploads to a central node that sends assignments"
    label = "central communication"
    uploads = True

    def __init__(self, cfg) -> None:
        Scheme.__init__(self)  # no readers: nothing reaches an agent but its assignment
        self.map = nn.Linear(cfg.perception, MAP)

    @classmethod
    def build_central(cls, cfg) -> CentralPlanner:
        return CentralPlanner(cfg)

    @classmethod
    def communicate(cls, cfg, comms, sf, x, present, hard, labels, central):
        up = torch.stack([c.outgoing(xn) for c, xn in zip(comms, x, strict=True)], dim=2)
        zeros = torch.zeros(*present.shape, cfg.inter)
        return central(up, present), zeros, {"T": None, "aux": torch.zeros(())}


class CentralPlanner(nn.Module):
    """The node: from every agent's upload (state 10 + map 400) an assignment (value dims) per
    agent, from its own upload and its teammates' pooled ones.

    It does not read the sub-task in the agent's own upload. Under behaviour cloning that
    field is the teacher's label of the last step, and a node that reads it learns to copy it
    (95-99.7 % of Setting I val steps keep last step's sub-task, per head:
    ``docs/research/probes/label_persistence.py``), then fails on its own sub-tasks at test
    time. No agent of any scheme reads its own last sub-task; teammates' are read wherever
    messages carry the state."""

    def __init__(self, cfg) -> None:
        super().__init__()
        self.state_reader = StateReader(cfg)
        self.read = nn.Sequential(nn.Linear(64 + MAP, 128), nn.ReLU())
        self.assign = nn.Sequential(nn.Linear(3 * 128, cfg.value), nn.ReLU())

    def _read(self, uploads: torch.Tensor) -> torch.Tensor:
        return self.read(torch.cat([self.state_reader(uploads[..., :STATE]),
                                    uploads[..., STATE:]], dim=-1))  # fmt: skip

    def forward(self, uploads: torch.Tensor, present: torch.Tensor) -> torch.Tensor:
        """uploads (…, N, STATE + MAP), present (…, N) -> assignments (…, N, value)."""
        own = uploads.clone()
        own[..., STATE - len(TASK) : STATE] = -1  # its own last sub-task: withheld
        n = uploads.shape[-2]
        h = self._read(uploads)
        others = present.unsqueeze(-2) & ~torch.eye(n, dtype=torch.bool)  # (…, N, N): i <- j
        mean, top = pool(h.unsqueeze(-3).expand(*h.shape[:-2], n, n, h.shape[-1]), others)
        out = self.assign(torch.cat([self._read(own), mean, top], dim=-1))
        return out * present.unsqueeze(-1).to(out.dtype)
