"""What every communication scheme shares: the interface, the state message and how messages
are read and pooled.

A scheme is the class of one agent's communication module (``nn.Module``). Its class methods
say how a whole team communicates in training (:meth:`Scheme.communicate`); at evaluation the
agents run the same module through the channel (``policies/message_exchange.py`` or
``policies/handshake_exchange.py``, chosen by :attr:`Scheme.protocol`).

The state message is the heuristic teams' (``policies/messages.py``) in the model's index
spaces: capability (3), x and y in metres, heading in degrees, and the sub-task the agent
pursued last step (kind, object, receptacle and room indices, -1 for none).
"""

from __future__ import annotations

from typing import ClassVar

import torch
from torch import nn

STATE = 10  # capability 3, x, y, heading, sub-task 4
MAP = 400  # the map embedding (the paper counts the map as 400 values)
TASK = ("kind", "object", "receptacle", "room")

Inputs = list[dict[str, torch.Tensor]]  # per agent, its inputs (B, T, ·)


class Scheme(nn.Module):
    """One agent's side of a scheme; subclasses are registered by ``name``."""

    name: ClassVar[str]
    title: ClassVar[str]  # the model card's words
    label: ClassVar[str]  # the runs table's words
    rounds: ClassVar[int] = 1  # message rounds per step at evaluation
    # how evaluation carries it: "none", "messages" (vectors through the channel) or
    # "handshake" (HanGrCom's requests, keys and values)
    protocol: ClassVar[str] = "messages"
    uploads: ClassVar[bool] = False  # messages go to a central node, which answers

    @classmethod
    def build(cls, cfg) -> nn.Module | None:
        """The module an agent of this scheme holds (``AgentDecision.comm``)."""
        return cls(cfg)

    @classmethod
    def build_central(cls, cfg) -> nn.Module | None:
        """The central node's module (``TeamDecision.central``), if the scheme has one."""
        return None

    @classmethod
    def communicate(
        cls, cfg, comms: list, sf: list[torch.Tensor], x: Inputs, present: torch.Tensor,
        hard: bool, labels: Inputs | None, central: nn.Module | None,
    ) -> tuple[torch.Tensor, torch.Tensor, dict]:  # fmt: skip
        """A whole team in training (``comms``: the agents' modules, ``sf`` their state
        features): ``inn`` (B, T, N, value), ``int`` (B, T, N, inter) and ``info`` (``T``:
        HanGrCom's attention or None; ``aux``: the scheme's auxiliary loss)."""
        raise NotImplementedError


def state_message(va: torch.Tensor, pose: torch.Tensor, task: torch.Tensor) -> torch.Tensor:
    """(…, STATE): capability (…, 3), pose (…, 4: x, y, heading, pitch) and last step's
    sub-task indices (…, 4, -1 for none)."""
    return torch.cat([va.float(), pose[..., :3].float(), task.float()], dim=-1)


class StateReader(nn.Module):
    """What a receiver makes of a state message: capability, position, heading and sub-task."""

    def __init__(self, cfg, out: int = 64) -> None:
        super().__init__()
        sizes = (2, cfg.objects, cfg.receptacles, cfg.rooms)
        self.task = nn.ModuleList(nn.Embedding(n + 1, 16) for n in sizes)  # index 0: none
        self.fuse = nn.Sequential(nn.Linear(3 + 4 + 16 * len(sizes), out), nn.ReLU())

    def forward(self, m: torch.Tensor) -> torch.Tensor:
        yaw = torch.deg2rad(m[..., 5])
        where = torch.stack([m[..., 3] / 10, m[..., 4] / 10, torch.cos(yaw), torch.sin(yaw)], -1)
        index = m[..., 6:10].round().long().clamp(min=-1) + 1
        task = [emb(index[..., k].clamp(max=emb.num_embeddings - 1))
                for k, emb in enumerate(self.task)]  # fmt: skip
        return self.fuse(torch.cat([m[..., :3], where, *task], dim=-1))


def pool(features: torch.Tensor, received: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """``inn`` (mean) and ``int`` (element-wise max) over the messages received: features
    (…, N, d), received (…, N) bool; zeros where nothing arrived."""
    w = received.to(features.dtype).unsqueeze(-1)
    inn = (features * w).sum(-2) / w.sum(-2).clamp(min=1)
    top = features.masked_fill(~received.unsqueeze(-1), float("-inf")).amax(-2)
    return inn, torch.where(received.any(-1, keepdim=True), top, torch.zeros_like(top))


class Messenger(Scheme):
    """A message-passing scheme: every agent sends a vector (its state message and a map
    embedding) to its teammates and reads theirs; ``inn`` is the mean of what it reads of the
    messages, ``int`` their element-wise max. Subclasses change what is sent, when, and how it
    is read, and may add an auxiliary loss."""

    sends_map: ClassVar[bool] = True

    def __init__(self, cfg) -> None:
        super().__init__()
        if self.sends_map:
            self.map = nn.Linear(cfg.perception, MAP)  # the map embedding it sends
        self.state_reader = StateReader(cfg)
        width = 64 + self.add_readers(cfg)
        self.read = nn.Sequential(nn.Linear(width, cfg.value), nn.ReLU())

    def add_readers(self, cfg) -> int:
        """Modules a receiver reads with besides the state reader; returns their width."""
        return MAP

    def map_embedding(self, x: dict[str, torch.Tensor]) -> torch.Tensor:
        return torch.tanh(self.map(x["sm"]))

    def outgoing(self, x: dict[str, torch.Tensor]) -> torch.Tensor:
        """The message (…, dims) this agent sends in this step."""
        state = state_message(x["va"], x["pose"], x["prev_task"])
        return torch.cat([state, self.map_embedding(x)], dim=-1)

    def sends(self, x: dict[str, torch.Tensor]) -> torch.Tensor:
        """(…) bool: whether it sends at all in this step."""
        return torch.ones_like(x["mis"], dtype=torch.bool)

    def incoming(self, m: torch.Tensor) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
        """What this agent reads of messages (…, dims): features (…, value) and what the
        auxiliary loss needs."""
        code = m[..., STATE:]
        state = self.state_reader(m[..., :STATE])
        return self.read(torch.cat([state, code], dim=-1)), {"map": code}

    @classmethod
    def communicate(cls, cfg, comms, sf, x, present, hard, labels, central):
        inn, inter, extras = exchange(comms, x, present)
        return inn, inter, {"T": None, "aux": cls.auxiliary_loss(comms, x, extras, labels)}

    @classmethod
    def auxiliary_loss(cls, comms: list, x: Inputs, extras: dict, labels: Inputs | None):
        return torch.zeros(())


def exchange(
    messengers: list[Messenger], x: Inputs, present: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor, dict]:
    """A message-passing scheme over a whole team in training: ``inn`` and ``int``
    (…, N, d) and the per-pair outputs the auxiliary losses need. Agent j's message reaches
    agent i when both are present, i != j and j sends."""
    msgs = torch.stack([m.outgoing(xn) for m, xn in zip(messengers, x, strict=True)], dim=-2)
    sends = torch.stack([m.sends(xn) for m, xn in zip(messengers, x, strict=True)], dim=-1)
    n = len(messengers)
    eye = torch.eye(n, dtype=torch.bool)
    inn, inter, extras = [], [], []
    for i, m in enumerate(messengers):
        feats, extra = m.incoming(msgs)
        received = sends & present & present[..., i : i + 1] & ~eye[i]
        a, b = pool(feats, received)
        inn.append(a)
        inter.append(b)
        extras.append({**extra, "received": received})
    return torch.stack(inn, -2), torch.stack(inter, -2), {"pairs": extras, "messages": msgs}
