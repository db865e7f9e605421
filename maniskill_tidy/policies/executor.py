"""The low-level action strategy under a learned sub-goal (paper Section 5.4, "Action Decision").

A sub-goal ``(dx, dy, drot, ope, stop)`` names a cell within 4 cells of the agent in its own
frame. The executor walks there by the shortest path on the public navigation grid (the
nearest reachable free cell if the cell itself is blocked), then turns by ``drot``, then
performs ``ope``, then stops if ``stop`` says so. One action per env step: the model predicts
a new sub-goal every step (``policies/learned.py``), so the executor only ever takes the first
action towards the current one.

Blocked moves are handled from the agent's own outcome: a move blocked by a robot it cannot
see marks that cell occupied for ``BLOCK_STEPS`` steps (paths go round it), and half the time
the agent steps aside, so that two robots facing each other in a corridor do not wait forever.
At the sub-goal with nothing to do, it sweeps its camera up and down (looking is what the
expert does there).
"""

from __future__ import annotations

import numpy as np

from maniskill_tidy.envs.actions import HORIZON_RANGE, LOOK, Action, AgentState, move_target
from maniskill_tidy.policies.base import SubGoal
from maniskill_tidy.policies.navigation import HEADING, Cell, GridPlanner, move_towards

BLOCK_STEPS = 3  # steps a cell where a robot blocked a move counts as occupied
MOVES = (Action.MoveAhead, Action.MoveLeft, Action.MoveRight)


def goal_cell(state: AgentState, goal: SubGoal) -> Cell:
    """The grid cell ``dx`` to the right and ``dy`` ahead of the agent."""
    fr, fc = HEADING[state.rotation]
    rr, rc = HEADING[(state.rotation - 90) % 360]
    row, col = state.cell
    return (row + goal.dy * fr + goal.dx * rr, col + goal.dy * fc + goal.dx * rc)


def relative(state: AgentState, cell: Cell, rotation: int, ope: str, stop: bool) -> SubGoal:
    """The sub-goal that names ``cell`` and ``rotation`` from where the agent stands now."""
    dr, dc = cell[0] - state.cell[0], cell[1] - state.cell[1]
    fr, fc = HEADING[state.rotation]
    rr, rc = HEADING[(state.rotation - 90) % 360]
    return SubGoal(
        dr * rr + dc * rc, dr * fr + dc * fc, (rotation - state.rotation) % 360, ope, stop
    )


class SubGoalExecutor:
    def __init__(self, planner: GridPlanner, rng: np.random.Generator) -> None:
        self.planner, self.rng = planner, rng
        self.blocked: dict[Cell, int] = {}  # cell -> last step it counts as occupied
        self.sidestep: Action | None = None
        self.sweep = 1  # direction of the camera sweep (+1 down)

    def failed(self, state: AgentState, reason: str, t: int) -> None:
        """The agent's own last action failed: remember a robot in the way."""
        if "blocked by agent" not in reason:
            return
        action = next(a for a in MOVES if reason.startswith(a.name))
        self.blocked[move_target(state, action)] = t + BLOCK_STEPS
        if self.rng.random() < 0.5:
            options = [a for a in (Action.MoveLeft, Action.MoveRight)
                       if self._free(move_target(state, a), t)]  # fmt: skip
            if options:
                self.sidestep = options[int(self.rng.integers(len(options)))]

    def _free(self, cell: Cell, t: int) -> bool:
        return self.planner.graph.has_node(cell) and self.blocked.get(cell, -1) < t

    def target(self, state: AgentState, goal: SubGoal, t: int) -> Cell:
        """The sub-goal's cell, or the reachable free cell nearest to it."""
        want = goal_cell(state, goal)
        if self._free(want, t) or want == state.cell:
            return want
        occupied = {c for c, until in self.blocked.items() if until >= t}
        return self.planner.nearest_reachable(state.cell, want, occupied)

    def move(self, state: AgentState, goal: SubGoal, t: int) -> Action | None:
        """The next navigation action towards the sub-goal; None once there and turned."""
        if self.sidestep is not None:
            action, self.sidestep = self.sidestep, None
            return action
        cell = self.target(state, goal, t)
        if cell != state.cell:
            occupied = {c for c, until in self.blocked.items() if until >= t}
            path = self.planner.path(state.cell, cell, occupied)
            if path and len(path) > 1:
                return move_towards(state, path[1])
            return self.look(state)
        if goal.drot:
            return Action.RotateLeft if goal.drot in (90, 180) else Action.RotateRight
        return None

    def look(self, state: AgentState) -> Action:
        """Sweep the camera between its bounds (a harmless action that also looks around)."""
        nxt = state.horizon + LOOK * self.sweep
        if not HORIZON_RANGE[0] <= nxt <= HORIZON_RANGE[1]:
            self.sweep = -self.sweep
        return Action.LookDown if self.sweep > 0 else Action.LookUp
