"""Heuristic teams that see only through their cameras, with the paper's communication patterns.

Every agent keeps a memory: the grid cells its camera has covered and the objects it has
detected (``perception/detections.py``: ground-truth segmentation, measured positions), each
judged misplaced or not with the placement knowledge D. Navigation-only agents explore: they walk
to the nearest free cell nobody they know of has seen. A manipulator tidies what it knows of
(nearest misplaced object first, then the nearest seen surface where D holds) and explores
otherwise. What an agent knows beyond its own camera comes only through the channel:

- ``none``: no messages (the scouts' findings are lost);
- ``detection``: an agent broadcasts its state, map crop and detections only in steps where it
  sees a misplaced object (the paper's CondComm.);
- ``broadcast``: every agent broadcasts them every step (BroadComm.);
- ``central``: every agent sends them to a central node, which sends each agent the object to
  fetch (CentralComm.).

Message contents, counted in dimensions: state = capability (3) + pose (3) + sub-task (kind,
object instance, receptacle type, room type: 4) = 10, as in the paper; map = the 20 x 20 crop of
the explored grid around the sender = 400; detections = 6 per misplaced object known (instance,
type, x, y, z, 1); an assignment from the central node = 6.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from maniskill_tidy.envs.actions import Action, AgentState, Targeted
from maniskill_tidy.envs.robots import robot_kind
from maniskill_tidy.knowledge import FLOOR, ROOM_TYPES, load_catalog, load_placement
from maniskill_tidy.perception.detections import (
    detect_objects,
    explored_cells,
    resting_place,
    surface_table,
)
from maniskill_tidy.policies.base import EXPLORE, PLACE, PublicInfo, SubGoal, SubTask, Team
from maniskill_tidy.policies.channel import CENTRAL, Channel
from maniskill_tidy.policies.navigation import Cell, GridPlanner, subgoal
from maniskill_tidy.policies.viewpoints import Viewpoint, viewpoints
from maniskill_tidy.policies.walker import Leg, NoViewpoint, Walker

CROP = 20  # cells of the map crop sent to others
EXPLORE_HORIZON = {True: 30, False: 0}  # high cameras look down a little while exploring


@dataclass
class Known:
    object_id: str
    seg_id: int
    type: str
    position: np.ndarray
    misplaced: bool


@dataclass
class Memory:
    explored: np.ndarray  # bool grid
    objects: dict[str, Known] = field(default_factory=dict)
    done: set[str] = field(default_factory=set)  # objects tidied or lost: not worth a trip
    claims: dict[str, str] = field(default_factory=dict)  # object -> manipulator going for it
    poses: dict[str, Cell] = field(default_factory=dict)  # other agents' last known cells


class HeuristicTeam(Team):
    name = "heuristic"
    team_override: list | None = None
    communication = "none"
    perception = "ground-truth segmentation + depth back-projection"

    def __init__(self) -> None:
        self.central = self.communication == "central"

    def reset(self, info: PublicInfo, channel: Channel, env: Any | None = None) -> None:
        self.info, self.channel, self.house = info, channel, info.house
        self.planner = GridPlanner(self.house)
        self.walker = Walker(self.planner)
        self.knowledge, self.catalog = load_placement(), load_catalog()
        self.room_type = {r.id: r.type for r in self.house.rooms}
        shape = tuple(self.house.navgrid.shape)
        self.memory = {a: Memory(np.zeros(shape, bool)) for a in info.agents}
        self.jobs: dict[str, tuple[str, str, Leg, SubTask] | None] = {a: None for a in info.agents}
        self.pending: dict[str, tuple[str, str] | None] = {a: None for a in info.agents}
        self.instances = info.instances
        self.seg_of = {inst.id: sid for sid, inst in info.instances.items()}
        self.furniture = self.house.furniture_by_id()
        self.surfaces = surface_table(self.house)
        self._states: dict[str, AgentState] = {}
        self._stopped_cells: list[Cell] = []
        self._bad_surfaces: dict[str, set[str]] = {}
        self._assigned: dict[str, str | None] = {}
        self._labels: dict[str, tuple[SubTask, SubGoal]] = {}
        self.stopped: set[str] = set()

    # ------------------------------------------------------------------ perception
    def _perceive(self, name: str, o: dict) -> bool:
        """Update ``name``'s memory from its frame; True if a misplaced object is in view."""
        mem = self.memory[name]
        rows, cols = mem.explored.shape
        for r, c in explored_cells(o, self.house):
            if 0 <= r < rows and 0 <= c < cols:
                mem.explored[r, c] = True
        sees_misplaced = False
        for d in detect_objects(o, self.instances):
            if d.seg_id == int(o["held"]):
                continue
            receptacle, surface, room = resting_place(self.house, d, self.surfaces)
            if not receptacle:
                continue  # carried by someone, or in mid-air
            if receptacle == FLOOR:
                misplaced = True
            else:
                rtype = self.furniture[receptacle].surface(surface).receptacle_type
                misplaced = not self.knowledge.D(d.type, rtype, self.room_type[room])
            mem.objects[d.object_id] = Known(d.object_id, d.seg_id, d.type, d.position, misplaced)
            sees_misplaced |= misplaced
        return sees_misplaced

    # ------------------------------------------------------------------ communication
    def _state(self, a: AgentState) -> np.ndarray:
        job = self.jobs[a.name]
        subtask = job[3] if job else SubTask(EXPLORE)
        target = self._seg_of(job[1]) if job and job[0] == "pick" else 0
        return np.array(
            [
                *a.capability,
                *a.cell,
                a.rotation,
                subtask.kind == PLACE,
                target,
                self._type_index(subtask.receptacle_type),
                ROOM_TYPES.index(subtask.room_type) if subtask.room_type else -1,
            ],
            dtype=np.float32,
        )

    def _crop(self, a: AgentState) -> np.ndarray:
        out = np.zeros((CROP, CROP), np.float32)
        in_grid, in_crop = crop_window(a.cell, self.memory[a.name].explored.shape)
        out[in_crop] = self.memory[a.name].explored[in_grid]
        return out

    def _detections(self, name: str) -> np.ndarray:
        mem = self.memory[name]
        rows = [
            [k.seg_id, self._type_index(k.type), *k.position, 1.0]
            for k in mem.objects.values()
            if k.misplaced and k.object_id not in mem.done
        ]
        return np.array(rows, np.float32).reshape(-1, 6)

    def _send(self, a: AgentState, receivers: list[str]) -> None:
        self.channel.send(a.name, receivers, self._state(a), "state")
        self.channel.send(a.name, receivers, self._crop(a), "map")
        det = self._detections(a.name)
        if det.size:
            self.channel.send(a.name, receivers, det, "detections")

    def _receive(self, name: str) -> None:
        mem = self.memory[name]
        by_sender: dict[str, dict[str, np.ndarray]] = {}
        for m in self.channel.inbox(name):
            by_sender.setdefault(m.sender, {})[m.kind] = m.vector
        for sender, parts in by_sender.items():
            if "state" in parts:
                s = parts["state"]
                cell = (int(s[3]), int(s[4]))
                mem.poses[sender] = cell
                if s[1] and s[7] > 0:
                    oid = self._object_of_seg(int(s[7]))
                    if oid:
                        mem.claims[oid] = sender
                if "map" in parts:
                    self._merge_crop(mem, cell, parts["map"].reshape(CROP, CROP))
            if "detections" in parts:
                for row in parts["detections"].reshape(-1, 6):
                    oid = self._object_of_seg(int(row[0]))
                    if oid and oid not in mem.done and oid not in mem.objects:
                        inst = self.instances[int(row[0])]
                        mem.objects[oid] = Known(oid, int(row[0]), inst.type, row[2:5].copy(), True)
            if "assignment" in parts:
                row = parts["assignment"]
                oid = self._object_of_seg(int(row[1])) if row[0] > 0 else None
                self._assigned[name] = oid
                if oid and oid not in mem.done:
                    inst = self.instances[int(row[1])]
                    mem.objects[oid] = Known(oid, int(row[1]), inst.type, row[2:5].copy(), True)

    @staticmethod
    def _merge_crop(mem: Memory, cell: Cell, crop: np.ndarray) -> None:
        in_grid, in_crop = crop_window(cell, mem.explored.shape)
        mem.explored[in_grid] |= crop[in_crop] > 0

    def _central_node(self, agents: list[AgentState]) -> None:
        """Merge what everyone sent, give each free manipulator the nearest unclaimed object."""
        for a in agents:
            self._send(a, [CENTRAL])
        merged: dict[str, np.ndarray] = {}
        for m in self.channel.inbox(CENTRAL):
            if m.kind == "detections":
                for row in m.vector.reshape(-1, 6):
                    oid = self._object_of_seg(int(row[0]))
                    if oid:
                        merged[oid] = row
        taken: set[str] = set()
        for a in agents:
            if not a.manipulator:
                continue
            options = [
                (float(np.hypot(*(np.array(self.house.navgrid.center(*a.cell)) - row[2:4]))), oid)
                for oid, row in merged.items()
                if oid not in taken
            ]
            oid = min(options)[1] if options and a.held is None else None
            if oid:
                taken.add(oid)
            seg = merged[oid][0] if oid else 0
            vec = [1.0 if oid else 0.0, seg, *(merged[oid][2:5] if oid else (0, 0, 0)), 0.0]
            self.channel.send(CENTRAL, a.name, np.array(vec, np.float32), "assignment")

    # ------------------------------------------------------------------ acting
    def act(self, obs: dict[str, dict], info: dict) -> dict[str, Any]:
        agents = [a for a in self._agents(obs) if a.name not in self.stopped]
        self._assigned: dict[str, str | None] = {}
        for a in agents:
            self._outcome(a, info["failed"].get(a.name, ""))
        for a in agents:  # where a robot stands is known, even if its camera never sees it
            self.memory[a.name].explored[a.cell] = True
        sees = {a.name: self._perceive(a.name, obs[a.name]) for a in agents}
        if self.communication == "broadcast":
            for a in agents:
                self._send(a, [b for b in self.info.agents if b != a.name])
        elif self.communication == "detection":
            for a in agents:
                if sees[a.name]:
                    self._send(a, [b for b in self.info.agents if b != a.name])
        elif self.central:
            self._central_node(agents)
        for a in agents:
            self._receive(a.name)
        self._labels = {}
        return {a.name: self._decide(a, agents) for a in agents}

    def labels(self) -> dict[str, tuple[SubTask, SubGoal]]:
        return self._labels

    def _outcome(self, a: AgentState, failure: str) -> None:
        pending, self.pending[a.name] = self.pending[a.name], None
        if pending is None:
            return
        kind, target = pending
        job = self.jobs[a.name]
        mem = self.memory[a.name]
        if kind == "pick" and a.held == target:
            mem.done.add(target)
            self.jobs[a.name] = None
        elif kind == "place" and a.held is None:
            self.jobs[a.name] = None
        elif job is not None:
            job[2].give_up_goal()

    def _decide(self, a: AgentState, agents: list[AgentState]) -> Any:
        others = {b.cell for b in agents if b is not a} | set(self._stopped_cells)
        for _ in range(4):
            job = self.jobs[a.name] or self._new_job(a)
            self.jobs[a.name] = job
            kind, target, leg, subtask = job
            if kind == "park" and a.cell == leg.candidates[0].cell:
                self.stopped.add(a.name)
                self._stopped_cells.append(a.cell)
                return Action.Stop
            if kind == "explore" and self.memory[a.name].explored[leg.candidates[0].cell]:
                self.jobs[a.name] = None
                continue
            try:
                action = self.walker.step(a, leg, others, set(self._stopped_cells))
            except NoViewpoint:
                if kind == "pick":
                    self.memory[a.name].done.add(target)
                elif kind == "place":
                    self._bad_surfaces.setdefault(a.name, set()).add(target)
                elif kind == "explore":
                    self.memory[a.name].explored[leg.candidates[0].cell] = True
                self.jobs[a.name] = None
                continue
            ope = {"pick": "PickUp", "place": "PutDown"}.get(kind, "NoAction")
            goal = leg.goal or leg.candidates[0]  # None after giving up on a blocked goal
            path = list(leg.path) if leg.path else [a.cell, goal.cell]
            if path[0] != a.cell:
                path = [a.cell, *path]
            label = subgoal(a, path, goal.rotation, ope, kind == "park")
            self._labels[a.name] = (subtask, label)
            if action is not None:
                return action
            if kind in ("pick", "place"):
                self.pending[a.name] = (kind, target)
                return Targeted(Action.PickUp if kind == "pick" else Action.PutDown, target)
            self.jobs[a.name] = None  # explored there: pick a new target
        return Action.RotateLeft  # look around while nothing else comes to mind

    def _new_job(self, a: AgentState) -> tuple[str, str, Leg, SubTask]:
        mem = self.memory[a.name]
        height = robot_kind(a.capability).camera_height
        if a.manipulator and a.held is not None:
            place = self._surface_for(a)
            if place is not None:
                return place
        elif a.manipulator:
            oid = self._assigned.get(a.name) if self.central else self._nearest_misplaced(a)
            if oid and oid in mem.objects and oid not in mem.done:
                k = mem.objects[oid]
                return (
                    "pick",
                    oid,
                    Leg(viewpoints(self.house, k.position, height)[:12]),
                    SubTask(PLACE, k.type),
                )
        cell = self._frontier(a)
        if cell is None:
            park = self.planner.parking(a.cell, self._stopped_cells, set())
            return (
                "park",
                "",
                Leg([Viewpoint(park, a.rotation, a.horizon, 0.0)]),
                SubTask(EXPLORE),
            )
        horizon = EXPLORE_HORIZON[height > 0.5]
        rotation = a.rotation
        return ("explore", "", Leg([Viewpoint(cell, rotation, horizon, 0.0)]), SubTask(EXPLORE))

    def _nearest_misplaced(self, a: AgentState) -> str | None:
        mem = self.memory[a.name]
        here = np.array(self.house.navgrid.center(*a.cell))
        options = [
            (float(np.hypot(*(k.position[:2] - here))), oid)
            for oid, k in mem.objects.items()
            if k.misplaced and oid not in mem.done and mem.claims.get(oid, a.name) == a.name
        ]
        return min(options)[1] if options else None

    def _surface_for(self, a: AgentState):
        """The nearest surface seen by this agent (or told of) where D holds for what it holds."""
        held_type = self.instances[self._seg_of(a.held)].type
        mem, bad = self.memory[a.name], self._bad_surfaces.get(a.name, set())
        here = np.array(self.house.navgrid.center(*a.cell))
        best = None
        for f in self.house.furniture:
            r, c = self.house.navgrid.cell_of(*f.position[:2])
            if not (0 <= r < mem.explored.shape[0] and 0 <= c < mem.explored.shape[1]):
                continue
            if not mem.explored[r, c]:
                continue
            for s in f.surfaces:
                target = f"{f.id}/{s.name}"
                if target in bad:
                    continue
                if not self.knowledge.D(held_type, s.receptacle_type, self.room_type[f.room]):
                    continue
                centre, _ = f.surface_world(s)
                d = float(np.hypot(centre[0] - here[0], centre[1] - here[1]))
                if best is None or d < best[0]:
                    best = (d, target, centre, s.receptacle_type, f.room)
        if best is None:
            return None
        _, target, centre, rtype, room = best
        height = robot_kind(a.capability).camera_height
        leg = Leg(viewpoints(self.house, np.asarray(centre) + [0, 0, 0.02], height)[:12])
        return ("place", target, leg, SubTask(PLACE, held_type, rtype, self.room_type[room]))

    def _frontier(self, a: AgentState) -> Cell | None:
        """The nearest reachable free cell not yet explored (as far as this agent knows)."""
        mem = self.memory[a.name]
        dist = self.planner.distances(a.cell, set(self._stopped_cells))
        others = [c for n, c in mem.poses.items() if n != a.name]
        best = None
        for cell, d in dist.items():
            if mem.explored[cell]:
                continue
            crowd = sum(1 for o in others if abs(o[0] - cell[0]) + abs(o[1] - cell[1]) < 6)
            score = d + 8 * crowd
            if best is None or score < best[0]:
                best = (score, cell)
        return best[1] if best else None

    # ------------------------------------------------------------------ helpers
    def _agents(self, obs: dict[str, dict]) -> list[AgentState]:
        out = []
        for name, cap in zip(self.info.agents, self.info.capabilities, strict=True):
            o = obs[name]
            x, y, rot = (float(v) for v in o["pose"])
            state = self._states.setdefault(name, AgentState(name, cap, (0, 0), 0))
            state.cell = self.house.navgrid.cell_of(x, y)
            state.rotation = int(round(rot)) % 360
            state.horizon = camera_pitch(o["extrinsics"])
            seg = int(o["held"])
            state.held = self.instances[seg].id if seg else None
            out.append(state)
        return out

    def _seg_of(self, oid: str | None) -> int:
        return self.seg_of.get(oid, 0)

    def _object_of_seg(self, seg: int) -> str | None:
        inst = self.instances.get(seg)
        return inst.id if inst is not None and inst.kind == "object" else None

    def _type_index(self, t: str) -> int:
        return self.catalog.category_index(t) if t else -1


def crop_window(cell: Cell, shape: tuple[int, int]) -> tuple[tuple[slice, slice], ...]:
    """Slices of the grid and of a CROP x CROP crop centred on ``cell`` that overlap."""
    out_grid, out_crop = [], []
    for centre, size in zip(cell, shape, strict=True):
        lo = centre - CROP // 2
        start, stop = max(lo, 0), min(lo + CROP, size)
        out_grid.append(slice(start, stop))
        out_crop.append(slice(start - lo, stop - lo))
    return tuple(out_grid), tuple(out_crop)


def camera_pitch(extrinsics: np.ndarray) -> int:
    """The camera's horizon in degrees (positive looks down), read off its world pose."""
    forward = np.asarray(extrinsics)[2, :3]  # OpenCV z axis in world coordinates
    return int(round(np.degrees(-np.arcsin(np.clip(forward[2], -1, 1))) / 30.0)) * 30


class NoCommTeam(HeuristicTeam):
    name = "heuristic-none"
    communication = "none"


class DetectionCommTeam(HeuristicTeam):
    name = "heuristic-detection"
    communication = "detection"


class BroadcastTeam(HeuristicTeam):
    name = "heuristic-broadcast"
    communication = "broadcast"


class CentralTeam(HeuristicTeam):
    name = "heuristic-central"
    communication = "central"


class SingleAgent(HeuristicTeam):
    """The paper's SA: one manipulator alone (starting where Setting I's first agent does)."""

    name = "sa"
    communication = "none"
    team_override = [[1, 1, 1]]
