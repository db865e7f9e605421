"""The paper's heuristic shortest-path expert (Section 4): a privileged, centrally planned team.

It reads the simulator: where every misplaced object lies, which surfaces are reasonable for it
and which still have room. Manipulators are allocated the nearest untaken object (path length on
the grid), walk the shortest path to a cell from which it can be seen and reached, pick it up,
and put it on the nearest reasonable surface with room. Navigation-only agents scout: each goes
to look at the nearest misplaced object no agent has seen yet. An agent with nothing left to do
walks to the nearest cell where standing still cuts no path for the others, and stops.

Everything it does goes through the env's actions and their visibility and reach rules; when an
operation fails at one viewpoint it tries the next. Its per-step sub-tasks and sub-goals are the
demonstrations for imitation learning (``training/demonstrations.py``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from maniskill_tidy.envs.actions import (
    HORIZON_RANGE,
    LOOK,
    MIN_PIXELS,
    Action,
    AgentState,
    Targeted,
    move_target,
)
from maniskill_tidy.envs.robots import robot_kind
from maniskill_tidy.policies.base import (
    EXPLORE,
    PLACE,
    Label,
    PrivilegedTeam,
    PublicInfo,
    SubTask,
)
from maniskill_tidy.policies.navigation import Cell, GridPlanner, move_towards, subgoal
from maniskill_tidy.policies.viewpoints import Viewpoint, viewpoints
from maniskill_tidy.policies.walker import Job, Leg, NoViewpoint, Walker, wait_action

MAX_CANDIDATES = 24  # viewpoints considered per target
RETRIES = 2  # rounds of viewpoints tried for an object before giving it up
SURE_PIXELS = MIN_PIXELS + 10  # margin over the visibility threshold (other robots may occlude)
RESERVED = 4  # cells of a manipulator's path ahead that scouts clear
HORIZONS = range(HORIZON_RANGE[0], HORIZON_RANGE[1] + 1, LOOK)


class ExpertTeam(PrivilegedTeam):
    name = "expert"

    def reset(self, public: PublicInfo, env: Any) -> None:
        if env is None:
            raise ValueError("the expert is privileged: reset() needs the unwrapped env")
        self.env = env
        self.planner = GridPlanner(env.house)
        self.walker = Walker(self.planner)
        self.task = {m.object: m for m in env.episode.task.misplaced}
        self.jobs: dict[str, Job | None] = {a: None for a in public.agents}
        self.attempts: dict[str, int] = {}  # rounds of viewpoints that failed, per object
        self.seen: set[str] = set()
        self._labels: dict[str, Label] = {}
        self._surface_queue: dict[str, list[tuple[str, list[Viewpoint]]]] = {}
        self._trapped: set[Cell] = set()  # scouts that could not step aside last step

    # ------------------------------------------------------------------ acting
    def act(self, info: dict) -> dict[str, Any]:
        """Manipulators plan first and ignore scouts in their way; a scout standing on the next
        cells of a manipulator's path steps aside (this is what breaks corridor deadlocks)."""
        actions = {}
        self._labels = {}
        self._trapped_before, self._trapped = self._trapped, set()
        self._reserved: set[Cell] = set()
        self._entering: set[Cell] = set()  # cells higher-ranked agents move into this step
        ranked = sorted(self.env.agents, key=lambda a: (not a.manipulator, a.name))
        for rank, agent in enumerate(ranked):
            if agent.stopped:
                continue
            self._yielding_to = {a.cell for a in ranked[:rank]} | {
                a.cell for a in ranked if a.stopped
            }
            if agent.cell in self._reserved:
                actions[agent.name] = self._step_aside(agent)
                job = self.jobs.get(agent.name)
                subtask = job.subtask if job is not None else SubTask(EXPLORE)
                act = actions[agent.name]
                path = [agent.cell]
                if act in (Action.MoveAhead, Action.MoveLeft, Action.MoveRight):
                    path.append(move_target(agent, act))
                self._labels[agent.name] = (
                    subtask,
                    subgoal(agent, path, agent.rotation, "NoAction", False),
                )
                continue
            actions[agent.name] = self._act_one(agent, info)
            if actions[agent.name] in (Action.MoveAhead, Action.MoveLeft, Action.MoveRight):
                self._entering.add(move_target(agent, actions[agent.name]))
            job = self.jobs.get(agent.name)
            if job is not None and job.leg.path:
                self._reserved.update([agent.cell, *job.leg.path[:RESERVED]])
        return actions

    def _step_aside(self, agent: AgentState) -> Any:
        """Head for the nearest cell off the reserved paths (passing through them if needed)."""
        occupied = {a.cell for a in self.env.agents if a is not agent} | self._entering
        dist = self.planner.distances(agent.cell, occupied)
        free = [c for c in dist if c not in self._reserved]
        path = (
            self.planner.path(agent.cell, min(free, key=lambda c: (dist[c], c)), occupied)
            if free
            else None
        )
        if not path or len(path) < 2:
            self._trapped.add(agent.cell)  # hemmed in: next step the manipulators go round it
            return wait_action(agent)
        action = move_towards(agent, path[1])
        if action in (Action.MoveAhead, Action.MoveLeft, Action.MoveRight):
            self._entering.add(path[1])
        return action

    def labels(self) -> dict[str, Label]:
        return self._labels

    def _act_one(self, agent: AgentState, info: dict) -> Any:
        job = self.jobs[agent.name]
        if job is not None and job.issued:
            job = self._outcome(agent, job)
        for _ in range(4):  # a finished or impossible job hands over to the next one
            if job is None:
                job = self._allocate(agent)
            self.jobs[agent.name] = job
            others = self._yielding_to | self._reserved | self._entering | self._trapped_before
            others -= {agent.cell}
            stopped = {a.cell for a in self.env.agents if a.stopped}
            if job.kind == "park" and agent.cell == job.leg.candidates[0].cell:
                self._labels[agent.name] = job.label(agent)
                return Action.Stop
            try:
                action = self.walker.step(agent, job.leg, others, stopped)
            except NoViewpoint:
                if job.kind == "pick":
                    self.attempts[job.target] = self.attempts.get(job.target, 0) + 1
                elif job.kind == "look":
                    self.seen.add(job.target)
                job = self._next_place(agent, job) if job.kind == "place" else None
                continue
            self._labels[agent.name] = job.label(agent)
            if action in (Action.MoveAhead, Action.MoveLeft, Action.MoveRight):
                nxt = move_target(agent, action)
                if any(a.cell == nxt for a in self.env.agents if a is not agent):
                    return wait_action(agent)  # a scout is stepping aside
            if action is not None:
                return action
            return self._operate(agent, job)
        # nothing it can do from here (no reachable viewpoint for anything left): stop
        stop = subgoal(agent, [agent.cell], agent.rotation, "NoAction", True)
        self._labels[agent.name] = (SubTask(EXPLORE), stop)
        return Action.Stop

    def _operate(self, agent: AgentState, job: Job) -> Any:
        if job.kind == "park":
            return Action.Stop
        if job.kind == "look":
            self.seen.add(job.target)
            self.jobs[agent.name] = None
            return self._act_one(agent, {"failed": {}})
        job.issued = True
        op = Action.PickUp if job.kind == "pick" else Action.PutDown
        return Targeted(op, job.target)

    def _outcome(self, agent: AgentState, job: Job) -> Job | None:
        if not job.succeeded(agent):
            return job  # try the next viewpoint
        if job.kind == "pick":
            self.seen.add(job.target)
            return self._place_job(agent)
        return None

    # ------------------------------------------------------------------ allocation
    def _allocate(self, agent: AgentState) -> Job:
        if agent.held is not None:
            return self._place_job(agent)
        kind = "pick" if agent.manipulator else "look"
        taken = {j.target for j in self.jobs.values() if j is not None and j.kind == kind}
        held = {a.held for a in self.env.agents if a.held}
        if agent.manipulator:
            reasonable = self._reasonable()
            todo = [
                o
                for o in self.task
                if o not in taken | held | reasonable and self.attempts.get(o, 0) < RETRIES
            ]
            fewest = min((self.attempts.get(o, 0) for o in todo), default=0)
            todo = [o for o in todo if self.attempts.get(o, 0) == fewest]
        else:
            todo = [o for o in self.task if o not in taken | held | self.seen]
        dist = self.planner.distances(agent.cell)
        best = None
        for oid in todo:
            vps = self._viewpoints(agent, self._object_centre(oid))
            d = min((dist[v.cell] for v in vps if v.cell in dist), default=None)
            if d is not None and (best is None or d < best[0]):
                best = (d, oid, vps)
        if best is None:
            return self._park_job(agent)
        _, oid, vps = best
        m = self.task[oid]
        if kind == "look":
            subtask = SubTask(EXPLORE, m.type)
        else:
            first = self._surfaces(oid, agent)
            subtask = self._place_subtask(oid, first[0][0] if first else None)
        sid = self.env.manipulation.seg_of_object[oid]
        leg = Leg(vps, check=lambda vp: self._sees(agent, vp, sid))
        return Job(kind, oid, leg, subtask)

    def _place_job(self, agent: AgentState) -> Job:
        self._surface_queue[agent.name] = self._surfaces(agent.held, agent)
        return self._next_place(agent, None)

    def _next_place(self, agent: AgentState, job: Job | None) -> Job:
        queue = self._surface_queue.get(agent.name, [])
        if not queue:
            return self._park_job(agent)  # nowhere reasonable to go: keep holding it
        target, vps = queue.pop(0)
        leg = Leg(vps, check=lambda vp: self._can_put(agent, vp, target))
        return Job("place", target, leg, self._place_subtask(agent.held, target))

    def _park_job(self, agent: AgentState) -> Job:
        stopped = {a.cell for a in self.env.agents if a.stopped}
        others = {a.cell for a in self.env.agents if a is not agent}
        cell = self.planner.parking(agent.cell, stopped, others)
        leg = Leg([Viewpoint(cell, agent.rotation, agent.horizon, 0.0)])
        return Job("park", "", leg, SubTask(EXPLORE))

    # ------------------------------------------------------------------ privileged views
    def _pitches(self, vp: Viewpoint) -> list[int]:
        return sorted(HORIZONS, key=lambda h: (abs(h - vp.horizon), h))

    def _sees(self, agent: AgentState, vp: Viewpoint, sid: int) -> Viewpoint | None:
        """``vp`` with a camera pitch that shows the object well enough, or None."""
        for h in self._pitches(vp):
            counts, _ = self.env.preview(agent.name, vp.cell, vp.rotation, h)
            if counts.get(sid, 0) >= SURE_PIXELS:
                return Viewpoint(vp.cell, vp.rotation, h, vp.distance)
        return None

    def _can_put(self, agent: AgentState, vp: Viewpoint, target: str) -> Viewpoint | None:
        xy = np.asarray(self.env.house.navgrid.center(*vp.cell))
        for h in self._pitches(vp):
            counts, camera = self.env.preview(agent.name, vp.cell, vp.rotation, h)
            if self.env.manipulation.put_candidates(xy, counts, camera, target):
                return Viewpoint(vp.cell, vp.rotation, h, vp.distance)
        return None

    # ------------------------------------------------------------------ privileged geometry
    def _reasonable(self) -> set[str]:
        return set(self.env.evaluate()["reasonable"])

    def _object_centre(self, oid: str) -> np.ndarray:
        size = self.env.manipulation.sizes[oid]
        return self.env.hs.object_bottom(oid) + [0.0, 0.0, size[2] / 2]

    def _viewpoints(self, agent: AgentState, point: np.ndarray) -> list:
        height = robot_kind(agent.capability).camera_height
        return viewpoints(self.env.house, point, height, side_views=True)[:MAX_CANDIDATES]

    def _surfaces(self, oid: str, agent: AgentState) -> list[tuple[str, list]]:
        """Reasonable surfaces with room for ``oid``, nearest first, with their viewpoints."""
        manip, hs = self.env.manipulation, self.env.hs
        size = manip.sizes[oid]
        dist = self.planner.distances(agent.cell)
        out = []
        for fid, sname in self.task[oid].reasonable:
            f = hs.furniture[fid]
            s = f.surface(sname)
            centre = manip.surface_centre(f, s)
            if manip.free_spot(f, s, size, oid, centre[:2]) is None:
                continue
            vps = self._viewpoints(agent, centre + [0.0, 0.0, 0.02])
            d = min((dist[v.cell] for v in vps if v.cell in dist), default=None)
            if d is not None:
                out.append((d, f"{fid}/{sname}", vps))
        out.sort(key=lambda t: (t[0], t[1]))
        return [(target, vps) for _, target, vps in out]

    def _place_subtask(self, oid: str, target: str | None) -> SubTask:
        m = self.task[oid]
        if target is None:
            return SubTask(PLACE, m.type)
        fid, _, sname = target.partition("/")
        f = self.env.hs.furniture[fid]
        return SubTask(
            PLACE, m.type, f.surface(sname).receptacle_type, self.env.hs.room_type[f.room]
        )
