"""Navigation helpers, and the messages camera-only teams put on the channel."""

from __future__ import annotations

from functools import partial
from types import SimpleNamespace

import networkx as nx
import numpy as np
import pytest

from maniskill_tidy.envs.actions import Action, AgentState
from maniskill_tidy.envs.episodes import default_dataset
from maniskill_tidy.perception.frame_inputs import camera_pitch
from maniskill_tidy.perception.semantic_map import SemanticMap
from maniskill_tidy.policies.base import SubTask
from maniskill_tidy.policies.heuristic_jobs import JobChoice
from maniskill_tidy.policies.messages import (
    FETCH,
    STATE_DIMS,
    decode_assignment,
    decode_crop,
    decode_state,
    encode_assignment,
    encode_crop,
    encode_state,
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


def test_move_counts_are_networkxs_breadth_first_search():
    """The compiled search gives networkx's move counts on the grid graph, cell for cell, with
    robots in the way (the source itself never blocked) and cells off the grid ignored."""
    planner = GridPlanner(_house())
    rng = np.random.default_rng(1)
    cells = sorted(planner.graph)
    for _ in range(100):
        source = cells[rng.integers(len(cells))]
        blocked = {cells[i] for i in rng.integers(len(cells), size=rng.integers(0, 40))}
        blocked |= {source, (-1, 0), (0, 10_000)}
        view = nx.subgraph_view(
            planner.graph, filter_node=lambda n, b=blocked - {source}: n not in b
        )
        want = nx.single_source_shortest_path_length(view, source)
        got = planner.distances(source, blocked)
        assert dict(got.items()) == want and len(got) == len(want)
        assert set(got) == set(want) and all(got[c] == want[c] for c in want)
        assert (-1, 0) not in got and not any(c in got for c in blocked - {source})
    with pytest.raises(nx.NodeNotFound):
        planner.distances((-1, -1))


def test_the_search_target_is_the_loop_minimum_over_reachable_cells():
    """A heuristic agent's next search cell, computed over the grid at once, is the minimum
    of (moves + 8 x teammates within 5 cells, cell) over the reachable cells it has not
    searched and does not avoid, as a loop over the move counts finds it."""
    planner = GridPlanner(_house())
    rng = np.random.default_rng(2)
    cells = sorted(planner.graph)
    for _ in range(100):
        pick = lambda k: [cells[i] for i in rng.integers(len(cells), size=k)]  # noqa: E731
        agent = SimpleNamespace(
            planner=planner, name="agent_0", assignment=None,
            state=SimpleNamespace(cell=pick(1)[0]),
            parked={f"p{i}": c for i, c in enumerate(pick(rng.integers(0, 3)))},
            teammates={f"agent_{i}": (c, 0) for i, c in enumerate(pick(3))},
            covered=rng.random(planner.free.shape) < rng.random(),
        )  # fmt: skip
        agent._unsearched = partial(JobChoice._unsearched, agent)
        avoid = set(pick(rng.integers(0, 10)))
        dist = planner.distances(agent.state.cell, set(agent.parked.values()))
        others = [c for n, (c, _) in agent.teammates.items() if n != agent.name]
        scores = [
            (d + 8 * sum(abs(o[0] - c[0]) + abs(o[1] - c[1]) < 6 for o in others), c)
            for c, d in dist.items()
            if not agent.covered[c] and c not in avoid
        ]
        want = min(scores)[1] if scores else None
        assert JobChoice._search_target(agent, avoid) == want
        rows, cols, order = agent._unsearched(avoid, dist)  # the whole order (explore candidates)
        assert [(int(rows[i]), int(cols[i])) for i in order] == [c for _, c in sorted(scores)]


def test_the_nearest_reachable_cell_is_the_minimum_over_the_whole_search():
    """Searching outwards from the point gives what the whole breadth-first search from the
    source did (the executor's rule: nearest to the point, then fewer moves, then the smaller
    cell), with robots in the way, points off the grid and walls between."""
    planner = GridPlanner(_house())
    rng = np.random.default_rng(0)
    cells = sorted(planner.graph)
    rows, cols = max(r for r, _ in cells), max(c for _, c in cells)
    for _ in range(300):
        source = cells[rng.integers(len(cells))]
        point = (int(source[0] + rng.integers(-6, 7)), int(source[1] + rng.integers(-6, 7)))
        if rng.random() < 0.1:
            point = (int(rng.integers(-3, rows + 3)), int(rng.integers(-3, cols + 3)))
        near = [c for c in cells if abs(c[0] - source[0]) + abs(c[1] - source[1]) <= 3]
        blocked = {near[i] for i in rng.integers(len(near), size=rng.integers(0, 8))}
        reach = planner.distances(source, blocked)
        want = min(reach, key=lambda c: (np.hypot(c[0] - point[0], c[1] - point[1]), reach[c], c))
        assert planner.nearest_reachable(source, point, blocked) == want, (source, point, blocked)


def test_camera_pitch_is_read_off_the_extrinsics():
    for pitch in (-30, 0, 30, 60):
        t = np.radians(pitch)
        forward = np.array([np.cos(t), 0.0, -np.sin(t)])  # looking along +x, tilted down
        right = np.array([0.0, -1.0, 0.0])
        down = np.cross(forward, right)
        extrinsics = np.eye(4)
        extrinsics[:3, :3] = np.stack([right, down, forward])
        assert camera_pitch(extrinsics) == pitch


def test_state_messages_round_trip_in_ten_values():
    subtask = SubTask("Place", "Apple", "CounterTop", "Kitchen")
    v = encode_state((1, 1, 1), (2.5, -1.25, 270), subtask)
    assert v.shape == (STATE_DIMS,) == (10,)
    st = decode_state(v)
    assert st.capability == (1, 1, 1) and st.pose == (2.5, -1.25, 270)
    assert st.subtask == subtask and not st.parking
    assert decode_state(encode_state((1, 0, 0), (0, 0, 0), SubTask("Park"))).parking
    with pytest.raises(ValueError, match="10 values"):
        decode_state(np.zeros(9, np.float32))


@pytest.mark.parametrize("rotation", [0, 90, 180, 270])
def test_a_map_crop_is_400_values_and_lands_where_the_sender_saw_it(rotation):
    house = _house()
    m = SemanticMap(house, {})
    nav = house.navgrid
    middle = np.array(nav.shape) / 2
    cell = min(
        ((r, c) for r in range(nav.shape[0]) for c in range(nav.shape[1]) if nav.free(r, c)),
        key=lambda rc: float(np.hypot(*(np.array(rc) - middle))),
    )
    x, y = nav.center(*cell)
    pose = (x, y, rotation)
    apple = np.array([x + 1.1, y - 0.6, 0.3])  # 1.1 m east, 0.6 m south of the sender
    crop = encode_crop(m, pose, [("Apple", apple)])
    assert crop.shape == (400,) and (crop < 0).sum() == 1
    cells = decode_crop(crop, pose, nav)
    ((kind, xy),) = cells.misplaced
    assert kind == "Apple" and np.hypot(xy[0] - apple[0], xy[1] - apple[1]) < 0.25
    assert len(cells.explored[0]) == 1  # the apple's cell; nothing else was seen
    assert (cells.explored[0][0], cells.explored[1][0]) == nav.cell_of(*xy)


def test_crop_cell_centres_are_the_meshgrids():
    """The crop's cell centres, against the numpy meshgrid arithmetic they replaced, bit for
    bit (where a message's misplaced objects and explored cells land)."""
    import math

    from maniskill_tidy.policies.messages import crop_cell_centres

    rng = np.random.default_rng(4)
    for _ in range(50):
        x, y = rng.uniform(-20, 20, 2)
        rotation = int(rng.choice([0, 90, 180, 270, 45, 135, 30]))
        yaw = math.radians(rotation)
        fwd = np.array([math.cos(yaw), math.sin(yaw)])
        right = np.array([math.sin(yaw), -math.cos(yaw)])
        offsets = (np.arange(20) + 0.5 - 20 / 2) * 0.25
        ahead, side = np.meshgrid(-offsets, offsets, indexing="ij")
        want = np.array([x, y]) + ahead[..., None] * fwd + side[..., None] * right
        got = crop_cell_centres((x, y, rotation), 20, 0.25)
        assert got.tobytes() == want.tobytes()


def test_assignments_are_six_values():
    v = encode_assignment(FETCH, "Apple", (1.0, 2.0, 0.5))
    assert v.shape == (6,)
    kind, object_type, xyz = decode_assignment(v)
    assert kind == FETCH and object_type == "Apple" and list(xyz) == [1.0, 2.0, 0.5]


def test_the_cells_seen_close_up_are_those_numpy_marked():
    """The heuristic agents' searched cells (points within COVER_RANGE of the camera) from
    the kernel, against the numpy reading it replaced, bit for bit: float32 points, some on
    the range's and the cells' borders, some off the grid."""
    from types import SimpleNamespace

    from maniskill_tidy.perception.map_kernels import mark_near_cells
    from maniskill_tidy.policies.heuristic import COVER_RANGE

    # an origin float32 cannot hold, so that the cells' arithmetic precision matters
    nav = SimpleNamespace(origin=(-3.1, 2.7), cell=0.25, shape=(24, 32))
    rng = np.random.default_rng(1)
    size = np.array(nav.shape[::-1]) * nav.cell
    for _ in range(20):
        camera = np.array([*(nav.origin + rng.uniform(0, 1, 2) * size), 1.0])
        points = np.concatenate(
            [
                camera[:2] + rng.normal(0, 1.5, (4000, 2)),
                camera[:2]
                + COVER_RANGE * np.stack([np.cos(a := rng.uniform(0, 7, 200)), np.sin(a)], 1),
                nav.origin + rng.integers(-2, 40, (200, 2)) * nav.cell,  # cell borders
            ]
        ).astype(np.float32)
        # and the float32 neighbours of cell borders near the camera, where float32 and
        # float64 arithmetic part
        near_cell = np.floor((camera[:2] - nav.origin) / nav.cell)
        steps = np.stack(np.meshgrid(np.arange(-6, 7), np.arange(-6, 7)), -1).reshape(-1, 2)
        borders = (nav.origin + (near_cell + steps) * nav.cell).astype(np.float32)
        points = np.concatenate([points, *(np.nextafter(borders, borders + d) for d in (-1, 0, 1))])
        points = np.column_stack([points, rng.uniform(0, 2, len(points))]).astype(np.float32)
        want = np.zeros(tuple(nav.shape), dtype=bool)
        near = points[np.hypot(*(points[:, :2] - camera[:2]).T) < COVER_RANGE][:, :2]
        rows = np.floor((near[:, 1] - nav.origin[1]) / nav.cell).astype(np.int64)
        cols = np.floor((near[:, 0] - nav.origin[0]) / nav.cell).astype(np.int64)
        on = (rows >= 0) & (rows < want.shape[0]) & (cols >= 0) & (cols < want.shape[1])
        want[rows[on], cols[on]] = True
        got = np.zeros_like(want)
        origin = np.asarray(nav.origin, np.float32)
        mark_near_cells(points, camera, COVER_RANGE, origin, np.float32(nav.cell), got)
        assert np.array_equal(got, want) and 0 < got.sum() < got.size
    # one point at a time on the range's border, where the kernel's shortcuts (the square and
    # the diamond around the camera) must give way to np.hypot: near the axes and diagonals
    camera = np.array([0.3, 0.4, 1.0])
    angles = np.arange(8)[:, None] * np.pi / 4 + np.array([0, 1e-4, -1e-3, 0.05])
    radii = COVER_RANGE * (1 + np.array([-1e-4, -1e-7, 0, 1e-7, 1e-4]))
    grid = SimpleNamespace(origin=np.float32([-5, -5]), cell=np.float32(0.25), shape=(40, 40))
    for angle in angles.ravel():
        for radius in radii:
            point = camera[:2] + radius * np.array([np.cos(angle), np.sin(angle)])
            point = np.float32([[*point, 0.5]])
            got = np.zeros(grid.shape, dtype=bool)
            mark_near_cells(point, camera, COVER_RANGE, grid.origin, grid.cell, got)
            assert got.any() == (np.hypot(*(point[0, :2] - camera[:2])) < COVER_RANGE)
