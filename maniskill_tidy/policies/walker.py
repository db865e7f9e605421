"""Going to a viewpoint: pick the best free cell, follow the shortest path, wait out other robots.

Shared by the expert and the heuristic teams, with the :class:`Job` both pursue (where to go,
what to do there), its sub-task / sub-goal label and the check of an operation's outcome;
which job to take is theirs to decide.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from maniskill_tidy.envs.actions import HORIZON_RANGE, NO_ROOM, STEP, Action, AgentState
from maniskill_tidy.policies.base import Label, SubTask
from maniskill_tidy.policies.navigation import (
    Cell,
    GridPlanner,
    move_towards,
    subgoal,
    turn_towards,
)
from maniskill_tidy.policies.viewpoints import Viewpoint

MAX_WAITS = 4  # steps to wait for a blocked path before trying another viewpoint
NEARNESS = 1.5  # a viewpoint a metre nearer the target is worth walking this many metres more


class NoViewpoint(RuntimeError):
    """Every candidate viewpoint was tried or cannot be reached."""


@dataclass
class Leg:
    candidates: list[Viewpoint]  # where the agent may stand, still untried
    goal: Viewpoint | None = None
    path: list[Cell] | None = None
    waits: int = 0
    tried: set[Cell] = field(default_factory=set)
    # Optional test of a viewpoint before walking there: the viewpoint to use (its camera
    # pitch may be changed) or None to skip it.
    check: Callable[[Viewpoint], Viewpoint | None] | None = None

    def give_up_goal(self) -> None:
        """The current viewpoint did not work (blocked, or the operation failed there)."""
        if self.goal is not None:
            self.tried.add(self.goal.cell)
        self.goal, self.path, self.waits = None, None, 0


class Walker:
    def __init__(self, planner: GridPlanner) -> None:
        self.planner = planner

    def step(
        self, agent: AgentState, leg: Leg, occupied: set[Cell], stopped: set[Cell]
    ) -> Action | None:
        """The next action towards ``leg``'s viewpoint, or None once there and facing it."""
        if leg.goal is None:
            self._choose(agent, leg, stopped)
        if agent.cell != leg.goal.cell:
            if leg.goal.cell in stopped:
                leg.give_up_goal()
                return self.step(agent, leg, occupied, stopped)
            if not leg.path or leg.path[0] != agent.cell or leg.path[1] in occupied:
                leg.path = self.planner.path(agent.cell, leg.goal.cell, occupied)
            if leg.path is None:
                leg.waits += 1
                if leg.waits > MAX_WAITS:
                    leg.give_up_goal()
                return wait_action(agent)
            action = move_towards(agent, leg.path[1])
            if action in (Action.MoveAhead, Action.MoveLeft, Action.MoveRight):
                leg.path = leg.path[1:]
            return action
        return turn_towards(agent, leg.goal.rotation, leg.goal.horizon)

    def _choose(self, agent: AgentState, leg: Leg, stopped: set[Cell]) -> None:
        dist = self.planner.distances(agent.cell, stopped)
        scored = sorted(
            (dist[vp.cell] * STEP + vp.distance * NEARNESS, i)
            for i, vp in enumerate(leg.candidates)
            if vp.cell not in leg.tried and vp.cell in dist
        )
        for _, i in scored:
            vp = leg.candidates[i]
            if leg.check is not None:
                vp = leg.check(vp)
                if vp is None:
                    leg.tried.add(leg.candidates[i].cell)
                    continue
            leg.goal, leg.path, leg.waits = vp, None, 0
            return
        raise NoViewpoint(f"{agent.name}: no untried viewpoint is reachable")


def wait_action(agent: AgentState) -> Action:
    """A harmless action that leaves the robot where it is (a camera tilt)."""
    return Action.LookDown if agent.horizon < HORIZON_RANGE[1] else Action.LookUp


OPERATION = {"pick": "PickUp", "place": "PutDown"}


@dataclass
class Job:
    """What an agent is doing: walking a leg to ``target`` and then operating there.

    ``kind`` is "pick" (target: an object id), "place" (a "furniture/surface"), "look" (at an
    object, or where one was reported), "inspect" (look at a "furniture/surface"), "explore"
    (walk there and look) or "park" (walk there and stop)."""

    kind: str
    target: str
    leg: Leg
    subtask: SubTask
    issued: bool = False  # the operation was sent last step; its outcome is due

    def label(self, agent: AgentState) -> Label:
        """The paper's (sub-task, sub-goal) for this step: the next waypoint of the path."""
        leg = self.leg
        goal = leg.goal or leg.candidates[0]  # None after giving up on a blocked goal
        path = list(leg.path) if leg.path else [agent.cell, goal.cell]
        if path[0] != agent.cell:  # the walker already stepped past this cell
            path = [agent.cell, *path]
        if agent.cell == goal.cell:
            path = [agent.cell]
        ope = OPERATION.get(self.kind, "NoAction")
        return self.subtask, subgoal(agent, path, goal.rotation, ope, self.kind == "park")

    def found_no_room(self, failed: str) -> bool:
        """Whether the PutDown issued last step was refused for want of room: the env searched
        the whole surface (``free_spot``), so no other viewpoint of it can help."""
        return self.kind == "place" and failed.startswith(NO_ROOM)

    def succeeded(self, agent: AgentState) -> bool:
        """Whether the operation issued last step worked; if not, the next viewpoint is tried."""
        self.issued = False
        if self.kind == "pick" and agent.held == self.target:
            return True
        if self.kind == "place" and agent.held is None:
            return True
        self.leg.give_up_goal()
        return False
