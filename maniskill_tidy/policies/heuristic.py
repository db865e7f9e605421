"""Heuristic teams that see only through their own cameras, with the paper's communication patterns.

Every agent keeps its own memory and nothing else: its semantic map
(``perception/semantic_map.py``, fed by its own RGB-D + segmentation), the cells it has
searched (seen within ``COVER_RANGE``), the objects it has detected (read off the map's
back-projected points, ``perception/detections.py``), each judged misplaced or not with the
placement knowledge D and the public floor plan, the teammates it sees or hears from, and what
others reported. Navigation-only agents search: they walk to the nearest reachable cell not
yet searched (as far as they know), keeping away from teammates they know of; once every cell
is searched they inspect the floor plan's surfaces their camera can see into or onto
(``heuristic_jobs.INSPECT_HEIGHTS``) one by one from a viewpoint facing each, then stop. A
manipulator tidies what it knows of (the nearest misplaced object; then the nearest surface of
the floor plan where D holds) and searches otherwise. What an agent knows beyond its own camera
comes only through the channel (``policies/messages.py``: state 10 + map crop 400 values):

- ``none``: no messages; a teammate is known only when seen, and a move blocked by an unseen
  one is a failed action the agent handles (it marks the cell occupied for a few steps and
  sometimes steps aside, so that two robots facing each other do not wait forever);
- ``detection``: an agent broadcasts its state and map crop only in steps where it sees a
  misplaced object (the paper's CondComm.);
- ``broadcast``: every agent broadcasts them every step (BroadComm.);
- ``central``: every agent uploads them to a central node (``policies/central.py``), which
  sends each agent an assignment (6 values: what to fetch or where to search; CentralComm.).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from maniskill_tidy.envs.actions import Action, AgentState, Targeted, move_target
from maniskill_tidy.envs.robots import robot_kind
from maniskill_tidy.knowledge import FLOOR, load_placement
from maniskill_tidy.perception.detections import (
    detect_objects,
    resting_place,
    seen_robots,
    surface_table,
)
from maniskill_tidy.perception.frame_inputs import camera_pitch
from maniskill_tidy.perception.map_kernels import mark_near_cells
from maniskill_tidy.perception.semantic_map import MapConfig, SemanticMap
from maniskill_tidy.policies.base import (
    EXPLORE,
    PLACE,
    Agent,
    AgentView,
    Label,
    PublicInfo,
    SubTask,
    Team,
)
from maniskill_tidy.policies.channel import CENTRAL, Message, Outbox
from maniskill_tidy.policies.heuristic_jobs import TEAMMATE_STEPS, JobChoice, Known, Report
from maniskill_tidy.policies.messages import (
    State,
    decode_assignment,
    decode_crop,
    decode_state,
    encode_crop,
    encode_state,
)
from maniskill_tidy.policies.navigation import Cell, GridPlanner
from maniskill_tidy.policies.walker import Job, NoViewpoint, Walker, wait_action

MAP_STRIDE = 2  # every other pixel: half the map's cost (``bench --only map``), same cells
COVER_RANGE = 2.0  # metres: a cell counts as searched once seen this close (small objects)
BLOCK_STEPS = 3  # steps a cell where a robot blocked a move counts as occupied
SAME_OBJECT = 0.6  # metres: a report this close to a known object of its type is that object


class HeuristicAgent(JobChoice, Agent):
    # A PutDown refused with "no room for X on S" gives S up for X at once, instead of trying
    # the next viewpoint of S (the rule before it, ``HeuristicTeam.rules`` ""): Success +0.040
    # [+0.010, +0.070] for heuristic-detection on val (scripts/full_surface_ab.py, which turns
    # it off for the paired "before").
    FULL_SURFACE_RULE: ClassVar[bool] = True

    def __init__(self, name: str, public: PublicInfo, outbox: Outbox, communication: str) -> None:
        super().__init__(name, public, outbox)
        self.communication = communication
        house = self.house = public.house
        self.capability = public.capability(name)
        self.manipulator = bool(self.capability[1])
        self.height = robot_kind(self.capability).camera_height
        self.planner = GridPlanner(house)
        self.walker = Walker(self.planner)
        self.map = SemanticMap(house, public.instances, MapConfig(stride=MAP_STRIDE))
        self.knowledge = load_placement()
        self.room_type = {r.id: r.type for r in house.rooms}
        self.surfaces = surface_table(house)
        self.furniture = house.furniture_by_id()
        self.covered = np.zeros(tuple(house.navgrid.shape), dtype=bool)
        self.objects: dict[str, Known] = {}
        self.reports: list[Report] = []
        self.dismissed: list[Report] = []  # reports checked and found stale: not again
        self.done: set[str] = set()  # objects tidied or given up: not worth a trip
        self.bad_surfaces: set[str] = set()
        self.full: set[tuple[str, str]] = set()  # (object, surface) PutDown found no room for
        self.inspected: set[str] = set()  # surfaces looked at from a viewpoint facing them
        self.teammates: dict[str, tuple[Cell, int]] = {}  # name -> (cell, step last known)
        self.claims: dict[str, tuple[str, Cell]] = {}  # manipulator -> (object type, cell)
        self.parked: dict[str, Cell] = {}  # teammates that said they go to stop there
        self.blocked: dict[Cell, int] = {}  # cell -> last step it counts as occupied
        self.assignment: tuple[int, str, np.ndarray] | None = None
        self.job: Job | None = None
        self.state = AgentState(name, self.capability, (0, 0), 0)
        self.rng = np.random.default_rng([public.seed, public.agents.index(name), 7])
        self.t = 0
        self.sees_misplaced = False
        self._label: Label | None = None
        self._sidestep: Action | None = None
        self._looking: Report | None = None  # the report a "look" job goes to check

    # ------------------------------------------------------------------ perception
    def observe(self, view: AgentView) -> None:
        self.t = view.step
        o = view.obs
        s = self.state
        s.cell = self.house.navgrid.cell_of(float(o["pose"][0]), float(o["pose"][1]))
        s.rotation = int(round(float(o["pose"][2]))) % 360
        s.horizon = camera_pitch(o["extrinsics"])
        seg = int(o["held"])
        s.held = self.public.instances[seg].id if seg else None
        if view.failed:
            self._failed(view.failed)
        if self.job is not None and self.job.issued:
            if self.FULL_SURFACE_RULE and self.job.found_no_room(view.failed):
                self.full.add((s.held, self.job.target))
                self.job = None
            elif self.job.succeeded(s):
                if self.job.kind == "pick":
                    self.done.add(self.job.target)
                self.job = None
        self.covered[s.cell] = True
        self.sees_misplaced = False
        if "depth" in o and "segmentation" in o:
            self._perceive(o)

    def _perceive(self, o: dict) -> None:
        self.map.update(o)
        frame = self.map.last_frame
        nav = self.house.navgrid
        dtype = frame.points.dtype  # the cell arithmetic in the points' precision, as numpy's
        mark_near_cells(frame.points, frame.camera, COVER_RANGE, np.asarray(nav.origin, dtype),
                        dtype.type(nav.cell), self.covered)  # fmt: skip
        for name, xy in seen_robots(frame, self.public.instances).items():
            if name != self.name:
                self.teammates[name] = (nav.cell_of(float(xy[0]), float(xy[1])), self.t)
        seen = set()
        for d in detect_objects(frame, self.public.instances):
            if d.object_id == self.state.held or d.object_id in self.done:
                continue
            receptacle, surface, room = resting_place(self.house, d, self.surfaces)
            if not receptacle:
                continue  # carried by someone, or in mid-air
            if receptacle == FLOOR:
                misplaced = True
            else:
                rtype = self.furniture[receptacle].surface(surface).receptacle_type
                misplaced = not self.knowledge.D(d.type, rtype, self.room_type[room])
            self.objects[d.object_id] = Known(d.object_id, d.seg_id, d.type, d.position, misplaced)
            self.sees_misplaced |= misplaced
            seen.add(d.object_id)
        view = _camera_view(o)
        self._forget_moved(view, seen)
        here = np.asarray(nav.center(*self.state.cell))
        for r in list(self.reports):
            if self._matches_known(r):
                self.reports.remove(r)
            elif np.hypot(*(np.asarray(r.xy) - here)) < COVER_RANGE and self._looked_at(r, view):
                self.reports.remove(r)  # in clear view and not there: a stale report
                self.dismissed.append(r)

    def _forget_moved(self, view: tuple, seen: set[str]) -> None:
        """Known objects whose spot is in clear view but which were not detected have moved."""
        for oid, k in list(self.objects.items()):
            if oid not in seen and _in_clear_view(k.position, view):
                del self.objects[oid]

    def forget(self, object_id: str) -> None:
        """Perception took back an object it had shown (the pixels track refutes a false
        detection, ``policies/pixels.py``): it leaves the memory, and a job to fetch it ends
        instead of trying every viewpoint of a spot where nothing lies. Never called on ground
        truth, whose objects are never taken back."""
        self.objects.pop(object_id, None)
        if self.job is not None and self.job.kind == "pick" and self.job.target == object_id:
            self.job = None

    def _looked_at(self, r: Report, view: tuple) -> bool:
        return any(_in_clear_view([*r.xy, z], view) for z in (0.05, 0.45, 0.85))

    def _matches_known(self, r: Report) -> bool:
        return any(
            k.type == r.type and np.hypot(*(k.position[:2] - np.asarray(r.xy))) < SAME_OBJECT
            for k in self.objects.values()
        )

    def _failed(self, reason: str) -> None:
        """A move blocked by a robot: that cell is occupied for a while; sometimes step aside."""
        if "blocked by agent" not in reason:
            if self.job is not None and not self.job.issued:
                self.job.leg.give_up_goal()
            return
        action = next(
            a
            for a in (Action.MoveAhead, Action.MoveLeft, Action.MoveRight)
            if reason.startswith(a.name)
        )
        self.blocked[move_target(self.state, action)] = self.t + BLOCK_STEPS
        if self.job is not None:
            self.job.leg.path = None
        if self.rng.random() < 0.5:  # break the symmetry of two robots facing each other
            options = [
                a
                for a in (Action.MoveLeft, Action.MoveRight)
                if self.house.navgrid.free(*move_target(self.state, a))
                and move_target(self.state, a) not in self.blocked
            ]
            if options:
                self._sidestep = options[int(self.rng.integers(len(options)))]

    # ------------------------------------------------------------------ communication
    def send(self, round: int, inbox: list[Message]) -> None:
        if self.communication == "none":
            return
        if self.communication == "detection" and not self.sees_misplaced:
            return
        receivers = [CENTRAL] if self.communication == "central" else self.outbox.peers
        if not receivers:
            return
        subtask = self.job.subtask if self.job is not None else SubTask(EXPLORE)
        if self.job is not None and self.job.kind == "park":
            subtask = SubTask("Park")
        x, y = self.house.navgrid.center(*self.state.cell)
        pose = (x, y, self.state.rotation)
        misplaced = [
            (k.type, k.position)
            for k in self.objects.values()
            if k.misplaced and k.object_id not in self.done
        ]
        self.outbox.send(receivers, encode_state(self.capability, pose, subtask), "state")
        self.outbox.send(receivers, encode_crop(self.map, pose, misplaced), "map")

    def _receive(self, inbox: list[Message]) -> None:
        states = {m.sender: decode_state(m.vector) for m in inbox if m.kind == "state"}
        nav = self.house.navgrid
        for sender, st in states.items():
            self._heard(sender, st)
        for m in inbox:
            if m.kind == "map" and m.sender in states:
                cells = decode_crop(m.vector, states[m.sender].pose, nav)
                self.covered[cells.explored] = True
                for object_type, xy in cells.misplaced:
                    self._add_report(Report(object_type, xy))
            elif m.kind == "assignment":
                self.assignment = decode_assignment(m.vector)

    def _heard(self, sender: str, st: State) -> None:
        """A teammate's state message: where it is, whether it parks, what it goes for."""
        cell = self.house.navgrid.cell_of(st.pose[0], st.pose[1])
        self.teammates[sender] = (cell, self.t)
        if st.parking:
            self.parked[sender] = cell
        else:
            self.parked.pop(sender, None)
        if st.capability[1] and st.subtask.kind == PLACE and st.subtask.object_type:
            self.claims[sender] = (st.subtask.object_type, cell)
        else:
            self.claims.pop(sender, None)

    def _add_report(self, report: Report) -> None:
        if self._matches_known(report):
            return
        for r in [*self.reports, *self.dismissed]:
            if r.type == report.type and np.hypot(*np.subtract(r.xy, report.xy)) < SAME_OBJECT:
                return
        self.reports.append(report)

    # ------------------------------------------------------------------ acting
    def act(self, inbox: list[Message]) -> Action | Targeted:
        self._receive(inbox)
        if self._sidestep is not None:
            action, self._sidestep = self._sidestep, None
            if self.job is not None:
                self.job.leg.path = None
            return action
        occupied = {c for c, t in self.teammates.values() if self.t - t < TEAMMATE_STEPS}
        occupied |= {c for c, until in self.blocked.items() if until >= self.t}
        stopped = set(self.parked.values()) - {self.state.cell}
        occupied -= {self.state.cell}
        s = self.state
        for _ in range(4):
            if self.job is None:
                self.job = self._new_job(occupied | stopped)
            job = self.job
            if job.kind == "park" and s.cell == job.leg.candidates[0].cell:
                self._label = job.label(s)
                return Action.Stop
            if job.kind == "explore" and self.covered[job.leg.candidates[0].cell]:
                self.job = None
                continue
            try:
                action = self.walker.step(s, job.leg, occupied, stopped)
            except NoViewpoint:
                self._give_up(job)
                self.job = None
                continue
            self._label = job.label(s)
            if action is not None:
                return action
            if job.kind in ("pick", "place"):
                job.issued = True
                op = Action.PickUp if job.kind == "pick" else Action.PutDown
                return Targeted(op, job.target)
            if job.kind == "look":
                self._drop_looked_report()
            elif job.kind == "inspect":
                self.inspected.add(job.target)
            self.job = None  # searched there: pick a new target
        return wait_action(s)

    def label(self) -> Label | None:
        return self._label

    def _give_up(self, job: Job) -> None:
        if job.kind == "pick":
            self.done.add(job.target)
        elif job.kind == "place":
            self.bad_surfaces.add(job.target)
        elif job.kind == "explore":
            self.covered[job.leg.candidates[0].cell] = True
        elif job.kind == "look":
            self._drop_looked_report()
        elif job.kind == "inspect":
            self.inspected.add(job.target)

    def _drop_looked_report(self) -> None:
        if self._looking is not None:
            self.dismissed.append(self._looking)
        self.reports = [r for r in self.reports if r is not self._looking]
        self._looking = None


def _camera_view(o: dict) -> tuple:
    """What ``_in_clear_view`` reads of a frame, converted once per frame: the world-to-camera
    rotation and shift (float64), the intrinsics and the depth."""
    ext = np.asarray(o["extrinsics"], float)
    return ext[:3, :3], ext[:3, 3], np.asarray(o["intrinsics"], float), o["depth"]


def _in_clear_view(point, view: tuple) -> bool:
    """The point is in the picture, within COVER_RANGE, with nothing in front of it."""
    rotation, shift, intr, depth = view
    cam = rotation @ np.asarray(point, float) + shift
    if not 0.2 < cam[2] < COVER_RANGE:
        return False
    u, v = intr[0, 0] * cam[0] / cam[2] + intr[0, 2], intr[1, 1] * cam[1] / cam[2] + intr[1, 2]
    h, w = depth.shape
    if not (5 <= u < w - 5 and 5 <= v < h - 5):
        return False
    return bool(depth[int(v), int(u)] > cam[2] - 0.1)  # nothing in front of it


class HeuristicTeam(Team):
    """Camera-only agents with one of the paper's communication patterns (see the top)."""

    name = "heuristic"
    communication = "none"
    observations = "depth+segmentation"  # no colour: the env skips reading it back
    perception = "ground-truth segmentation + depth, open3d semantic map"
    threadsafe_agents = True
    rules = "full-surface"  # HeuristicAgent.FULL_SURFACE_RULE, from 2026-12-01

    def make_agent(self, name: str, public: PublicInfo, outbox: Outbox) -> Agent:
        return HeuristicAgent(name, public, outbox, self.communication)

    def make_central(self, public: PublicInfo, outbox: Outbox):
        if not self.central:
            return None
        from maniskill_tidy.policies.central import HeuristicCentral

        return HeuristicCentral(public, outbox)


class NoCommTeam(HeuristicTeam):
    name = "heuristic-none"


class DetectionCommTeam(HeuristicTeam):
    name = "heuristic-detection"
    communication = "detection"


class BroadcastTeam(HeuristicTeam):
    name = "heuristic-broadcast"
    communication = "broadcast"


class CentralTeam(HeuristicTeam):
    name = "heuristic-central"
    communication = "central"
    central = True


class SingleAgent(HeuristicTeam):
    """The paper's SA: one manipulator alone (starting where Setting I's first agent does)."""

    name = "sa"
    team_override = [[1, 1, 1]]
