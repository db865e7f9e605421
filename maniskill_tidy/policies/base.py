"""The policy interface every team implements, and what a team is told at the start.

A team acts for all its agents: ``reset`` with the task's public information (and, for a
privileged team only, the env itself), then ``act`` once per env step on the per-agent
observations. Teams talk only through the :class:`~maniskill_tidy.policies.channel.Channel`
they are given, so the runner can count what they send.

Besides actions a team may report, per agent, the sub-task and sub-goal it is pursuing (the
paper's hierarchical decision, Section 5.4); the expert's reports are the demonstrations, and
recordings show them for every team.
"""

from __future__ import annotations

import dataclasses
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar

from maniskill_tidy.envs.actions import Action, Targeted
from maniskill_tidy.houses.schema import House
from maniskill_tidy.policies.channel import Channel
from maniskill_tidy.tasks.teams import Capability

EXPLORE, PLACE = "Explore", "Place"
OPERATIONS = ("NoAction", "PickUp", "PutDown", "Drop")


@dataclass(frozen=True)
class PublicInfo:
    """What every team knows at the start: the floor plan, not where any object lies."""

    house: House  # rooms, walls, doors, furniture and navigation grid; ``objects`` is empty
    agents: list[str]
    capabilities: list[Capability]
    episode_id: str
    seed: int
    # The segmentation's label table, id -> Instance(kind, type, id): with ground-truth
    # segmentation it stands in for a trained detector's class (and instance) output.
    instances: dict = dataclasses.field(default_factory=dict)

    @classmethod
    def of(cls, env, seed: int) -> PublicInfo:
        return cls(
            house=dataclasses.replace(env.house, objects=[]),
            agents=list(env.agent_names),
            capabilities=list(env.team),
            episode_id=env.episode.id,
            seed=seed,
            instances=dict(env.instances),
        )


@dataclass(frozen=True)
class SubTask:
    """(Explore | Place, o, p, r): the object, receptacle and room types ("" when none)."""

    kind: str
    object_type: str = ""
    receptacle_type: str = ""
    room_type: str = ""


@dataclass(frozen=True)
class SubGoal:
    """(dx, dy, drot, ope, stop): the next waypoint within 4 cells, in the agent's frame.

    ``dx`` is to the agent's right and ``dy`` ahead, in 0.25 m cells, each in -4..4; ``drot``
    the turn wanted there (0, 90, 180, 270 degrees counter-clockwise); ``ope`` the operation
    once there (one of ``OPERATIONS``); ``stop`` whether the agent stops after it.
    """

    dx: int
    dy: int
    drot: int
    ope: str
    stop: bool


AgentAction = int | Action | Targeted


class Team(ABC):
    name: ClassVar[str]
    privileged: ClassVar[bool] = False  # reads the simulator's state (the expert)
    needs_images: ClassVar[bool] = True  # False: the env may skip rendering (obs_mode "none")

    @abstractmethod
    def reset(self, info: PublicInfo, channel: Channel, env: Any | None = None) -> None:
        """Start an episode; ``env`` (the unwrapped env) is given to privileged teams only."""

    @abstractmethod
    def act(self, obs: dict[str, dict], info: dict) -> dict[str, AgentAction]:
        """One action per agent that has not stopped; ``info`` is the env's last info."""

    def labels(self) -> dict[str, tuple[SubTask, SubGoal]]:
        """Per agent, the sub-task and sub-goal behind the last actions (empty if none)."""
        return {}
