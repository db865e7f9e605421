"""The paper's discrete actions and what each one does.

Indices follow the paper's order; a navigation-only agent's action space is ``Discrete(8)``
(``MoveAhead`` .. ``Stop``), a manipulator's ``Discrete(11)``.

Rules, applied to the agents one after the other in team order within a step:

- ``MoveAhead`` / ``MoveRight`` / ``MoveLeft`` move the base one 0.25 m grid cell forward, right
  or left of its heading, without turning. The move happens only if the target cell is free on
  the house's navigation grid (a disc of radius 0.2 m fits there, clear of walls and furniture)
  and no other robot stands on it (robots earlier in the team order have already moved this
  step). A blocked move leaves the robot where it is and is reported as failed with the reason.
- ``RotateRight`` / ``RotateLeft`` turn the base by 90 degrees (right = clockwise).
- ``LookUp`` / ``LookDown`` tilt the camera by 30 degrees within [-30, 60] degrees
  (positive looks down, as AI2-THOR's horizon); beyond the bound the action fails.
- ``Stop`` ends the agent's episode: later actions of a stopped agent are ignored (not counted
  as steps) and its robot stays where it is. The episode ends when every agent has stopped.
- ``PickUp`` takes one object into the empty gripper. Candidates are objects that cover at
  least ``MIN_PIXELS`` pixels of the agent's current instance segmentation and whose centre is
  within ``REACH`` (1.5 m, horizontally) of the robot's centre; the one covering most pixels is
  taken. A target can be named instead (``Targeted(Action.PickUp, "Apple_0")``); it must pass
  the same visibility and reach tests.
- ``PutDown`` places the held object on or in a receptacle surface. Candidates are the surfaces
  of furniture (or of its door or drawer link) visible with ``MIN_PIXELS`` pixels, whose centre
  lies within reach and projects into the image; they are tried in order of how close that
  projection is to the image centre (what the camera looks at), and the first one with room for
  the object gets it, at the free spot nearest to the robot. A surface can be named
  (``Targeted(Action.PutDown, "CounterTop_2/top")``, or just the furniture id). The object is
  then released and physics settles it; if it sinks (the pose was not stable) the action is
  reported as failed and the object stays where physics left it.
- ``Drop`` releases the held object where the gripper holds it; physics lets it fall, and it then
  counts as lying wherever it came to rest (a surface, or the floor).

- A target can also be a pixel of the agent's current frame, ``Targeted(Action.PickUp, (x, y))``
  (column x, row y, as AI2-THOR's): the object, or for PutDown the piece of furniture (or its
  door or drawer), drawn there is the target, then the same tests apply; PutDown tries that
  piece's surfaces whose centre projects nearest the pixel first. An env made with
  ``targets="pixels"`` (the pixels track, where no agent knows an instance id) takes only pixel
  targets and refuses id targets.

Every failure is named in ``info["failed"][agent]``; a failed action still costs a step.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np

from maniskill_tidy.houses.navgrid import ARM_REACH


class Action(IntEnum):
    MoveAhead = 0
    MoveRight = 1
    MoveLeft = 2
    RotateRight = 3
    RotateLeft = 4
    LookUp = 5
    LookDown = 6
    Stop = 7
    PickUp = 8
    PutDown = 9
    Drop = 10


NAVIGATION_ACTIONS = 8  # MoveAhead .. Stop
MANIPULATION_ACTIONS = 11  # .. PickUp, PutDown, Drop
STEP = 0.25  # metres per move
TURN = 90  # degrees per rotation
LOOK = 30  # degrees per look step
HORIZON_RANGE = (-30, 60)
REACH = ARM_REACH  # metres, horizontal, from the robot's centre (1.5)
MIN_PIXELS = 20  # an instance covering fewer pixels than this is not "visible"
# how a pixel target's failure ends when the pixel shows no object (or furniture) at all
NOTHING_DRAWN = "drawn there"
NO_ROOM = "no room for"  # how a PutDown the whole surface had no room for fails (agents read it)
MAX_STEPS = 300


Pixel = tuple[int, int]  # (x, y): column and row of the agent's current frame
TARGETS = ("ids", "pixels")  # what an env's Targeted actions may name


@dataclass(frozen=True)
class Targeted:
    """An action with a target: an object id, a furniture id or "furniture/surface", or a
    pixel (x, y) of the agent's current frame."""

    action: int
    target: str | Pixel


@dataclass
class AgentState:
    name: str
    capability: tuple[int, int, int]
    cell: tuple[int, int]  # (row, col) on the navigation grid
    rotation: int  # degrees counter-clockwise from +x: 0, 90, 180, 270
    horizon: int = 0  # camera pitch in degrees, positive looks down
    held: str | None = None
    stopped: bool = False
    steps: int = 0
    failures: list[str] = field(default_factory=list)

    @property
    def manipulator(self) -> bool:
        return bool(self.capability[1])

    @property
    def n_actions(self) -> int:
        return MANIPULATION_ACTIONS if self.manipulator else NAVIGATION_ACTIONS


_HEADING = {0: (0, 1), 90: (1, 0), 180: (0, -1), 270: (-1, 0)}  # rotation -> (d_row, d_col)


def move_target(state: AgentState, action: Action) -> tuple[int, int]:
    """The cell a move action aims at."""
    offset = {Action.MoveAhead: 0, Action.MoveLeft: 90, Action.MoveRight: -90}[action]
    dr, dc = _HEADING[(state.rotation + offset) % 360]
    return state.cell[0] + dr, state.cell[1] + dc


def parse_action(
    value, n_actions: int, agent: str, targets: str = "ids"
) -> tuple[Action, str | Pixel | None]:
    """An int (Python, NumPy or an :class:`Action`) or a :class:`Targeted`, checked against the
    agent's space. Floats, strings and booleans are refused, not converted. ``targets``: what a
    target may name (``"pixels"``: only a pixel)."""
    target = None
    if isinstance(value, Targeted):
        value, target = value.action, value.target
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(
            f"action for {agent} is {value!r} ({type(value).__name__}); expected an integer "
            f"action index in [0, {n_actions}) or a Targeted(action, target)"
        )
    index = int(value)
    if n_actions == NAVIGATION_ACTIONS and NAVIGATION_ACTIONS <= index < MANIPULATION_ACTIONS:
        raise ValueError(
            f"{agent} cannot manipulate (Mani = 0): {Action(index).name} needs a manipulator; "
            f"its actions are 0..{NAVIGATION_ACTIONS - 1} (MoveAhead..Stop)"
        )
    if not 0 <= index < n_actions:
        names = ", ".join(f"{a.value}={a.name}" for a in list(Action)[:n_actions])
        raise ValueError(f"action {index} for {agent} is out of range; its actions are {names}")
    action = Action(index)
    if target is not None and action not in (Action.PickUp, Action.PutDown):
        raise ValueError(f"{agent}: only PickUp and PutDown take a target, not {action.name}")
    if target is None:
        return action, None
    if isinstance(target, tuple):
        if len(target) != 2 or not all(
            isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_)) for v in target
        ):
            raise TypeError(f"{agent}: a pixel target is (x, y), two integers; got {target!r}")
        return action, (int(target[0]), int(target[1]))
    if not isinstance(target, str):
        raise TypeError(f"{agent}: a target is an id string or a pixel (x, y), got {target!r}")
    if targets == "pixels":
        raise ValueError(f"{agent}: {action.name} names {target!r}, an id; this env takes pixel "
                         "targets only (the pixels track): Targeted(action, (x, y))")  # fmt: skip
    return action, target
