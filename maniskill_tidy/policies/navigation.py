"""Shortest paths on the 0.25 m navigation grid and the discrete actions that follow them.

The grid graph comes from networkx (4-connected free cells, as the env moves robots). Paths are
planned around the cells other robots stand on; a planner is built once per house. Move counts
to every cell (what agents ask most, several times a step) come from scipy's Dijkstra over the
graph's adjacency matrix, the edges into the cells robots stand on costing infinity: the counts
are networkx's (a test compares them) at a tenth of its cost, with no subgraph view per
call. Paths stay networkx's: which of several shortest paths it returns is part of every
record.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping

import networkx as nx
import numpy as np
from scipy.sparse.csgraph import dijkstra

from maniskill_tidy.envs.actions import HORIZON_RANGE, LOOK, Action, AgentState
from maniskill_tidy.houses.navgrid import grid_array
from maniskill_tidy.houses.schema import House
from maniskill_tidy.policies.base import SubGoal

Cell = tuple[int, int]
HEADING = {0: (0, 1), 90: (1, 0), 180: (0, -1), 270: (-1, 0)}  # rotation -> (d_row, d_col)
SUBGOAL_RANGE = 4  # cells, the paper's -4..4


class GridPlanner:
    def __init__(self, house: House) -> None:
        free = grid_array(house.navgrid)
        rows, cols = free.shape
        graph = nx.grid_2d_graph(rows, cols)
        graph.remove_nodes_from([(int(r), int(c)) for r, c in zip(*np.nonzero(~free), strict=True)])
        self.graph = graph
        self.house = house
        self.free = free
        self._cells = np.argwhere(free)  # the free cells, row-major: the graph's node order
        self._node = np.full(free.shape, -1, dtype=np.int64)
        self._node[free] = np.arange(len(self._cells))
        nodes = list(map(tuple, self._cells.tolist()))
        self._moves = nx.to_scipy_sparse_array(graph, nodelist=nodes, format="csr", dtype=float)

    def distances(self, source: Cell, blocked: Iterable[Cell] = ()) -> Distances:
        """Path length in moves from ``source`` to every reachable free cell, avoiding
        ``blocked`` (networkx's ``single_source_shortest_path_length`` on the grid graph)."""
        if not self._inside(source) or not self.free[source]:
            raise nx.NodeNotFound(f"Source {source} is not a free cell of the grid")
        weights = self._moves  # one move per edge
        into = [self._node[c] for c in blocked if c != source and self._inside(c)]  # -1: a wall
        if into:  # the edges into a robot's cell cost infinity: never settled through
            weights = weights.copy()
            weights.data[np.isin(weights.indices, into)] = np.inf
        moves = dijkstra(weights, indices=self._node[source])
        moves[np.isinf(moves)] = -1
        grid = np.full(self.free.shape, -1, dtype=np.int64)
        grid[self.free] = moves
        return Distances(grid)

    def _inside(self, cell: Cell) -> bool:
        return 0 <= cell[0] < self.free.shape[0] and 0 <= cell[1] < self.free.shape[1]

    def nearest_reachable(self, source: Cell, point: Cell, blocked: Iterable[Cell] = ()) -> Cell:
        """The cell reachable from ``source`` (avoiding ``blocked``) nearest to ``point``, ties
        to the one fewer moves away, then the smaller cell: the minimum over :meth:`distances`
        of (distance to ``point``, moves, cell), found by visiting cells outwards from ``point``
        (the point is a few cells from the source; the house is thousands)."""
        reach = self.distances(source, blocked)
        squared = ((self._cells - np.asarray(point)) ** 2).sum(axis=1)
        order = np.argsort(squared, kind="stable")
        bounds = (np.flatnonzero(np.diff(squared[order])) + 1).tolist()
        # the cells at one distance from the point, ring by ring (np.split would cut them all
        # up front, a thousand arrays for the first few rings that are read)
        for lo, hi in zip([0, *bounds], [*bounds, len(order)], strict=True):
            ring = order[lo:hi]
            moves = {c: reach[c] for c in map(tuple, self._cells[ring].tolist()) if c in reach}
            if moves:
                return min(moves, key=lambda c: (np.hypot(c[0] - point[0], c[1] - point[1]),
                                                 moves[c], c))  # fmt: skip
        return source

    def path(self, source: Cell, goal: Cell, blocked: Iterable[Cell] = ()) -> list[Cell] | None:
        """Cells from ``source`` to ``goal`` (both included), avoiding ``blocked``; None if cut."""
        view = self._view(blocked, source)
        if goal not in view:
            return None
        try:
            return nx.shortest_path(view, source, goal)
        except nx.NetworkXNoPath:
            return None

    def parking(self, source: Cell, stopped: Iterable[Cell], occupied: Iterable[Cell]) -> Cell:
        """The nearest cell where a robot can stop for good without cutting the free space."""
        stopped, occupied = set(stopped), set(occupied)
        rest = self.graph.subgraph(n for n in self.graph if n not in stopped)
        cut = set(nx.articulation_points(rest))
        reach = self.distances(source, occupied)
        for cell, _ in sorted(reach.items(), key=lambda kv: (kv[1], kv[0])):
            if cell not in cut and cell not in stopped:
                return cell
        return source

    def _view(self, blocked: Iterable[Cell], source: Cell) -> nx.Graph:
        blocked = set(blocked) - {source}
        if not blocked:
            return self.graph
        return nx.subgraph_view(self.graph, filter_node=lambda n: n not in blocked)


class Distances(Mapping[Cell, int]):
    """Moves from a source to every reachable cell, read as networkx's dict is (cell -> moves),
    held as a grid of counts (-1: unreachable)."""

    def __init__(self, moves: np.ndarray) -> None:
        self.moves = moves

    def __getitem__(self, cell: Cell) -> int:
        r, c = cell
        if 0 <= r < self.moves.shape[0] and 0 <= c < self.moves.shape[1] and self.moves[r, c] >= 0:
            return int(self.moves[r, c])
        raise KeyError(cell)

    def __contains__(self, cell: object) -> bool:
        try:
            self[cell]  # type: ignore[index]
        except (KeyError, TypeError, ValueError):
            return False
        return True

    def __iter__(self) -> Iterator[Cell]:
        rows, cols = np.nonzero(self.moves >= 0)
        return zip(rows.tolist(), cols.tolist(), strict=True)

    def __len__(self) -> int:
        return int((self.moves >= 0).sum())

    def items(self) -> list[tuple[Cell, int]]:  # one pass over the array, not a lookup per cell
        rows, cols = np.nonzero(self.moves >= 0)
        cells = zip(rows.tolist(), cols.tolist(), strict=True)
        return list(zip(cells, self.moves[rows, cols].tolist(), strict=True))


def move_towards(agent: AgentState, nxt: Cell) -> Action:
    """The action that brings an agent one cell closer to the neighbouring cell ``nxt``."""
    d = (nxt[0] - agent.cell[0], nxt[1] - agent.cell[1])
    if d == HEADING[agent.rotation]:
        return Action.MoveAhead
    if d == HEADING[(agent.rotation + 90) % 360]:
        return Action.MoveLeft
    if d == HEADING[(agent.rotation - 90) % 360]:
        return Action.MoveRight
    return Action.RotateRight  # it lies behind: after a turn it is to one side


def turn_towards(agent: AgentState, rotation: int, horizon: int | None) -> Action | None:
    """The action that turns the base (first) and tilts the camera towards a view; None if there."""
    diff = (rotation - agent.rotation) % 360
    if diff:
        return Action.RotateLeft if diff == 90 else Action.RotateRight
    if horizon is not None:
        horizon = int(np.clip(horizon, *HORIZON_RANGE))
        if horizon > agent.horizon:
            return Action.LookDown
        if horizon < agent.horizon:
            return Action.LookUp
    return None


def subgoal(
    agent: AgentState, path: list[Cell] | None, rotation: int, ope: str, stop: bool
) -> SubGoal:
    """The paper's sub-goal: the furthest cell of ``path`` within 4 cells, in the agent's frame."""
    path = path or [agent.cell]
    far = path[-1]
    for cell in path:
        if max(abs(cell[0] - agent.cell[0]), abs(cell[1] - agent.cell[1])) > SUBGOAL_RANGE:
            break
        far = cell
    reached = far == path[-1]
    dr, dc = far[0] - agent.cell[0], far[1] - agent.cell[1]
    fr, fc = HEADING[agent.rotation]  # ahead
    rr, rc = HEADING[(agent.rotation - 90) % 360]  # right
    dy, dx = dr * fr + dc * fc, dr * rr + dc * rc
    drot = (rotation - agent.rotation) % 360 if reached else 0
    return SubGoal(int(dx), int(dy), int(drot), ope if reached else "NoAction", stop and reached)


def look_horizon(camera_height: float, distance: float, height: float) -> int:
    """The camera pitch (multiple of 30 degrees) that looks at a point ``distance`` ahead."""
    pitch = np.degrees(np.arctan2(camera_height - height, max(distance, 0.05)))
    return int(np.clip(round(pitch / LOOK) * LOOK, *HORIZON_RANGE))
