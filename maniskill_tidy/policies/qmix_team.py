"""The QMIX team (the paper's QMIX baseline): each agent acts on its own Q-network.

Per env step an agent perceives its frame (``PerceivingAgent``), encodes its state feature and
sends it to every teammate (256 values each: in Setting I an agent receives 2 x 256 = 512, the
paper's figure); it fuses what arrived with its own feature and takes the legal action of
highest Q (epsilon-greedy while training). Legal: the navigation actions and Stop always; an
operation only when the agent can do it and it can succeed from here (PickUp: an object the
detector finds misplaced in reach; PutDown: a visible surface of one of the three receptacle
types the reasonable-receptacle predictor found likeliest for the object held; Drop: holding).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np
import torch

from maniskill_tidy.common.agent_files import resolve
from maniskill_tidy.envs.actions import Action, Targeted
from maniskill_tidy.models.checkpoints import (
    CheckpointError,
    for_agents,
    load_perception,
    load_qmix,
    verify,
)
from maniskill_tidy.models.qmix import ACTIONS, QmixTeamModel, observation
from maniskill_tidy.policies.agent_config import PerceptionLook, QmixConfig
from maniskill_tidy.policies.base import EXPLORE, Agent, AgentView, PublicInfo, SubTask, Team
from maniskill_tidy.policies.channel import Message, Outbox
from maniskill_tidy.policies.perceiving import PerceivingAgent
from maniskill_tidy.tasks.teams import SETTINGS, setting_of

OPERATIONS = (Action.PickUp, Action.PutDown, Action.Drop)


@dataclass
class Steps:
    """What the agents of one episode did, for the replay buffer (training only)."""

    obs: dict[int, dict[int, tuple]] = field(default_factory=dict)  # t -> i -> (obs, a, legal)

    def add(self, t: int, i: int, obs: torch.Tensor, action: int, legal: np.ndarray) -> None:
        self.obs.setdefault(t, {})[i] = (obs, action, legal)


class QmixAgent(PerceivingAgent):
    def __init__(self, name: str, public: PublicInfo, outbox: Outbox, team: QmixTeam) -> None:
        model, perception = team.models(public.capabilities)
        super().__init__(name, public, outbox, perception)
        self.net = model.agents[self.i]
        self.slots = [a for a in public.agents if a != name]  # teammates' feature slots
        self.feature = model.feature
        self.epsilon, self.steps = team.epsilon, team.steps
        self.rng = np.random.default_rng([public.seed, self.i, 17])
        self.h: torch.Tensor | None = None

    def observe(self, view: AgentView) -> None:
        self.obs = observation(self.perceive(view))[0]  # (1, OBS)
        with torch.inference_mode():
            self.f = self.net.encode(self.obs)

    def send(self, round: int, inbox: list[Message]) -> None:
        if round == 0 and self.outbox.peers:
            self.outbox.send(self.outbox.peers, self.f[0].numpy(), "state-feature")

    def act(self, inbox: list[Message]) -> Action | Targeted:
        others = torch.zeros(1, len(self.slots), self.feature)
        for m in inbox:
            if m.kind == "state-feature":
                others[0, self.slots.index(m.sender)] = torch.from_numpy(np.array(m.vector))
        with torch.inference_mode():
            q, self.h = self.net(self.f, others, self.h)
        targets = self._targets()
        legal = np.array([a < Action.PickUp or targets.get(Action(a)) is not None
                          for a in range(ACTIONS)])  # fmt: skip
        if self.rng.random() < self.epsilon:
            a = int(self.rng.choice(np.flatnonzero(legal)))
        else:
            a = int(torch.where(torch.from_numpy(legal), q[0], -torch.inf).argmax())
        if self.steps is not None:
            self.steps.add(self.t, self.i, self.obs[0], a, legal)
        action = targets.get(Action(a), Action(a))
        self._last_op = action.action if isinstance(action, Targeted) else action
        return action

    def _targets(self) -> dict[Action, Action | Targeted | None]:
        if self.state.held is not None:
            self.p_receptacle = self.picked_receptacles
        return {op: self._operation(op.name, SubTask(EXPLORE)) for op in OPERATIONS}


class QmixTeam(Team):
    name = "qmix"
    observations = "rgb+depth+segmentation"
    communication = "state-features"
    perception: ClassVar[str] = (
        "learned: small CNNs and GCN (agents/perception) over ground-truth segmentation; "
        "QMIX Q-networks on the perception features"
    )
    look: ClassVar[str | None] = PerceptionLook(QmixConfig.perception)  # its views': v1
    folder: ClassVar[Path] = Path("agents/qmix")

    def __init__(self, model: QmixTeamModel | None = None, epsilon: float = 0.0,
                 perception=None, steps: Steps | None = None) -> None:  # fmt: skip
        """At evaluation: the shipped models. In training: the live model, its exploration
        rate and where to record the steps."""
        self.model, self.epsilon, self.steps, self._perception = model, epsilon, steps, perception
        self._loaded: dict = {}

    @classmethod
    def trained_setting(cls, capabilities) -> str:
        setting = setting_of(capabilities)
        if setting is None:
            raise ValueError(f"qmix is trained for the teams of Settings {sorted(SETTINGS)}, "
                             f"not {list(map(tuple, capabilities))}")  # fmt: skip
        return setting

    @classmethod
    def missing_model(cls, team: tuple) -> str | None:
        setting = cls.trained_setting(team)
        try:
            verify(resolve(cls.folder) / f"setting_{setting}",
                   f"maniskill-tidy train agents/qmix.yaml --setting {setting}")  # fmt: skip
        except CheckpointError as err:
            return str(err)
        return None

    def models(self, capabilities: list) -> tuple:
        if self.model is not None:
            return self.model, self._perception
        setting = self.trained_setting(capabilities)
        if setting not in self._loaded:
            torch.set_num_threads(1)
            model, saved = load_qmix(resolve(self.folder) / f"setting_{setting}")
            perception = load_perception(resolve(saved["perception"]))
            self._loaded[setting] = (for_agents(model), for_agents(perception))
        return self._loaded[setting]

    def make_agent(self, name: str, public: PublicInfo, outbox: Outbox) -> Agent:
        return QmixAgent(name, public, outbox, self)
