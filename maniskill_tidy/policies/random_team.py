"""The paper's Random baseline: every agent draws uniformly from its own action space.

Stop is left out of the draw (with it, a team of three would end most episodes within a few
steps); as in the paper the episode then runs to the 300-step limit. Each agent has its own
generator, seeded from the episode seed and its index in the team.
"""

from __future__ import annotations

import numpy as np

from maniskill_tidy.envs.actions import Action
from maniskill_tidy.policies.base import Agent, AgentView, PublicInfo, Team
from maniskill_tidy.policies.channel import Message, Outbox


class RandomAgent(Agent):
    def __init__(self, name: str, public: PublicInfo, outbox: Outbox) -> None:
        super().__init__(name, public, outbox)
        self.rng = np.random.default_rng([public.seed, public.agents.index(name)])
        manipulator = bool(public.capability(name)[1])
        self.choices = [a for a in Action if a != Action.Stop and (manipulator or a < Action.Stop)]

    def observe(self, view: AgentView) -> None:
        pass

    def act(self, inbox: list[Message]) -> Action:
        return self.choices[self.rng.integers(len(self.choices))]


class RandomTeam(Team):
    name = "random"
    needs_images = False
    perception = "none (uniform random actions)"

    def make_agent(self, name: str, public: PublicInfo, outbox: Outbox) -> Agent:
        return RandomAgent(name, public, outbox)
