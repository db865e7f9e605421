"""A team written outside the package (docs/teams.md): each robot walks ahead and turns when
blocked. Play it from this folder with

    maniskill-tidy eval --policy wanderer:WandererTeam --setting I --episodes 4 --workers 2

or through a config that names it (``wanderer.yaml``: ``team_class: wanderer:WandererTeam``).
"""

from __future__ import annotations

import numpy as np

from maniskill_tidy.envs.actions import Action
from maniskill_tidy.policies.base import Agent, Team


class Wanderer(Agent):
    def __init__(self, name, public, outbox, turn: Action) -> None:
        super().__init__(name, public, outbox)
        self.turn, self.blocked = turn, False

    def observe(self, view):  # view.obs: this agent's own observation only
        self.blocked = bool(view.failed)  # its last move was refused

    def act(self, inbox):  # inbox: what was sent to this agent this step
        return self.turn if self.blocked else Action.MoveAhead


class WandererTeam(Team):
    name = "wanderer"
    needs_images = False  # it reads no image: the env renders none
    communication = "none"
    perception = "none: it only knows whether its last move was refused"

    def __init__(self, turn: str = "RotateLeft") -> None:
        self.turn = Action[turn]  # a config's `options: {turn: RotateRight}` changes it

    def make_agent(self, name, public, outbox):
        return Wanderer(name, public, outbox, self.turn)


class Talker(Wanderer):
    """A wanderer that tells its teammates where it is, and reads where they are."""

    def observe(self, view):
        super().observe(view)
        self.pose = view.obs["pose"]  # (x, y, rotation)

    def send(self, round, inbox):
        self.outbox.send(self.outbox.peers, np.asarray(self.pose, np.float32), kind="state")

    def act(self, inbox):
        self.teammates = {m.sender: m.vector for m in inbox if m.kind == "state"}
        return super().act(inbox)


class TalkerTeam(WandererTeam):
    name = "talker"
    communication = "broadcast: each agent's pose, every step"

    def make_agent(self, name, public, outbox):
        return Talker(name, public, outbox, self.turn)
