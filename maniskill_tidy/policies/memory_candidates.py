"""What an agent with object memory could do next, as rows a model can score.

A mixin of :class:`~maniskill_tidy.policies.memory.MemoryAgent`, which keeps the heuristic
agent's memory (``policies/heuristic.py``: the objects it detected, its teammates' reports, the
cells it searched, the teammates it knows of). When the agent needs a new job, every job it
could take is a :class:`Candidate`:

- ``fetch`` a misplaced object it detected (the ``MAX_FETCH`` nearest, those a nearer teammate
  manipulator is after included and marked);
- ``look`` where a teammate reported a misplaced object (the ``MAX_LOOK`` nearest);
- ``place`` what it holds on a surface of the floor plan where D holds (the ``MAX_PLACE``
  nearest);
- ``explore``: walk to the nearest cell it has not searched (the heuristic's choice of cell)
  and, with ``MemoryConfig.explore`` above 1, to the first such cell in the heuristic's order of
  up to that many less one other rooms: where to search next becomes the pointer's choice;
- ``inspect`` a surface its camera sees into or onto (the heuristic's choice of surface);
- ``park``: stop for good.

Each candidate becomes one row (:meth:`MemoryCandidates._rows`): its kind, the object type it
concerns, the receptacle type of a ``place``, and the numbers of ``NUMERIC`` (and of
``ROOM_NUMERIC`` when the agent has explore candidates in other rooms); the agent's own
situation is the ``CONTEXT`` row. The same rows are what the teacher's choice is recorded against
(:func:`teacher_slot`) and what the trained pointer (``models/memory_pointer.py``) scores.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from maniskill_tidy.houses.navgrid import room_index
from maniskill_tidy.knowledge import load_catalog
from maniskill_tidy.policies.heuristic_jobs import TEAMMATE_STEPS, Report
from maniskill_tidy.policies.navigation import Cell, Distances
from maniskill_tidy.policies.walker import Job

KINDS = ("fetch", "look", "place", "explore", "inspect", "park")
MAX_FETCH, MAX_LOOK, MAX_PLACE = 8, 4, 6
SLOTS = MAX_FETCH + MAX_LOOK + MAX_PLACE + 3  # one explore, one inspect, one park
NUMERIC = (
    "metres",  # straight distance from the agent / 10 m
    "moves",  # grid moves to the nearest reachable cell within 2 cells of it / 40
    "unreachable",  # no reachable cell within 2 cells of it
    "rank",  # its place among the candidates of its kind (nearest first; explore: the
    # heuristic's order) / 8
    "beyond_nearest",  # metres beyond the first candidate of its kind / 10
    "claimed",  # a nearer teammate manipulator said it goes for an object of this type
    "teammates_nearer",  # teammates it knows of (not stopped) nearer to it / 3
    "crowd",  # teammates it knows of within 5 cells of it / 3
    "height",  # metres above the floor
)
ROOM_NUMERIC = (  # appended to NUMERIC when MemoryConfig.explore > 1
    "room_unsearched",  # the share of the reachable cells of its room the agent has not searched
    "room_cells",  # the reachable cells of its room / 100
)
CONTEXT = (
    "navigation", "manipulation", "high_camera",  # the agent's capability vector
    "holding", "time",  # step / 300
    "searched",  # the share of the reachable cells it has searched
    "misplaced_known", "reports",  # / MAX_FETCH, / MAX_LOOK
    "teammates_recent", "teammates_stopped",  # / 3
)  # fmt: skip
NEAR_CELLS = 2  # an object on furniture is reached from a free cell this close to it


@dataclass
class Candidate:
    kind: str  # one of KINDS
    what: Any  # Known | Report | PlaceOption | Cell | InspectOption | None (park)
    object_type: str = ""
    receptacle_type: str = ""
    position: np.ndarray | None = None  # (x, y, z); None for park


@dataclass
class Rows:
    """One decision's candidates, padded to ``slots(explore)`` (kind -1: no candidate)."""

    kind: np.ndarray  # (slots,) int8
    type: np.ndarray  # (slots,) int16; len(categories): none
    rest: np.ndarray  # (slots,) int16; len(receptacles): none
    numeric: np.ndarray  # (slots, numeric_width) float32
    context: np.ndarray  # (len(CONTEXT),) float32


def slots(explore: int) -> int:
    """Candidate rows per decision with ``explore`` explore candidates."""
    return SLOTS - 1 + explore


def numeric_width(explore: int) -> int:
    """Numbers per candidate row with ``explore`` explore candidates."""
    return len(NUMERIC) + (len(ROOM_NUMERIC) if explore > 1 else 0)


class MemoryCandidates:
    explore = 1  # explore candidates per decision (MemoryConfig.explore)
    _room_index: np.ndarray | None = None

    def _candidates(self, avoid: set[Cell], dist: Distances) -> list[Candidate]:
        """Every job the agent could take now (see the top), in a fixed order."""
        s = self.state
        out: list[Candidate] = []
        if self.manipulator and s.held is not None:
            for o in self._place_options()[:MAX_PLACE]:
                out.append(Candidate("place", o, o.object_type, o.receptacle_type, o.centre))
        elif self.manipulator:
            known = [
                k for k in self.objects.values() if k.misplaced and k.object_id not in self.done
            ]
            for k in sorted(known, key=lambda k: (self._metres(k.position), k.object_id))[
                :MAX_FETCH
            ]:
                out.append(Candidate("fetch", k, k.type, "", np.asarray(k.position, float)))
            reports = sorted(self.reports, key=lambda r: (self._metres(r.xy), r.type))
            for r in reports[:MAX_LOOK]:
                out.append(Candidate("look", r, r.type, "", np.array([*r.xy, 0.4])))
        for cell in self._explore_cells(avoid, dist):
            xy = self.house.navgrid.center(*cell)
            out.append(Candidate("explore", cell, position=np.array([xy[0], xy[1], 0.0])))
        inspect = self._inspect_options()
        if inspect:
            out.append(Candidate("inspect", inspect[0], position=inspect[0].centre))
        out.append(Candidate("park", None))
        return out

    def _explore_cells(self, avoid: set[Cell], dist: Distances) -> list[Cell]:
        """The heuristic's cell to search, then the first unsearched cell (in the heuristic's
        order) of each other room, until there are ``explore`` of them."""
        rows, cols, order = unsearched = self._unsearched(avoid, dist)
        first = self._search_target(avoid, dist, unsearched)
        if first is None or self.explore == 1:
            return [] if first is None else [first]
        room = self._rooms()[rows[order], cols[order]]
        _, firsts = np.unique(room, return_index=True)  # each room's first cell in the order
        cells = [first]
        for i in order[np.sort(firsts)]:
            cell = (int(rows[i]), int(cols[i]))
            if 0 <= self._rooms()[cell] != self._rooms()[first] and len(cells) < self.explore:
                cells.append(cell)
        return cells

    def _rooms(self) -> np.ndarray:
        if self._room_index is None:
            self._room_index = room_index(self.house)
        return self._room_index

    def _job_for(self, c: Candidate, avoid: set[Cell]) -> Job:
        if c.kind == "fetch":
            return self._pick_job(c.what)
        if c.kind == "look":
            return self._look_job(c.what)
        if c.kind == "place":
            return self._place_job_at(c.what)
        if c.kind == "explore":
            return self._explore_job(c.what)
        if c.kind == "inspect":
            return self._inspect_job_at(c.what)
        return self._park_job(avoid)

    def _metres(self, xy) -> float:
        here = np.asarray(self.house.navgrid.center(*self.state.cell))
        return float(np.hypot(*(np.asarray(xy, float)[:2] - here)))

    def _rows(self, cands: list[Candidate], dist: Distances) -> Rows:
        catalog = load_catalog()
        n = slots(self.explore)
        assert len(cands) <= n
        kind = np.full(n, -1, np.int8)
        types = np.full(n, len(catalog.categories), np.int16)
        rest = np.full(n, len(catalog.receptacles), np.int16)
        numeric = np.zeros((n, numeric_width(self.explore)), np.float32)
        nav = self.house.navgrid
        reachable = dist.moves >= 0
        if self.explore > 1:  # per room: reachable cells, and those not searched
            rooms = self._rooms()
            size = np.bincount(rooms[reachable] + 1, minlength=len(self.house.rooms) + 1)
            open_ = np.bincount(rooms[reachable & ~self.covered] + 1, minlength=len(size))
        others = [
            (name, np.asarray(nav.center(*c)), c)
            for name, (c, t) in self.teammates.items()
            if name != self.name and self.t - t <= TEAMMATE_STEPS and name not in self.parked
        ]
        claims = [(typ, np.asarray(nav.center(*c))) for typ, c in self.claims.values()]
        nearest: dict[str, float] = {}
        rank: dict[str, int] = {}
        for i, c in enumerate(cands):
            kind[i] = KINDS.index(c.kind)
            if c.object_type:
                types[i] = catalog.category_index(c.object_type)
            if c.receptacle_type:
                rest[i] = catalog.receptacles.index(c.receptacle_type)
            if c.position is None:
                continue
            metres = self._metres(c.position)
            cell = nav.cell_of(float(c.position[0]), float(c.position[1]))
            moves = _moves_near(dist, cell)
            xy = np.asarray(c.position[:2], float)
            nearest.setdefault(c.kind, metres)  # each kind's first candidate
            numeric[i, : len(NUMERIC)] = (
                metres / 10,
                max(moves, 0) / 40,
                float(moves < 0),
                rank.get(c.kind, 0) / MAX_FETCH,
                (metres - nearest[c.kind]) / 10,
                float(
                    c.kind in ("fetch", "look")
                    and any(
                        claimed == c.object_type and float(np.hypot(*(xy - at))) < metres
                        for claimed, at in claims
                    )
                ),
                sum(float(np.hypot(*(xy - at))) < metres for _, at, _ in others) / 3,
                sum(abs(oc[0] - cell[0]) + abs(oc[1] - cell[1]) < 6 for *_, oc in others) / 3,
                float(c.position[2]),
            )
            if self.explore > 1 and 0 <= cell[0] < rooms.shape[0] and 0 <= cell[1] < rooms.shape[1]:
                r = rooms[cell] + 1  # 0: outside every room
                numeric[i, len(NUMERIC) :] = (open_[r] / max(size[r], 1), size[r] / 100) if r else 0
            rank[c.kind] = rank.get(c.kind, 0) + 1
        s = self.state
        context = np.array(
            [
                *map(float, self.capability),
                float(s.held is not None),
                self.t / 300,
                float((self.covered & reachable).sum() / max(reachable.sum(), 1)),
                sum(k.misplaced and k.object_id not in self.done for k in self.objects.values())
                / MAX_FETCH,
                len(self.reports) / MAX_LOOK,
                len(others) / 3,
                len(self.parked) / 3,
            ],
            np.float32,
        )
        return Rows(kind, types, rest, numeric, context)


def _moves_near(dist: Distances, cell: Cell) -> int:
    """Moves to the nearest reachable cell within NEAR_CELLS of ``cell`` (-1: none)."""
    m = dist.moves
    r0, c0 = max(cell[0] - NEAR_CELLS, 0), max(cell[1] - NEAR_CELLS, 0)
    window = m[r0 : cell[0] + NEAR_CELLS + 1, c0 : cell[1] + NEAR_CELLS + 1]
    reach = window[window >= 0]
    return int(reach.min()) if reach.size else -1


def teacher_slot(cands: list[Candidate], job: Job, looking: Report | None) -> int | None:
    """Which candidate the heuristic's own choice ``job`` is (None: none of them)."""
    for i, c in enumerate(cands):
        if job.kind == "pick" and c.kind == "fetch" and c.what.object_id == job.target:
            return i
        if job.kind == "look" and c.kind == "look" and c.what is looking:
            return i
        if job.kind == "place" and c.kind == "place" and c.what.target == job.target:
            return i
        if job.kind == "explore" and c.kind == "explore" and c.what == job.leg.candidates[0].cell:
            return i
        if job.kind == "inspect" and c.kind == "inspect" and c.what.target == job.target:
            return i
        if job.kind == "park" and c.kind == "park":
            return i
    return None
