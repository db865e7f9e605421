"""The team interface: decentralised execution is the shape of the API.

A camera-only team is a factory of agents. For every episode the runner
(``eval/episode.py``) asks it for one :class:`Agent` per robot, and a :class:`CentralNode` if
the team has one, each bound to its own :class:`~maniskill_tidy.policies.channel.Outbox`.
Every step the runner then

1. gives each active agent its :class:`AgentView`: its own observation and the outcome of its
   own last action, nothing else (``observe``);
2. runs ``Team.rounds`` communication rounds: in each, every agent and then the central node
   may send vectors (``send``), and what is sent in a round can be read from the next one on;
3. asks each agent for its action, with its inbox (``act``).

An agent is called with nothing but its view, its inbox and the public information of
:class:`PublicInfo`; a central node sees only what is sent to it. Agents of one team may share
code, read-only public data (the floor plan, the placement knowledge) and weights, not state:
a teammate's position, parking spot or held object reaches an agent only as a message, and is
counted there. Success counters never reach a camera-only team.

Only privileged teams (the expert) see the simulator: a :class:`PrivilegedTeam` is handed the
env and acts for all its agents at once; every result it produces is marked privileged.

Besides actions, an agent may report the sub-task and sub-goal it is pursuing (the paper's
hierarchical decision, Section 5.4); the expert's reports are the demonstrations, and
recordings show them for every team.
"""

from __future__ import annotations

import dataclasses
import hashlib
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from maniskill_tidy.envs.actions import Action, Targeted
from maniskill_tidy.houses.schema import House
from maniskill_tidy.policies.channel import Message, Outbox
from maniskill_tidy.tasks.teams import Capability

EXPLORE, PLACE = "Explore", "Place"
OPERATIONS = ("NoAction", "PickUp", "PutDown", "Drop")
# What one agent's observation may hold (``AgentView.obs``); images only in image obs modes.
OBSERVATION_KEYS = frozenset(
    {"rgb", "depth", "segmentation", "pose", "intrinsics", "extrinsics", "capability", "held"}
)


def opaque(name: str) -> str:
    """A stable name for a house or an episode that says nothing of where it comes from."""
    return "x" + hashlib.sha256(f"maniskill-tidy:{name}".encode()).hexdigest()[:16]


@dataclass(frozen=True)
class PublicInfo:
    """What every agent knows at the start: the floor plan, not where any object lies."""

    # rooms, walls, doors, furniture and navigation grid; ``objects`` is empty, ``seed`` None
    # and ``id`` opaque: the generator is public, and its seed or the house's index in the
    # dataset would rebuild the mess (``generate_meta_task``)
    house: House
    agents: list[str]
    capabilities: list[Capability]
    episode_id: str  # opaque, for the same reason (not "house_00010/task_0/start_0")
    seed: int  # the agents' own random seed
    # The segmentation's label table, id -> Instance(kind, type, id): with ground-truth
    # segmentation it stands in for a trained detector's class (and instance) output.
    instances: dict = dataclasses.field(default_factory=dict)
    # Only for an oracle team (SA(Oracle)): misplaced object id -> its position (x, y, z).
    oracle_misplaced: dict = dataclasses.field(default_factory=dict)

    @classmethod
    def of(cls, env, seed: int, oracle: bool = False) -> PublicInfo:
        def centre(oid: str) -> tuple[float, ...]:  # where the simulator has it now
            size = env.manipulation.sizes[oid]
            return tuple(float(v) for v in env.hs.object_bottom(oid) + [0.0, 0.0, size[2] / 2])

        house = dataclasses.replace(env.house, objects=[], seed=None, id=opaque(env.house.id))
        return cls(
            house=house,
            agents=list(env.agent_names),
            capabilities=list(env.team),
            episode_id=opaque(env.episode.id),
            seed=seed,
            instances=dict(env.instances),
            oracle_misplaced={oid: centre(oid) for oid in env.misplaced} if oracle else {},
        )

    def capability(self, name: str) -> Capability:
        return self.capabilities[self.agents.index(name)]


@dataclass(frozen=True)
class AgentView:
    """One agent's input in one step: its own observation and its own last action's outcome."""

    name: str
    step: int  # env steps taken so far in this episode
    obs: dict[str, np.ndarray]  # keys from OBSERVATION_KEYS
    failed: str = ""  # why its last action failed ("" if it did not)


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
Label = tuple[SubTask, SubGoal]


class Agent(ABC):
    """One robot's policy. Made per episode by its team; holds only its own state."""

    # It sends and reads messages only at steps that are multiples of this (its sub-goal steps,
    # the whole team in step); on the others the runner makes its calls one (quiet_step) and
    # stops the episode if anyone sends
    decide_every: int = 1

    def __init__(self, name: str, public: PublicInfo, outbox: Outbox) -> None:
        self.name, self.public, self.outbox = name, public, outbox

    @abstractmethod
    def observe(self, view: AgentView) -> None:
        """Take in this step's own observation (perception, memory)."""

    def quiet_step(self, view: AgentView, rounds: int) -> AgentAction:
        """A step between sub-goal steps (``decide_every``), on which no agent sends: the calls
        the runner would make one by one, every inbox empty, as one (one message to a host)."""
        self.observe(view)
        for r in range(rounds):
            self.send(r, [])
        return self.act([])

    def send(self, round: int, inbox: list[Message]) -> None:  # noqa: B027  (optional hook)
        """Communication round ``round``: send through ``self.outbox`` (default: nothing)."""

    @abstractmethod
    def act(self, inbox: list[Message]) -> AgentAction:
        """This step's action, given every message received this step."""

    def label(self) -> Label | None:
        """The sub-task and sub-goal behind the last action (None if the agent has none)."""
        return None

    def trace(self) -> dict:
        """What else was behind the last action, for recordings (HanGrCom's T and groups)."""
        return {}


class CentralNode(ABC):
    """A team's central planner: it sees only the messages sent to it."""

    def __init__(self, public: PublicInfo, outbox: Outbox) -> None:
        self.public, self.outbox = public, outbox

    @abstractmethod
    def send(self, round: int, inbox: list[Message]) -> None:
        """Communication round ``round``: read the uploads, send through ``self.outbox``."""


class Team(ABC):
    """A team of camera-only agents (the decentralised interface above)."""

    name: ClassVar[str]
    privileged: ClassVar[bool] = False
    needs_images: ClassVar[bool] = True  # False: the env may skip rendering (obs_mode "none")
    observations: ClassVar[str] = "rgb+depth+segmentation"  # the env obs_mode it reads
    communication: ClassVar[str] = "none"  # what the leaderboard calls its pattern
    central: ClassVar[bool] = False  # the channel gets a CENTRAL endpoint
    rounds: ClassVar[int] = 1  # communication rounds per step
    team_override: ClassVar[list | None] = None  # plays with its own team (SA: one manipulator)
    perception: ClassVar[str] = ""  # what stands in for the paper's perception, for the results
    # The look whose pixels its learned weights were trained on (``perception_look``), where
    # ``eval`` plays it unless ``--env`` says otherwise; None: any look (it reads no RGB
    # through weights, or reads the renderer's segmentation, the same in both).
    look: ClassVar[str | None] = None
    # Given the misplaced objects' locations at reset (``PublicInfo.oracle_misplaced``): the
    # paper's SA(Oracle). Such a team reads the task, so its rows are privileged too.
    oracle: ClassVar[bool] = False
    # Its agents' observe and act touch nothing but their own state (as this interface asks),
    # so the runner may call them on several threads at once: the same results, sooner.
    threadsafe_agents: ClassVar[bool] = False
    # Its agents' steps cost enough (model passes) to pay for the messages of thinking in
    # processes of their own, one per agent, where the cores allow (eval/agent_processes.py);
    # a heuristic agent's does not (its episodes got slower).
    agent_processes: ClassVar[bool] = False
    # The name of its decision rules once they were changed on purpose after its first runs
    # ("": as first played). Runs record it, a run made under other rules is not resumed, and
    # the leaderboard marks a row whose rules are not today's (its records would not replay).
    rules: ClassVar[str] = ""

    @abstractmethod
    def make_agent(self, name: str, public: PublicInfo, outbox: Outbox) -> Agent:
        """A fresh agent for one episode."""

    @classmethod
    def missing_model(cls, team: tuple) -> str | None:
        """What is missing for this team of capabilities to play (a trained model's file, and
        the command that makes it), checked before a run writes anything; None: nothing."""
        return None

    def make_central(self, public: PublicInfo, outbox: Outbox) -> CentralNode | None:
        return None


class PrivilegedTeam(ABC):
    """A team that reads the simulator (the expert): one controller for all agents."""

    name: ClassVar[str]
    privileged: ClassVar[bool] = True
    needs_images: ClassVar[bool] = False
    observations: ClassVar[str] = "none"
    communication: ClassVar[str] = "none"
    central: ClassVar[bool] = False
    team_override: ClassVar[list | None] = None
    perception: ClassVar[str] = "privileged: reads the simulator's state"

    @abstractmethod
    def reset(self, public: PublicInfo, env: Any) -> None:
        """Start an episode; ``env`` is the unwrapped env."""

    @abstractmethod
    def act(self, info: dict) -> dict[str, AgentAction]:
        """One action per agent that has not stopped; ``info`` is the env's last info."""

    def labels(self) -> dict[str, Label]:
        """Per agent, the sub-task and sub-goal behind the last actions (empty if none)."""
        return {}


AnyTeam = Team | PrivilegedTeam
