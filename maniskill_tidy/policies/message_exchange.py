"""One agent's side of the learned communication baselines, over the counting channel.

The messages and how they are read are the scheme's (``models/communication/``), the modules
training runs; this is who sends what to whom in one env step, for any message-passing scheme:

- round 0, the agent's message to every teammate, when its messenger ``sends`` (CondComm
  only while its detector finds a misplaced object in view);
- a scheme that ``uploads`` (CentralComm) sends it to the central node instead, which in the
  same round (it reads after the agents) sends each agent that uploaded its assignment
  (:class:`LearnedCentral`).

:meth:`MessageExchange.combine` then gives ``inn`` and ``int`` from what arrived, as
``models.communication.base.exchange`` does for the whole team in training.
"""

from __future__ import annotations

import numpy as np
import torch

from maniskill_tidy.models.communication.base import Messenger, pool
from maniskill_tidy.models.communication.central import CentralPlanner
from maniskill_tidy.policies.base import CentralNode, PublicInfo
from maniskill_tidy.policies.channel import CENTRAL, Message, Outbox

UPLOAD = "upload"  # the kind of a message to the central node; "message" between agents


class MessageExchange:
    def __init__(self, name: str, outbox: Outbox, messenger: Messenger, value: int, inter: int):
        self.name, self.outbox, self.messenger = name, outbox, messenger
        self.dims = (value, inter)

    def send(self, round: int, x: dict[str, torch.Tensor]) -> None:
        """Round ``round``; ``x`` holds this step's inputs (1, 1, ·) with ``prev_task``."""
        if round != 0:
            return
        with torch.inference_mode():
            if not bool(self.messenger.sends(x).reshape(-1)[0]):
                return
            vector = self.messenger.outgoing(x).reshape(-1).numpy()
        if self.messenger.uploads:
            self.outbox.send(CENTRAL, vector, UPLOAD)
        elif self.outbox.peers:
            self.outbox.send(self.outbox.peers, vector, "message")

    def combine(self, inbox: list[Message]) -> tuple[torch.Tensor, torch.Tensor]:
        inn, inter = torch.zeros(self.dims[0]), torch.zeros(self.dims[1])
        if self.messenger.uploads:  # what comes back is the node's assignment
            for m in inbox:
                if m.kind == "assignment" and m.sender == CENTRAL:
                    inn = torch.from_numpy(np.array(m.vector))
            return inn, inter
        msgs = [np.array(m.vector) for m in inbox if m.kind == "message"]
        if not msgs:
            return inn, inter
        with torch.inference_mode():
            feats, _ = self.messenger.incoming(torch.from_numpy(np.stack(msgs)))
            inn, inter = pool(feats, torch.ones(len(msgs), dtype=torch.bool))
        return inn, inter


class LearnedCentral(CentralNode):
    """CentralComm's node at evaluation: reads the uploads, sends each uploader its
    assignment."""

    def __init__(self, public: PublicInfo, outbox: Outbox, planner: CentralPlanner) -> None:
        super().__init__(public, outbox)
        self.planner = planner

    def send(self, round: int, inbox: list[Message]) -> None:
        uploads = {m.sender: np.array(m.vector) for m in inbox if m.kind == UPLOAD}
        if round != 0 or not uploads:
            return
        agents = [a for a in self.public.agents if a in uploads]
        with torch.inference_mode():
            up = torch.from_numpy(np.stack([uploads[a] for a in agents]))
            out = self.planner(up, torch.ones(len(agents), dtype=torch.bool))
        for a, vector in zip(agents, out.numpy(), strict=True):
            self.outbox.send(a, vector, "assignment")
