"""The object-memory team with HanGrCom links that carry memory entries (DESIGN.md, "Beyond
the paper").

Each agent is a :class:`~maniskill_tidy.policies.memory.MemoryAgent` (heuristic memory, a
learned choice of job) whose messages are the paper's handshake instead of its teacher's
pattern, in three rounds per step (``policies/handshake_exchange.py``):

0. a query (``key`` values) to every teammate still playing;
1. its row of T (N values), so that every agent forms the same groups;
2. along each link (A_i asked, ``T_ij > mu``), A_j sends A_i its state (10 values,
   ``policies/messages.py``) and, when A_i is a manipulator (capabilities are public), up to
   ``entries`` memory entries, 4 values each: the catalog
   index of a misplaced object's type and where it lies (x, y, z). They are the misplaced
   objects A_j remembers and has not yet told A_i of, nearest to A_j first; A_i takes each as
   a teammate's report (a ``look`` candidate of its pointer), as the teacher takes a map crop's.

Query and key come from :func:`summary` of the agent's own memory, through
``models/memory_links.py`` (trained: ``training/memory_links.py``). The paper's value vector
is left out: the pointer is cloned from a teacher that never had one, so it could not read it;
the entries are what a link carries. Every value sent is counted (ACm), queries and rows of T
included.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from maniskill_tidy.knowledge import load_catalog
from maniskill_tidy.models.checkpoints import state_digest
from maniskill_tidy.policies.base import EXPLORE, Agent, PublicInfo, SubTask
from maniskill_tidy.policies.channel import Message, Outbox
from maniskill_tidy.policies.handshake_exchange import HandshakeExchange
from maniskill_tidy.policies.heuristic_jobs import Report
from maniskill_tidy.policies.memory import MemoryAgent, MemoryTeam
from maniskill_tidy.policies.messages import STATE_DIMS, decode_state, encode_state

ENTRY_DIMS = 4  # type index, x, y, z
SUMMARY = (
    "navigation", "manipulation", "high_camera",  # the agent's capability vector
    "holding",
    "busy",  # on its way to pick up or put down
    "misplaced",  # log(1 + misplaced objects it remembers, not yet tidied)
    "untold",  # log(1 + the most of them some teammate manipulator has not been told of)
    "reports",  # log(1 + teammates' reports it has not checked)
    "searched",  # the share of the grid's free cells it has searched
)  # fmt: skip


def encode_entries(state: np.ndarray, entries: list[tuple[str, np.ndarray]]) -> np.ndarray:
    """A link's vector: the sender's state, then (type index, x, y, z) per entry."""
    categories = load_catalog().categories
    rows = [[categories.index(t), *np.asarray(p, np.float32)[:3]] for t, p in entries]
    return np.concatenate([state, np.asarray(rows, np.float32).reshape(-1)]).astype(np.float32)


def decode_entries(v: np.ndarray):
    """(sender's state, [(type, (x, y))]) of a link's vector."""
    v = np.asarray(v, np.float32)
    if v.size < STATE_DIMS or (v.size - STATE_DIMS) % ENTRY_DIMS:
        raise ValueError(f"a memory link has {STATE_DIMS} + {ENTRY_DIMS} x k values, got {v.size}")
    categories = load_catalog().categories
    rows = v[STATE_DIMS:].reshape(-1, ENTRY_DIMS)
    return decode_state(v[:STATE_DIMS]), [(categories[int(r[0])], (float(r[1]), float(r[2])))
                                          for r in rows]  # fmt: skip


class EntryExchange(HandshakeExchange):
    """The handshake, with memory entries where HanGrCom sends its value vector."""

    def __init__(self, agent: LinkedMemoryAgent, mu: float, delta: float) -> None:
        super().__init__(agent.name, agent.public.agents, agent.outbox, mu, delta)
        self.agent = agent

    def value_for(self, receiver: str, gens: dict[str, torch.Tensor]) -> np.ndarray:
        return self.agent.link_vector(receiver)


class LinkedMemoryAgent(MemoryAgent):
    def __init__(self, name: str, public: PublicInfo, outbox: Outbox, team: LinkedMemoryTeam):
        super().__init__(name, public, outbox, team)
        self.links = None if team.recording_links else team.links_model(public.capabilities)
        links = team.config.links_settings()
        self.max_entries = links["entries"]
        self.exchange = EntryExchange(self, links["mu"], links["delta"])
        # object ids told to each teammate manipulator (capabilities are public): only they fetch
        self.told: dict[str, set[str]] = {p: set() for p in outbox.peers
                                          if public.capability(p)[1]}  # fmt: skip
        self.free_cells = sum(row.count(".") for row in public.house.navgrid.rows)
        self.snapshots: list[dict] | None = [] if team.recording_links else None
        self.gens: dict[str, torch.Tensor] = {}
        self._trace: dict = {}

    def _misplaced(self) -> list:
        return [k for k in self.objects.values() if k.misplaced and k.object_id not in self.done]

    def summary(self) -> np.ndarray:
        """What query and key are made of: this agent's own memory, nothing else (SUMMARY)."""
        misplaced = self._misplaced()
        untold = max((sum(k.object_id not in told for k in misplaced)
                      for told in self.told.values()), default=0)  # fmt: skip
        busy = self.job is not None and self.job.kind in ("pick", "place")
        return np.array(
            [*self.capability, self.state.held is not None, busy, math.log1p(len(misplaced)),
             math.log1p(untold), math.log1p(len(self.reports)),
             float(self.covered.sum()) / max(self.free_cells, 1)], dtype=np.float32,
        )  # fmt: skip

    def send(self, round: int, inbox: list[Message]) -> None:
        if round == 0:
            sf = self.summary()
            if self.snapshots is not None:  # training data: this step's memory, for labels
                self.snapshots.append(self._snapshot(sf))
            if self.links is not None:
                with torch.inference_mode():
                    self.gens = self.links(torch.from_numpy(sf))
        if self.links is not None:
            self.exchange.send(round, inbox, self.gens)

    def _snapshot(self, sf: np.ndarray) -> dict:
        known = {*self.objects, *self.done}
        return {"t": self.t, "sf": sf, "manipulator": self.manipulator, "known": known,
                "misplaced": {k.object_id: (k.type, *k.position[:2]) for k in self._misplaced()},
                "reports": [(r.type, *r.xy) for r in self.reports],
                "told": {p: set(s) for p, s in self.told.items()}}  # fmt: skip

    def link_vector(self, receiver: str) -> np.ndarray:
        """This agent's state and, for a manipulator, the nearest misplaced objects ``receiver``
        was not told of."""
        subtask = self.job.subtask if self.job is not None else SubTask(EXPLORE)
        if self.job is not None and self.job.kind == "park":
            subtask = SubTask("Park")
        x, y = self.house.navgrid.center(*self.state.cell)
        state = encode_state(self.capability, (x, y, self.state.rotation), subtask)
        told = self.told.get(receiver)
        if told is None:  # a scout fetches nothing: where this agent is and what it does
            return encode_entries(state, [])
        here = np.array([x, y])
        untold = sorted((k for k in self._misplaced() if k.object_id not in told),
                        key=lambda k: float(np.hypot(*(k.position[:2] - here))))  # fmt: skip
        entries = untold[: self.max_entries]
        told.update(k.object_id for k in entries)
        return encode_entries(state, [(k.type, k.position) for k in entries])

    def _receive(self, inbox: list[Message]) -> None:
        for m in inbox:
            if m.kind == "value":
                state, entries = decode_entries(m.vector)
                self._heard(m.sender, state)
                for object_type, xy in entries:
                    self._add_report(Report(object_type, xy))
        if self.links is not None and self.exchange.hs is not None:
            ex = self.exchange
            self._trace = {"T": ex.T, "groups": ex.groups(), "links": ex.links()}

    def trace(self) -> dict:
        """The pointer's choice (if it made one) and this step's handshake (T, groups,
        links): recordings show both."""
        out, self._trace = {**super().trace(), **self._trace}, {}
        return out


class LinkedMemoryTeam(MemoryTeam):
    """Heuristic memory, a learned choice of job, learned links carrying memory entries."""

    name = "memory-links"
    communication = "handshake"
    rounds = 3

    def __init__(self, recording_links: bool = False, **kwargs) -> None:
        """``recording_links``: play without messages and keep each agent's memory every step
        (``LinkedMemoryAgent.snapshots``, of the agents in ``made``): the links' training
        data."""
        super().__init__(**kwargs)
        self.recording_links = recording_links

    def links_model(self, capabilities: list):
        from maniskill_tidy.models.checkpoints import read
        from maniskill_tidy.models.memory_links import MemoryLinks

        setting = self.trained_setting(capabilities)
        key = ("links", setting)
        if key not in self._loaded:
            saved = read(self.model_folder(capabilities), self._hint(capabilities))
            if "links" not in saved:
                raise ValueError(f"{self.model_folder(capabilities)} holds a pointer without "
                                 f"links; train it with `{self._hint(capabilities)}`")  # fmt: skip
            model = MemoryLinks(**saved["links"]["sizes"])
            model.load_state_dict({k: v.float() for k, v in saved["links"]["state"].items()})
            self._loaded[key] = model.eval()
        return self._loaded[key]

    def use_links(self, setting: str, model) -> None:
        """Play ``model`` in ``setting`` instead of the saved links (training's val runs)."""
        self._loaded[("links", setting)] = model.eval()

    @classmethod
    def _hint(cls, team) -> str:
        return f"maniskill-tidy train {cls.config_file} --setting {cls.trained_setting(team)}"

    @classmethod
    def missing_model(cls, team: tuple) -> str | None:
        why = super().missing_model(team)
        if why is None and "links" not in torch.load(cls.model_folder(team) / "model.pt",
                                                      weights_only=False):  # fmt: skip
            why = (
                f"{cls.model_folder(team)} holds a pointer without links; train it with "
                f"`{cls._hint(team)}`"
            )
        return why

    @classmethod
    def model_hash(cls, team: tuple) -> str:
        """The pointer's and the links' weights together."""
        saved = torch.load(cls.model_folder(team) / "model.pt", weights_only=False)
        return state_digest([saved["state"], saved["links"]["state"]])

    def make_agent(self, name: str, public: PublicInfo, outbox: Outbox) -> Agent:
        agent = LinkedMemoryAgent(name, public, outbox, self)
        if self.recording_links or self.recording or self.keep_decisions:
            self.made.append(agent)
        return agent
