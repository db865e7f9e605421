"""Where a heuristic agent goes next, from what it knows (``policies/heuristic.py``).

A mixin of :class:`~maniskill_tidy.policies.heuristic.HeuristicAgent`: it reads the agent's
memory (its state, the objects it detected, the reports it received, the cells it searched,
the teammates it knows of, the central node's assignment) and returns the next :class:`Job`:
place what it holds, fetch or check a misplaced object, search the nearest unsearched cell,
inspect a surface, or park.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from maniskill_tidy.policies.base import EXPLORE, PLACE, SubTask
from maniskill_tidy.policies.messages import EXPLORE_AREA, FETCH
from maniskill_tidy.policies.navigation import Cell, Distances
from maniskill_tidy.policies.viewpoints import Viewpoint, viewpoints
from maniskill_tidy.policies.walker import Job, Leg

REPORT_HEIGHT = 0.4  # metres: where to look for an object whose height a report does not give
# Surfaces worth a look once searching ends, by camera: a low camera sees into low shelves and
# under tables but not onto tops; a high one sees tops up to a metre.
INSPECT_HEIGHTS = {False: (0.0, 0.5), True: (0.25, 1.0)}  # metres, by "camera above 0.5 m"
EXPLORE_HORIZON = {True: 30, False: 0}  # high cameras look down a little while searching
TEAMMATE_STEPS = 2  # steps a teammate's seen or reported cell counts as occupied


@dataclass
class Known:
    object_id: str
    seg_id: int
    type: str
    position: np.ndarray
    misplaced: bool


@dataclass
class Report:
    """A misplaced object another endpoint told of: its type and where, to 0.25 m."""

    type: str
    xy: tuple[float, float]


@dataclass
class PlaceOption:
    """A surface where D holds for the object held."""

    distance: float  # metres from the agent, straight
    target: str  # "furniture/surface"
    centre: np.ndarray
    object_type: str
    receptacle_type: str
    room: str  # the room's id


@dataclass
class InspectOption:
    """A surface worth a look once searching ends."""

    nearer: bool  # a teammate this agent knows of is nearer to it
    distance: float
    target: str
    centre: np.ndarray


class JobChoice:
    def _new_job(self, avoid: set[Cell]) -> Job:
        s = self.state
        if self.manipulator and s.held is not None:
            job = self._place_job()
            if job is not None:
                return job
        elif self.manipulator:
            job = self._fetch_job()
            if job is not None:
                return job
        cell = self._search_target(avoid)
        if cell is None:
            job = self._inspect_job()
            if job is not None:
                return job
            return self._park_job(avoid)
        return self._explore_job(cell)

    def _explore_job(self, cell: Cell) -> Job:
        s = self.state
        horizon = EXPLORE_HORIZON[self.height > 0.5]
        leg = Leg([Viewpoint(cell, s.rotation, horizon, 0.0)])
        return Job("explore", "", leg, SubTask(EXPLORE))

    def _park_job(self, avoid: set[Cell]) -> Job:
        s = self.state
        park = self.planner.parking(s.cell, set(self.parked.values()), avoid)
        leg = Leg([Viewpoint(park, s.rotation, s.horizon, 0.0)])
        return Job("park", "", leg, SubTask(EXPLORE))

    def _fetch_job(self) -> Job | None:
        here = np.asarray(self.house.navgrid.center(*self.state.cell))
        if self.assignment is not None and self.assignment[0] == FETCH:
            _, object_type, xyz = self.assignment
            options = [k for k in self._targets() if k.type == object_type]
            if not options:
                return self._look_job(Report(object_type, (float(xyz[0]), float(xyz[1]))))
        else:
            options = self._targets()
        if options:
            k = min(options, key=lambda k: (float(np.hypot(*(k.position[:2] - here))), k.object_id))
            return self._pick_job(k)
        if self.reports:
            r = min(
                self.reports, key=lambda r: (float(np.hypot(*(np.asarray(r.xy) - here))), r.type)
            )
            return self._look_job(r)
        return None

    def _pick_job(self, k: Known) -> Job:
        leg = Leg(viewpoints(self.house, k.position, self.height)[:12])
        return Job("pick", k.object_id, leg, SubTask(PLACE, k.type))

    def _targets(self) -> list[Known]:
        """Misplaced objects this agent knows of that no closer teammate manipulator is after."""
        out = []
        for k in self.objects.values():
            if not k.misplaced or k.object_id in self.done:
                continue
            mine = float(np.hypot(*(k.position[:2] - self.house.navgrid.center(*self.state.cell))))
            taken = any(
                t == k.type
                and float(np.hypot(*(k.position[:2] - self.house.navgrid.center(*c)))) < mine
                for t, c in self.claims.values()
            )
            if not taken:
                out.append(k)
        return out

    def _look_job(self, r: Report) -> Job:
        if r not in self.reports:
            self.reports.append(r)
        self._looking = r
        leg = Leg(viewpoints(self.house, np.array([*r.xy, REPORT_HEIGHT]), self.height)[:12])
        return Job("look", r.type, leg, SubTask(PLACE, r.type))

    def _place_job(self) -> Job | None:
        """The nearest surface of the floor plan where D holds for what the agent holds."""
        options = self._place_options()
        return self._place_job_at(options[0]) if options else None

    def _place_options(self) -> list[PlaceOption]:
        """The surfaces of the floor plan where D holds for what the agent holds (and which did
        not refuse it, or this object), nearest first (the floor plan's order among equals)."""
        held_type = self.public.instances[self._seg_of(self.state.held)].type
        here = np.asarray(self.house.navgrid.center(*self.state.cell))
        options = []
        for spot in self.surfaces:
            target = f"{spot.furniture}/{spot.surface}"
            if target in self.bad_surfaces or (self.state.held, target) in self.full:
                continue
            rtype = self.furniture[spot.furniture].surface(spot.surface).receptacle_type
            if not self.knowledge.D(held_type, rtype, self.room_type[spot.room]):
                continue
            x0, y0, x1, y1 = spot.bounds
            centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2, spot.height])
            d = float(np.hypot(*(centre[:2] - here)))
            options.append(PlaceOption(d, target, centre, held_type, rtype, spot.room))
        return sorted(options, key=lambda o: o.distance)

    def _place_job_at(self, o: PlaceOption) -> Job:
        leg = Leg(viewpoints(self.house, o.centre + [0, 0, 0.02], self.height)[:12])
        subtask = SubTask(PLACE, o.object_type, o.receptacle_type, self.room_type[o.room])
        return Job("place", o.target, leg, subtask)

    def _inspect_job(self) -> Job | None:
        """Look at the nearest surface not yet inspected (objects hide on and in furniture),
        preferring those no teammate this agent knows of is nearer to."""
        options = self._inspect_options()
        return self._inspect_job_at(options[0]) if options else None

    def _inspect_options(self) -> list[InspectOption]:
        """The surfaces at a height this agent's camera sees, not yet inspected: those no
        teammate it knows of is nearer to first, then nearest first."""
        nav = self.house.navgrid
        here = np.asarray(nav.center(*self.state.cell))
        others = [
            np.asarray(nav.center(*c))
            for n, (c, t) in self.teammates.items()
            if n != self.name and self.t - t <= TEAMMATE_STEPS and n not in self.parked
        ]
        low, high = INSPECT_HEIGHTS[self.height > 0.5]
        options = []
        for spot in self.surfaces:
            target = f"{spot.furniture}/{spot.surface}"
            if target in self.inspected or not low <= spot.height <= high:
                continue
            x0, y0, x1, y1 = spot.bounds
            centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2, spot.height])
            mine = float(np.hypot(*(centre[:2] - here)))
            nearer = any(float(np.hypot(*(centre[:2] - o))) < mine for o in others)
            options.append(InspectOption(nearer, mine, target, centre))
        return sorted(options, key=lambda o: (o.nearer, o.distance, o.target))

    def _inspect_job_at(self, o: InspectOption) -> Job:
        leg = Leg(viewpoints(self.house, o.centre + [0, 0, 0.05], self.height)[:12])
        return Job("inspect", o.target, leg, SubTask(EXPLORE))

    def _search_target(
        self, avoid: set[Cell], dist: Distances | None = None, unsearched: tuple | None = None
    ) -> Cell | None:
        """Where to search next: the central node's area, else the nearest unsearched cell
        (as far as this agent knows) away from the teammates it knows of. ``dist`` and
        ``unsearched`` (``_unsearched``'s answer): when the caller has them already."""
        if dist is None:
            dist = self.planner.distances(self.state.cell, set(self.parked.values()))
        if self.assignment is not None and self.assignment[0] == EXPLORE_AREA:
            cell = self.house.navgrid.cell_of(*self.assignment[2][:2])
            if cell in dist and not self.covered[cell]:
                return cell
        rows, cols, order = unsearched or self._unsearched(avoid, dist)
        if not len(rows):
            return None
        return int(rows[order[0]]), int(cols[order[0]])

    def _unsearched(
        self, avoid: set[Cell], dist: Distances
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The reachable cells not searched and not avoided (rows, cols), and their order of
        preference: by moves + 8 x teammates within 5 cells, then by cell; computed over the
        whole grid at once."""
        candidates = (dist.moves >= 0) & ~self.covered
        for cell in avoid:
            if cell in dist:
                candidates[cell] = False
        rows, cols = np.nonzero(candidates)
        crowd = np.zeros(len(rows), np.int64)
        for n, (o, _) in self.teammates.items():
            if n != self.name:
                crowd += np.abs(o[0] - rows) + np.abs(o[1] - cols) < 6
        return rows, cols, np.lexsort((cols, rows, dist.moves[rows, cols] + 8 * crowd))

    def _seg_of(self, oid: str | None) -> int:
        return next(s for s, inst in self.public.instances.items() if inst.id == oid)
