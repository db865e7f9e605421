"""One agent's side of HanGrCom's message exchange, over the counting channel.

The rules are ``models/hangrcom.py``'s inference mode; this is who sends what to whom, in
three communication rounds of one env step:

0. ``query`` (qry): to every teammate that sent one last step (a teammate that did not has
   stopped, and stopping is for good);
1. ``attention`` (N values): the agent's row of T (softmax over the agents present), to the
   same teammates, so that every agent forms the same groups;
2. ``value`` (val) to each teammate that links to it (asked, T_ij > mu), and ``inter`` (inv)
   to each agent whose group attends to it most (when the agent has an inv).

Then :meth:`combine` gives ``inn`` and ``int`` from what arrived, equal to
``models.hangrcom.hard`` on the same T.
"""

from __future__ import annotations

import numpy as np
import torch

from maniskill_tidy.models.hangrcom import Handshake, handshake
from maniskill_tidy.policies.channel import Message, Outbox


class HandshakeExchange:
    def __init__(self, name: str, agents: list[str], outbox: Outbox, mu: float, delta: float):
        self.name, self.agents, self.outbox = name, list(agents), outbox
        self.i = self.agents.index(name)
        self.mu, self.delta = mu, delta
        self.alive = set(outbox.peers)  # teammates that sent a query last step
        self.T = np.eye(len(self.agents), dtype=np.float32)
        self.hs: Handshake | None = None

    def send(self, round: int, inbox: list[Message], gens: dict[str, torch.Tensor]) -> None:
        """Round ``round`` of the exchange, with this step's qry, key, val and inv."""
        if round == 0:
            if self.alive:
                self.outbox.send(sorted(self.alive), gens["qry"].numpy(), "query")
        elif round == 1:
            queries = {m.sender: m.vector for m in inbox if m.kind == "query"}
            self.alive = set(queries)
            self.present = np.array([a == self.name or a in queries for a in self.agents])
            qry = torch.stack([torch.from_numpy(np.array(queries[a])) if a in queries
                               else gens["qry"] for a in self.agents])  # fmt: skip
            attc = qry @ gens["key"] / np.sqrt(qry.shape[-1])
            attc[~torch.from_numpy(self.present)] = float("-inf")
            self.row = torch.softmax(attc, -1).numpy()
            if self.alive:
                self.outbox.send(sorted(self.alive), self.row, "attention")
        elif round == 2:
            t = np.zeros((len(self.agents),) * 2, dtype=np.float32)
            t[self.i] = self.row
            for m in inbox:
                if m.kind == "attention":
                    t[self.agents.index(m.sender)] = m.vector
            self.T, self.hs = t, handshake(t, self.present, self.mu, self.delta)
            for j, other in enumerate(self.agents):
                if other not in self.alive:
                    continue
                if self.hs.links[j, self.i]:
                    self.outbox.send(other, self.value_for(other, gens), "value")
                if "inv" in gens and self.hs.inter[j] == self.i:
                    self.outbox.send(other, gens["inv"].numpy(), "inter")

    def value_for(self, receiver: str, gens: dict[str, torch.Tensor]) -> np.ndarray:
        """What a link to ``receiver`` carries: the learned value vector (the object-memory
        team's links carry memory entries instead, ``policies/memory_links.py``)."""
        return gens["val"].numpy()

    def combine(
        self, inbox: list[Message], gens: dict[str, torch.Tensor]
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """``inn = T_ii val_i + sum over links T_ij val_j`` and ``int`` (zero if none came)."""
        inn = float(self.T[self.i, self.i]) * gens["val"]
        inter = torch.zeros_like(gens["inv"])
        for m in inbox:
            j = self.agents.index(m.sender)
            if m.kind == "value":
                inn = inn + float(self.T[self.i, j]) * torch.from_numpy(np.array(m.vector))
            elif m.kind == "inter":
                inter = torch.from_numpy(np.array(m.vector))
        return inn, inter

    def groups(self) -> list[list[str]]:
        """This step's handshake groups, by name."""
        if self.hs is None:
            return [[self.name]]
        return [[self.agents[i] for i in g] for g in self.hs.groups]

    def links(self) -> list[tuple[str, str]]:
        """This step's (sender, receiver) pairs of values."""
        if self.hs is None:
            return []
        pairs = zip(*np.nonzero(self.hs.links), strict=True)
        return [(self.agents[j], self.agents[i]) for i, j in pairs]
