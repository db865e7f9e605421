"""Navigation helpers, and what the heuristic teams put on the channel."""

from __future__ import annotations

import networkx as nx
import numpy as np

from maniskill_tidy.envs.actions import Action, AgentState
from maniskill_tidy.envs.episodes import default_dataset
from maniskill_tidy.policies.base import PublicInfo, SubTask
from maniskill_tidy.policies.channel import CENTRAL, Channel
from maniskill_tidy.policies.heuristic import (
    BroadcastTeam,
    CentralTeam,
    DetectionCommTeam,
    Known,
    NoCommTeam,
    camera_pitch,
)
from maniskill_tidy.policies.navigation import GridPlanner, move_towards, subgoal, turn_towards
from maniskill_tidy.tasks.dataset import load_dataset

TEAM = [(1, 0, 0), (1, 0, 1), (1, 1, 1)]


def _house():
    data = load_dataset(default_dataset(), "test")
    return next(iter(data.houses.values()))


def test_moves_and_turns_follow_the_heading():
    a = AgentState("a", (1, 1, 1), (5, 5), 0)  # facing +x: ahead is column + 1
    assert move_towards(a, (5, 6)) == Action.MoveAhead
    assert move_towards(a, (6, 5)) == Action.MoveLeft  # +y is to the left of +x
    assert move_towards(a, (4, 5)) == Action.MoveRight
    assert move_towards(a, (5, 4)) == Action.RotateRight  # behind: turn first
    assert turn_towards(a, 90, 0) == Action.RotateLeft
    assert turn_towards(a, 270, 0) == Action.RotateRight
    assert turn_towards(a, 0, 30) == Action.LookDown and turn_towards(a, 0, 0) is None
    path = [(5, 5), (5, 6), (5, 7), (6, 7), (7, 7), (8, 7), (9, 7), (10, 7)]
    g = subgoal(a, path, 90, "PickUp", False)
    assert (g.dx, g.dy) == (-4, 2)  # (10, 7) is 5 rows away: the sub-goal stops at (9, 7)
    assert g.ope == "NoAction" and g.drot == 0  # not there yet
    last = subgoal(a, [(5, 5), (5, 6)], 90, "PickUp", True)
    assert (last.dx, last.dy, last.drot, last.ope, last.stop) == (0, 1, 90, "PickUp", True)


def test_parking_never_cuts_the_free_space():
    house = _house()
    planner = GridPlanner(house)
    cut = set(nx.articulation_points(planner.graph))
    assert cut, "a house with rooms and doors has cells whose loss disconnects it"
    for source in sorted(cut)[:5]:
        cell = planner.parking(source, [], [])
        assert cell not in cut and cell in planner.graph


def test_camera_pitch_is_read_off_the_extrinsics():
    for pitch in (-30, 0, 30, 60):
        t = np.radians(pitch)
        forward = np.array([np.cos(t), 0.0, -np.sin(t)])  # looking along +x, tilted down
        right = np.array([0.0, -1.0, 0.0])
        down = np.cross(forward, right)
        extrinsics = np.eye(4)
        extrinsics[:3, :3] = np.stack([right, down, forward])
        assert camera_pitch(extrinsics) == pitch


def _team(cls):
    house = _house()
    team = cls()
    channel = Channel([f"agent_{i}" for i in range(3)], central=team.central)
    team.reset(PublicInfo(house, list(channel.agents), TEAM, "e", 0, {}), channel)
    agents = [
        AgentState(n, c, (3, 3 + i), 0)
        for i, (n, c) in enumerate(zip(channel.agents, TEAM, strict=True))
    ]
    for a in agents:
        team.jobs[a.name] = ("explore", "", None, SubTask("Explore"))
    return team, channel, agents


def test_broadcast_sends_state_map_and_detections_to_every_other_agent():
    team, channel, agents = _team(BroadcastTeam)
    team.memory["agent_0"].objects["Apple_0"] = Known("Apple_0", 7, "Apple", np.zeros(3), True)
    team.memory["agent_0"].objects["Bowl_0"] = Known("Bowl_0", 8, "Bowl", np.zeros(3), False)
    team._send(agents[0], ["agent_1", "agent_2"])
    kinds = {(m.receiver, m.kind): m.dims for m in channel.step_messages}
    assert kinds[("agent_1", "state")] == 10 and kinds[("agent_2", "map")] == 400
    assert kinds[("agent_1", "detections")] == 6  # one misplaced object known, not the bowl
    assert channel.total == 2 * (10 + 400 + 6)
    team._send(agents[1], ["agent_0", "agent_2"])  # nothing misplaced known: no detections
    assert channel.total == 2 * (10 + 400 + 6) + 2 * 410


def test_the_patterns_differ_in_what_they_send():
    assert NoCommTeam.communication == "none" and DetectionCommTeam.communication == "detection"
    team, channel, agents = _team(CentralTeam)
    assert CENTRAL in channel.endpoints
    team._central_node(agents)
    up = [m for m in channel.step_messages if m.receiver == CENTRAL]
    down = [m for m in channel.step_messages if m.sender == CENTRAL]
    assert {m.sender for m in up} == {"agent_0", "agent_1", "agent_2"}
    assert [m.receiver for m in down] == ["agent_2"]  # only the manipulator gets an assignment
    assert down[0].dims == 6
