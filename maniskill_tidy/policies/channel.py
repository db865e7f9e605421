"""The team's communication channel: every message is a vector, and every dimension is counted.

AvgCom (the paper's ACm) is ``Total / (Len * N)`` where ``Total`` is the number of dimensions
received over the episode: a vector of ``d`` values sent to ``m`` receivers costs ``d * m``
(a broadcast of 410 values in a team of three costs 820 per step, as the paper counts it).
The cost comes from the arrays actually handed to :meth:`Channel.send`, never from a constant.

Within one env step agents first send (in one or more rounds), then read their inboxes and
decide: a message is readable in the step it was sent and gone at the next
:meth:`Channel.new_step`. Endpoints are the agent names and, for teams with a central planner,
``CENTRAL``. Each endpoint sends only through its own :class:`Outbox`, and a receiver gets a
read-only copy of the vector: a message is the only thing that crosses between agents.
"""

from __future__ import annotations

from dataclasses import dataclass

import networkx as nx
import numpy as np

CENTRAL = "central"


@dataclass(frozen=True)
class Message:
    sender: str
    receiver: str
    kind: str  # what the vector holds, e.g. "state", "map", "assignment"
    vector: np.ndarray  # 1-D float32, read-only
    round: int = 0  # the communication round it was sent in

    @property
    def dims(self) -> int:
        return int(self.vector.size)


class Channel:
    def __init__(self, agents: list[str], central: bool = False) -> None:
        self.agents = list(agents)
        self.endpoints = self.agents + ([CENTRAL] if central else [])
        self._index = {name: i for i, name in enumerate(self.endpoints)}
        self.total = 0  # dimensions received over the episode
        self.step_messages: list[Message] = []
        self.round = 0

    def new_step(self) -> None:
        self.step_messages = []
        self.round = 0

    def send(self, sender: str, receivers: list[str] | str, vector, kind: str) -> None:
        """Send ``vector`` (any array-like of numbers) from ``sender`` to each receiver."""
        receivers = [receivers] if isinstance(receivers, str) else list(receivers)
        for name in [sender, *receivers]:
            if name not in self._index:
                raise KeyError(f"unknown endpoint {name!r}; this channel has {self.endpoints}")
        if sender in receivers:
            raise ValueError(f"{sender} sends to itself; messages go to other endpoints")
        flat = np.array(vector, dtype=np.float32).ravel()  # a copy: the sender keeps its own
        if not np.all(np.isfinite(flat)):
            raise ValueError(f"{sender} sends a {kind!r} vector with NaN or infinite values")
        flat.flags.writeable = False
        for receiver in receivers:
            self.step_messages.append(Message(sender, receiver, kind, flat, self.round))
            self.total += flat.size

    def inbox(self, name: str, before_round: int | None = None) -> list[Message]:
        """Messages to ``name`` this step (only those of rounds before ``before_round``)."""
        return [
            m
            for m in self.step_messages
            if m.receiver == name and (before_round is None or m.round < before_round)
        ]

    @property
    def step_total(self) -> int:
        return sum(m.dims for m in self.step_messages)

    def matrix(self) -> np.ndarray:
        """Dimensions sent this step, [sender, receiver], in ``endpoints`` order."""
        out = np.zeros((len(self.endpoints),) * 2, dtype=np.int64)
        for m in self.step_messages:
            out[self._index[m.sender], self._index[m.receiver]] += m.dims
        return out

    def groups(self) -> list[list[str]]:
        """This step's communication groups: agents linked by messages (directly or via a hub)."""
        graph = nx.Graph()
        graph.add_nodes_from(self.endpoints)
        graph.add_edges_from((m.sender, m.receiver) for m in self.step_messages)
        out = []
        for component in nx.connected_components(graph):
            members = [a for a in self.agents if a in component]
            if members:
                out.append(members)
        return sorted(out, key=lambda g: self.agents.index(g[0]))


class Outbox:
    """One endpoint's handle on the channel: it sends as that endpoint and nothing else."""

    def __init__(self, channel: Channel, sender: str) -> None:
        if sender not in channel.endpoints:
            raise KeyError(f"unknown endpoint {sender!r}; this channel has {channel.endpoints}")
        self._channel, self.sender = channel, sender

    @property
    def peers(self) -> list[str]:
        """The other agents (not the central node) this endpoint can send to."""
        return [a for a in self._channel.agents if a != self.sender]

    @property
    def has_central(self) -> bool:
        return CENTRAL in self._channel.endpoints

    def send(self, receivers: list[str] | str, vector, kind: str) -> None:
        self._channel.send(self.sender, receivers, vector, kind)
