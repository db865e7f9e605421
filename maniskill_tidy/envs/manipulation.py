"""PickUp, PutDown and Drop on a built house (rules in ``envs/actions.py``); where objects lie."""

from __future__ import annotations

import math
from collections import Counter

import numpy as np
import sapien

from maniskill_tidy.envs.actions import MIN_PIXELS, NO_ROOM, REACH, AgentState
from maniskill_tidy.houses.furnish import GAP, overlaps
from maniskill_tidy.houses.objects import is_hanging, stacked_footprints
from maniskill_tidy.houses.schema import Furniture, Surface, rotated_bounds
from maniskill_tidy.knowledge import FLOOR
from maniskill_tidy.sim.house_scene import HouseScene, ObjectState, yaw_quat

SPOT_STEP = 0.04  # metres between candidate spots on a surface
ON_SURFACE = 0.06  # an object whose bottom is this close to a surface rests on it


class Manipulation:
    def __init__(self, hs: HouseScene) -> None:
        self.hs = hs
        self.sizes = {o.id: o.size for o in hs.house.objects}
        self.types = {o.id: o.type for o in hs.house.objects}
        self.seg_of_object = {i.id: sid for sid, i in hs.instances.items() if i.kind == "object"}
        self.stacked = stacked_footprints(hs.house)  # a plant on a dresser takes room there
        self.furniture_of_seg: dict[int, str] = {}
        self.link_of_seg: dict[int, str] = {}
        for sid, inst in hs.instances.items():
            if inst.kind == "furniture":
                fid, _, link = inst.id.partition("/")
                self.furniture_of_seg[sid] = fid
                self.link_of_seg[sid] = link or "body"

    # ------------------------------------------------------------------ PickUp
    def pick_up(
        self, agent: AgentState, xy: np.ndarray, counts: Counter, target: str | None
    ) -> str | None:
        if agent.held is not None:
            return f"already holding {agent.held}"
        candidates = []
        for oid, sid in self.seg_of_object.items():
            if target is not None and oid != target:
                continue
            state = self.hs.state[oid]
            if state.receptacle == "held":
                continue
            pixels = counts.get(sid, 0)
            dist = float(np.linalg.norm(self._centre(oid)[:2] - xy))
            candidates.append((pixels, -dist, oid))
        if target is not None and not candidates:
            known = target in self.seg_of_object
            return (
                f"{target} is held by another agent"
                if known
                else f"no object {target!r} in this house"
            )
        visible = [c for c in candidates if c[0] >= MIN_PIXELS]
        if not visible:
            return f"{target} is not visible" if target else "no object in view"
        in_reach = [c for c in visible if -c[1] <= REACH]
        if not in_reach:
            best = max(visible)
            return f"{best[2]} is out of reach ({-best[1]:.2f} m > {REACH} m)"
        oid = max(in_reach)[2]
        agent.held = oid
        self.hs.state[oid] = ObjectState("held", None, None, holder=agent.name)
        self.hs.bodies[oid].kinematic = True
        return None

    def carry(
        self, agent: AgentState, robot: sapien.Pose, hold_offset: tuple[float, float]
    ) -> None:
        """Keep a held object in the gripper."""
        if agent.held is None:
            return
        yaw = math.radians(agent.rotation)
        ahead, z = hold_offset
        size = self.sizes[agent.held]
        x = robot.p[0] + math.cos(yaw) * (ahead + 0.02)
        y = robot.p[1] + math.sin(yaw) * (ahead + 0.02)
        self.hs.objects[agent.held].set_pose(
            sapien.Pose(p=[x, y, z - size[2] / 2], q=yaw_quat(yaw))
        )

    # ------------------------------------------------------------------ PutDown
    def put_down(
        self,
        agent: AgentState,
        xy: np.ndarray,
        counts: Counter,
        camera: tuple[np.ndarray, np.ndarray, int, int],
        target: str | None,
        aim: tuple[int, int] | None = None,
    ) -> str | None:
        """``aim``: a pixel of the frame; the surfaces whose centre projects nearest it are
        tried first (else those nearest the image centre)."""
        if agent.held is None:
            return "holding nothing"
        oid = agent.held
        size = self.sizes[oid]
        if target is not None:
            fid, _, sname = target.partition("/")
            if fid not in self.hs.furniture:
                return f"no furniture {fid!r} in this house"
            f = self.hs.furniture[fid]
            if sname and sname not in [s.name for s in f.surfaces]:
                return f"{fid} has no surface {sname!r}; it has {[s.name for s in f.surfaces]}"
        ranked = self.put_candidates(xy, counts, camera, target, aim)
        if not ranked:
            what = target or "no receptacle surface"
            return (
                f"{what} is not visible within reach" if target else f"{what} visible within reach"
            )
        reasons = []
        for _, f, s in ranked:
            spot = self.free_spot(f, s, size, oid, xy)
            if spot is None:
                reasons.append(f"{f.id}/{s.name}")
                continue
            bottom, yaw = spot
            hanging = is_hanging(s)
            self.hs.bodies[oid].kinematic = hanging
            self.hs.set_object_pose(oid, bottom, yaw)
            agent.held = None
            self.hs.state[oid] = ObjectState(f.id, s.name, f.room)
            fell = [] if hanging else self.hs.settle(watch=[oid])
            if fell:
                self.hs.state[oid] = self.locate(oid)
                return f"{oid} was not stable on {f.id}/{s.name} and fell"
            return None
        return f"{NO_ROOM} {oid} on " + ", ".join(reasons[:3])

    def put_candidates(
        self,
        xy: np.ndarray,
        counts: Counter,
        camera: tuple[np.ndarray, np.ndarray, int, int],
        target: str | None = None,
        aim: tuple[int, int] | None = None,
    ) -> list[tuple[float, Furniture, Surface]]:
        """Surfaces PutDown would try from here, best first (see the rules in actions.py)."""
        visible_links: dict[tuple[str, str], int] = {}
        for sid, n in counts.items():
            if sid in self.furniture_of_seg and n >= MIN_PIXELS:
                visible_links[(self.furniture_of_seg[sid], self.link_of_seg[sid])] = n
        intrinsic, extrinsic, width, height = camera
        ranked = []
        for f in self.hs.house.furniture:
            if target is not None and f.id != target.partition("/")[0]:
                continue
            for s in f.surfaces:
                if target is not None and target.partition("/")[2] not in ("", s.name):
                    continue
                if (f.id, s.link) not in visible_links and (f.id, "body") not in visible_links:
                    continue
                centre = self.surface_centre(f, s)
                if np.linalg.norm(centre[:2] - xy) > REACH:
                    continue
                uv = project(centre + [0, 0, 0.02], intrinsic, extrinsic)
                if uv is None or not (0 <= uv[0] < width and 0 <= uv[1] < height):
                    continue
                at = (width / 2, height / 2) if aim is None else (aim[0] + 0.5, aim[1] + 0.5)
                ranked.append((math.hypot(uv[0] - at[0], uv[1] - at[1]), f, s))
        ranked.sort(key=lambda r: r[0])
        return ranked

    def surface_centre(self, f: Furniture, s: Surface) -> np.ndarray:
        centre, _ = f.surface_world(s)
        return np.asarray(centre) + self.hs.surface_offset(f, s.link)

    def free_spot(
        self, f: Furniture, s: Surface, size: list[float], oid: str, xy: np.ndarray
    ) -> tuple[np.ndarray, float] | None:
        """The free pose nearest the robot for an object of ``size`` on ``s``, or None."""
        if s.clearance is not None and size[2] > s.clearance:
            return None
        centre = self.surface_centre(f, s)
        x0, y0, x1, y1 = rotated_bounds(centre[:2], s.size[0], s.size[1], f.yaw)
        others = list(self.stacked.get(f.id, [])) if s.name == "top" else []
        for other, st in self.hs.state.items():
            if other != oid and st.receptacle == f.id and st.surface == s.name:
                p = self.hs.object_bottom(other)
                ow, od, _ = self.sizes[other]
                others.append(rotated_bounds(p[:2], ow, od, self.hs.yaw_of(other)))
        best = None
        for yaw in (f.yaw, f.yaw + math.pi / 2):
            fw, fd = (
                abs(size[0] * math.cos(yaw)) + abs(size[1] * math.sin(yaw)),
                abs(size[0] * math.sin(yaw)) + abs(size[1] * math.cos(yaw)),
            )
            if fw > x1 - x0 + 1e-6 or fd > y1 - y0 + 1e-6:
                continue
            for x in np.arange(x0 + fw / 2, x1 - fw / 2 + 1e-6, SPOT_STEP):
                for y in np.arange(y0 + fd / 2, y1 - fd / 2 + 1e-6, SPOT_STEP):
                    fp = (x - fw / 2, y - fd / 2, x + fw / 2, y + fd / 2)
                    if any(overlaps(fp, o, GAP) for o in others):
                        continue
                    d = math.hypot(x - xy[0], y - xy[1])
                    if best is None or d < best[0] - 1e-9:
                        best = (d, x, y, yaw)
        if best is None:
            return None
        _, x, y, yaw = best
        z = centre[2] - size[2] if is_hanging(s) else centre[2]
        return np.array([x, y, z + 0.002]), yaw

    # ------------------------------------------------------------------ Drop
    def drop(self, agent: AgentState) -> str | None:
        if agent.held is None:
            return "holding nothing"
        oid = agent.held
        agent.held = None
        self.hs.bodies[oid].kinematic = False
        self.hs.settle(watch=[])
        self.hs.state[oid] = self.locate(oid)
        return None

    def locate(self, oid: str) -> ObjectState:
        """Where an object came to rest: the surface under it, the floor, or nowhere known."""
        p = self.hs.object_bottom(oid)
        if p[2] < ON_SURFACE / 2:
            return ObjectState(FLOOR, None, self.hs.house.room_at(p[0], p[1]))
        for f in self.hs.house.furniture:
            for s in f.surfaces:
                c = self.surface_centre(f, s)
                x0, y0, x1, y1 = rotated_bounds(c[:2], s.size[0], s.size[1], f.yaw)
                if x0 <= p[0] <= x1 and y0 <= p[1] <= y1 and abs(p[2] - c[2]) < ON_SURFACE:
                    return ObjectState(f.id, s.name, f.room)
        return ObjectState("unknown", None, None)

    def _centre(self, oid: str) -> np.ndarray:
        p = self.hs.object_bottom(oid)
        return p + [0.0, 0.0, self.sizes[oid][2] / 2]


def project(point: np.ndarray, intrinsic: np.ndarray, extrinsic: np.ndarray) -> np.ndarray | None:
    """Pixel (u, v) of a world point for an OpenCV camera, or None behind it."""
    p = extrinsic[:3, :3] @ point + extrinsic[:3, 3]
    if p[2] <= 1e-6:
        return None
    uv = intrinsic @ (p / p[2])
    return uv[:2]
