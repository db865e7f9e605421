"""The pixels track: any camera-only team, seeing through a learned segmenter.

A pixels agent receives RGB, depth, its pose and camera matrices, whether it holds something,
and nothing else: no segmentation, no instance id (DESIGN.md, "Perception tracks"; the runner
enforces it, ``eval/episode.py``). :class:`PixelsAgent` wraps the team's own agent and gives it
what it would read in the ground-truth track, made from the agent's own frame alone:

- a segmentation image of ids from the agent's *own* label table, made before the episode
  (the maps build their label table once): floor, wall, ceiling and robot by class only;
  each piece of furniture of the public floor plan (its id is public); and per pickupable type
  a block of slots for the objects this agent comes to track;
- masks from the segmenter (``models/segmenter.py``), instances from masks split at depth
  jumps (``perception/instances.py``), furniture named by the nearest piece of its type on the
  floor plan; objects' masks from what the floor plan does not explain (the pixels whose point
  rests on a known surface or the floor, ``perception/object_space.py``), typed by the
  segmenter's votes, and from the segmenter's own object masks where the plan explains the
  pixels (flat objects), refined from its grid to the frame's pixels with depth's guidance;
  objects associated across frames by type and position (``perception/tracks.py``);
- ``held``: the slot of the object its last successful PickUp aimed at.

Its PickUp and PutDown targets become a pixel of the current frame (the env resolves it,
``targets="pixels"``): the pixel of the named object's mask nearest the mask's middle, or for a
surface, the pixel of that furniture's mask nearest where the surface's centre projects (the
env tries the piece's surfaces in that order; of the pixels the labels were made at, off the
mask's rim where it can). An object
the segmenter missed this frame is aimed at where its track lies, if the frame shows that spot
in clear view within reach; a target not in view is aimed at no pixel (the env names the
failure, as for an id not in view). A PickUp
whose pixel showed no object at all (the env's failure says so, as a gripper closing on nothing
would), or that failed twice at a pixel of the frame for another reason than the distance,
refutes the track it aimed at: that track's masks are no longer shown to the team, and the
team's agent forgets the object (``HeuristicAgent.forget``). So
does looking: a track whose spot the frame showed in clear view within the arm's reach, and
whose object the segmenter did not find there more often than it did (``MISSES``), is taken
for a false detection made from afar (a multi-object tracker's deletion after missed
detections, counted only where the object could not have hidden).
"""

from __future__ import annotations

import dataclasses
import functools
import time
from collections import Counter
from typing import ClassVar

import numpy as np
from scipy import ndimage

from maniskill_tidy.envs.actions import MIN_PIXELS, NOTHING_DRAWN, Action, Targeted
from maniskill_tidy.perception.instances import Mask2D, coarse, scored_by_relief, split_instances
from maniskill_tidy.perception.object_space import ObjectSpace, frame_objects, unexplained
from maniskill_tidy.perception.seg_classes import STRUCTURE, seg_classes
from maniskill_tidy.perception.tracks import (
    Tracker,
    back_project,
    camera_position,
    clear_view,
    coarse_intrinsics,
    mask_positions,
    project,
)
from maniskill_tidy.policies.base import Agent, AgentView, PublicInfo, Team
from maniskill_tidy.policies.channel import Outbox
from maniskill_tidy.sim.house_scene import Instance

SLOTS = 48  # objects one agent may track per pickupable type
FURNITURE_BASE = 16
OBJECT_BASE = 1024
FURNITURE_MATCH = 1.0  # metres from a mask's point to the nearest footprint of its type
HOLD_RANGE = 0.8  # metres from the camera: a mask of the held type this close is the held one
OWN_BODY = 0.45  # metres (horizontal) from the camera: a robot this close is the agent itself
# an object mask this confident continues a track; to start one it needs the card's threshold
KEEP_THRESHOLD = 0.6
REAIM = 0.6  # metres: a PickUp of an object out of view takes one of its type this close
CONFIRM = 2  # frames an object must be seen in before the team is shown it
FAILS = 2  # PickUps failed at a pixel of the frame (not for the distance) that refute its track
# a track whose spot was in clear view this close (metres: the arm's reach) and yet unseen
# this many times, more often than seen there, is refuted: a false detection seen from afar
VERIFY_RANGE = 1.5
MISSES = 2
PIXELS_OBSERVATION = "rgb+depth"
# The name of how pixels agents turn the segmenter's labels into what their team reads, once it
# changed on purpose (absent from a run's files: as first played): pixels runs record it, a
# run begun under another is not resumed, and the leaderboard marks it. "refined-masks":
# object masks refined to the frame's pixels with depth's guidance (``instances.refined``),
# from 2026-12-06; "floor-plan": objects' masks also from what the floor plan does not explain
# (``perception/object_space.py``), typed by the segmenter's votes, from 2026-12-07.
PIXELS_PIPELINE = "floor-plan"
# A mask of what the floor plan does not explain starts a track at this score (the share of its
# pixels the segmenter calls one pickupable type) and keeps one at the lower: the best-F1 score
# of such masks on v2 val frames, and the same ratio to it as KEEP_THRESHOLD to the card's
# (``docs/research/probes/floor_plan_masks.py``)
PLAN_START = 0.45
PLAN_KEEP = 0.35
# a segmenter's object mask with this share of its cells unexplained by the floor plan is left
# to the floor plan's mask there; the others (flat objects: a CD, a card) keep their own
PLAN_COVERED = 0.5
# metres from a furniture mask's point: a second piece of its type this close, and the mask is
# named cell by cell (one mask may cover both); else the whole mask is the nearest piece's
SPLIT_RANGE = 2.0


def footprint_distance(xy: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Horizontal metres from each point (N, 2) to each footprint (P, 4: x0 y0 x1 y1), 0
    inside: (N, P)."""
    dx = np.maximum(np.maximum(boxes[None, :, 0] - xy[:, :1], 0), xy[:, :1] - boxes[None, :, 2])
    dy = np.maximum(np.maximum(boxes[None, :, 1] - xy[:, 1:], 0), xy[:, 1:] - boxes[None, :, 3])
    return np.hypot(dx, dy)


class Segmenter:
    """The shipped weights of one look, loaded once per process and shared by its agents."""

    _loaded: ClassVar[dict] = {}

    def __init__(self, folder: str) -> None:
        from maniskill_tidy.models.checkpoints import served_segmenter

        if folder not in self._loaded:  # the threads the renderer may use in this process
            self._loaded[folder] = served_segmenter(folder, render_threads())
        self.runtime, self.sha256, card = self._loaded[folder]
        self.threshold = start_threshold(card)
        # seconds spent per stage and frames seen in this process (``bench --only teams``)
        self.seconds = {"segmenter": 0.0, "instances": 0.0, "labels": 0.0}
        self.frames = 0
        self.pending: dict[str, tuple[np.ndarray, np.ndarray]] = {}

    def batch(self, frames: dict[str, tuple[np.ndarray, np.ndarray]]) -> None:
        """Segment the step's frames of every agent in one call (``PixelsTeam.prepare``); each
        frame's labels depend on that frame alone, and only its agent takes them."""
        if not frames:
            return
        start = time.perf_counter()
        names = list(frames)
        rgb = np.stack([np.asarray(frames[n][0]) for n in names])
        depth = np.stack([frames[n][1] for n in names])
        labels, probs = self.runtime(rgb, depth)
        self.pending = {n: (labels[i], probs[i]) for i, n in enumerate(names)}
        self.seconds["segmenter"] += time.perf_counter() - start
        self.frames += len(names)

    def __call__(self, name: str, rgb: np.ndarray, depth: np.ndarray):
        """Agent ``name``'s labels and confidence: from this step's batch, else on its own."""
        if name in self.pending:
            return self.pending.pop(name)
        start = time.perf_counter()
        labels, probs = self.runtime(rgb[None], depth.reshape(1, *depth.shape[:2]))
        self.seconds["segmenter"] += time.perf_counter() - start
        self.frames += 1
        return labels[0], probs[0]


def start_threshold(card: dict) -> float:
    """The score an object mask needs to start a track: the card's, chosen on val (0 for a
    card that chose none)."""
    chosen = card.get("agent_threshold")
    return float(chosen["threshold"]) if chosen else 0.0


def render_threads() -> int:
    """As many threads as the renderer may take here: a worker's share (LP_NUM_THREADS, set by
    ``common/parallel.py``), else every core this process may run on."""
    import os

    from maniskill_tidy.common.parallel import worker_threads

    return max(1, int(os.environ.get("LP_NUM_THREADS") or worker_threads(1)))


def frame_arrays(obs: dict) -> tuple[np.ndarray, np.ndarray]:
    """An observation's RGB and its depth as an (H, W) float32 image in metres."""
    depth = np.asarray(obs["depth"], dtype=np.float32).reshape(obs["rgb"].shape[:2])
    return np.asarray(obs["rgb"]), depth


class LabelTable:
    """One agent's segmentation ids and what each names, fixed before the episode starts."""

    def __init__(self, public: PublicInfo) -> None:
        c = seg_classes()
        self.classes = c
        self.instances: dict[int, Instance] = {}
        self.structure = {}
        for i, kind in enumerate(STRUCTURE, start=1):
            self.structure[c.index[kind]] = i
            self.instances[i] = Instance(i, kind, kind.capitalize(), kind)
        self.furniture = {}  # furniture id -> seg id
        for i, f in enumerate(public.house.furniture):
            sid = FURNITURE_BASE + i
            self.furniture[f.id] = sid
            self.instances[sid] = Instance(sid, "furniture", f.type, f.id)
        self.slots = {t: 0 for t in c.pickupable}  # next free slot per type
        for k, t in enumerate(c.pickupable):
            for slot in range(SLOTS):
                sid = OBJECT_BASE + k * SLOTS + slot
                self.instances[sid] = Instance(sid, "object", t, f"{t}#{slot}")
        self.by_track: dict[int, int] = {}  # track id -> seg id
        self.by_id = {inst.id: sid for sid, inst in self.instances.items()}

    def tracks_of(self, sid: int) -> list[int]:
        """The tracks shown under slot ``sid`` (one, or none; the latest last)."""
        return [t for t, s in self.by_track.items() if s == sid]

    def object_id(self, track) -> int:
        """The slot of a track: a new one for a new track, or when its type changed (its
        sightings voted otherwise); the oldest of the type reused when all are taken."""
        t = self.classes.names[track.cls]
        sid = self.by_track.get(track.id)
        if sid is None or self.instances[sid].type != t:
            k = self.classes.pickupable.index(t)
            slot = self.slots[t] % SLOTS
            self.slots[t] += 1
            sid = OBJECT_BASE + k * SLOTS + slot
            self.by_track = {tid: s for tid, s in self.by_track.items() if s != sid}
            self.by_track[track.id] = sid
        return self.by_track[track.id]


@functools.cache
def mask_classes() -> tuple[list[int], np.ndarray, list[int]]:
    """The classes instances are made of (robots, furniture, pickupable types), per class id
    (256) whether it is a pickupable type, and the pickupable class ids."""
    c = seg_classes()
    objects = np.zeros(256, bool)
    objects[[i for i in range(1, len(c.names)) if c.is_pickupable(i)]] = True
    classes = [i for i, n in enumerate(c.names)
               if n == "robot" or n.startswith("furniture:") or objects[i]]  # fmt: skip
    return classes, objects, np.flatnonzero(objects).tolist()


def find_masks(space: ObjectSpace, labels: np.ndarray, probs: np.ndarray, depth: np.ndarray,
               intrinsics, extrinsics, threshold: float,
               ) -> tuple[list[Mask2D], list[Mask2D], list[float]]:  # fmt: skip
    """One frame's masks as a pixels agent makes them: every instance mask of the segmenter's
    labels on its grid (robots, furniture, objects), and the object masks at the frame's
    resolution (``object_space.frame_objects``) with the score each needs to start a track.
    ``threshold``: the segmenter card's start score for its own object masks."""
    classes, objects, object_ids = mask_classes()
    grid = depth.shape[0] // labels.shape[0]
    depth_g = coarse(depth, grid)
    masks = split_instances(labels, depth_g, classes, probs, -(-MIN_PIXELS // grid**2))
    masks = scored_by_relief(masks, depth_g, object_ids)
    free = unexplained(space, depth, intrinsics, extrinsics)
    found, thresholds = frame_objects(
        masks, free, depth, labels, probs, objects,
        keep=min(KEEP_THRESHOLD, threshold), start=threshold,
        plan_keep=PLAN_KEEP, plan_start=PLAN_START, covered=PLAN_COVERED, min_pixels=MIN_PIXELS,
    )  # fmt: skip
    return masks, found, thresholds


class PixelsAgent(Agent):
    """A camera-only agent seeing through the segmenter (see the module's docstring)."""

    def __init__(self, inner_factory, name: str, public: PublicInfo, outbox: Outbox,
                 segmenter: Segmenter) -> None:  # fmt: skip
        super().__init__(name, public, outbox)
        self.table = LabelTable(public)
        self.segmenter, self.tracker = segmenter, Tracker()
        own = dataclasses.replace(public, instances=self.table.instances)
        self.inner = inner_factory(name, own, outbox)
        self.decide_every = self.inner.decide_every
        self.house = public.house
        c = self.table.classes
        self.furniture_by_id = public.house.furniture_by_id()
        self.space = ObjectSpace(public.house)
        pieces: dict[str, list] = {}
        for f in public.house.furniture:
            pieces.setdefault(f.type, []).append((f.id, f.footprint()))
        # furniture type -> (ids, footprints (n, 4): x0 y0 x1 y1)
        self.footprints = {t: ([fid for fid, _ in ps], np.array([fp for _, fp in ps], float))
                           for t, ps in pieces.items()}  # fmt: skip
        self.structure_ids = np.zeros(256, dtype=np.int32)  # class -> id (robots by mask)
        for cls, sid in self.table.structure.items():
            if c.names[cls] != "robot":
                self.structure_ids[cls] = sid
        self.held = 0  # seg id of what this agent believes it holds
        self.seg = None  # this frame's predicted ids
        self.grid = 2  # frame pixels per cell of the segmenter's labels, each way
        self.points = None  # this frame's back-projection inputs
        self.aimed: int | None = None  # the seg id of the last PickUp's target
        # whether that PickUp named a pixel of the frame: one aimed at no pixel (its target out
        # of view) failed for want of a view, which says nothing of the track
        self.aimed_in_frame = False
        self.refuted: set[int] = set()  # tracks a PickUp found nothing at: no object there
        self.newly_refuted: list[int] = []  # refuted this step, for the team's agent to forget
        self.fails: Counter = Counter()  # track -> PickUps aimed at it that failed
        self.in_frame: dict[int, tuple] = {}  # this frame's object slots: (class, position)

    # ------------------------------------------------------------------ perception
    def _frame(self, obs: dict, step: int) -> np.ndarray:
        """This frame's segmentation image in the agent's own ids. Masks are made and named
        on the segmenter's grid (every other pixel: its labels' resolution), with the depth and
        camera matrix of that grid, and the image upsampled by nearest neighbour; object masks
        are made at the frame's resolution (``object_space.frame_objects``: what the floor
        plan does not explain, and the segmenter's own masks refined with depth's guidance
        where it does), and located and tracked there."""
        c, table = self.table.classes, self.table
        rgb, depth = frame_arrays(obs)
        labels, probs = self.segmenter(self.name, rgb, depth)
        self.grid = grid = depth.shape[0] // labels.shape[0]
        depth_g = coarse(depth, grid)
        seg = self.structure_ids[labels]
        robot = c.index["robot"]
        K, E = coarse_intrinsics(obs["intrinsics"], grid), obs["extrinsics"]
        camera = camera_position(E)
        start = time.perf_counter()
        masks, found, thresholds = find_masks(
            self.space, labels, probs, depth, obs["intrinsics"], E, self.segmenter.threshold
        )
        named = time.perf_counter()
        self.segmenter.seconds["instances"] += named - start
        objects, starts = [], []
        for m, p, t in zip(found, mask_positions(found, depth, obs["intrinsics"], E), thresholds,
                           strict=True):  # fmt: skip
            if p is not None:
                objects.append((m, p))
                starts.append(m.score >= t)
        rest = [m for m in masks if not c.is_pickupable(m.cls)]
        for m, p in zip(rest, mask_positions(rest, depth_g, K, E), strict=True):
            if p is None:
                continue
            if m.cls == robot:
                if np.hypot(*(p - camera)[:2]) > OWN_BODY:  # not its own base
                    m.paint(seg, table.structure[robot])
            else:
                self._paint_furniture(m, c.names[m.cls].split(":", 1)[1], p, seg, depth_g, K, E)
        self.in_frame = {}
        located = self.tracker.update(objects, step, starts)
        for t in self.tracker.looked_at(step, depth_g, K, E, VERIFY_RANGE):
            if (
                t.sightings >= CONFIRM
                and t.missed_clear >= MISSES
                and t.missed_clear > t.seen_clear
            ):
                self._refute(t.id)
        seg = np.repeat(np.repeat(seg, grid, axis=0), grid, axis=1)
        for m, p, track in located:
            if track.id in self.refuted or track.sightings < CONFIRM:
                continue  # still tracked, so its sightings stay explained
            sid = table.object_id(track)
            if self.held and self._is_held(m, p, camera):
                sid = self.held
            m.paint(seg, sid)
            self.in_frame[sid] = (m.cls, p)
        self.points = (depth, obs["intrinsics"], E)
        self.segmenter.seconds["labels"] += time.perf_counter() - named
        return seg

    def _paint_furniture(self, m, type_name: str, p, seg, depth, K, E) -> None:
        """Name a furniture mask by the floor plan: the piece of its type nearest it, or where
        another piece of that type lies near it too, each cell by the piece nearest its own
        point (two counters side by side make one mask of one class: each must keep its own
        pixels, or PutDown finds only one of them in view)."""
        ids, boxes = self.footprints.get(type_name, ((), None))
        if not ids:
            return
        near = footprint_distance(p[None, :2], boxes)[0]
        if (near <= SPLIT_RANGE).sum() < 2:
            if near.min() <= FURNITURE_MATCH:
                m.paint(seg, self.table.furniture[ids[int(near.argmin())]])
            return
        w = m.window
        rows, cols = np.nonzero(m.mask[w])
        rows, cols = rows + (w[0].start or 0), cols + (w[1].start or 0)
        dist = footprint_distance(back_project(rows, cols, depth, K, E)[:, :2], boxes)
        nearest = dist.argmin(axis=1)
        ok = dist[np.arange(len(nearest)), nearest] <= FURNITURE_MATCH
        sids = np.array([self.table.furniture[fid] for fid in ids])
        seg[rows[ok], cols[ok]] = sids[nearest[ok]]

    def _is_held(self, m, p: np.ndarray, camera: np.ndarray) -> bool:
        """A mask of the held type seen this close to the camera is the held object."""
        held_type = self.table.instances[self.held].type
        if self.table.classes.names[m.cls] != held_type:
            return False
        return float(np.linalg.norm(p - camera)) <= HOLD_RANGE

    def _refute(self, track: int) -> None:
        if track not in self.refuted:
            self.refuted.add(track)
            self.newly_refuted.append(track)

    def observe(self, view: AgentView) -> None:
        if self.aimed is not None and not view.failed:  # the last PickUp took what it aimed at
            self.held = self.aimed
        elif self.aimed is not None and self.aimed_in_frame and "out of reach" not in view.failed:
            # failed at a pixel of the frame, and not for the distance: the track is in doubt
            for t in self.table.tracks_of(self.aimed):
                self.fails[t] += 1
                # its pixel showed no object, or it failed again: a false detection
                if view.failed.endswith(f"no object {NOTHING_DRAWN}") or self.fails[t] >= FAILS:
                    self._refute(t)
        if not int(view.obs.get("held", 0)):
            self.held = 0
        self.aimed = None
        self.seg = self._frame(view.obs, view.step)
        self._take_back(self.newly_refuted)
        self.newly_refuted = []
        obs = dict(view.obs, segmentation=self.seg, held=np.int32(self.held))
        self.inner.observe(dataclasses.replace(view, obs=obs))

    def _take_back(self, tracks: list[int]) -> None:
        """Tell the team's agent which objects it was shown are refuted (if it can forget one:
        ``HeuristicAgent.forget``), so that it stops fetching what is not there."""
        forget = getattr(self.inner, "forget", None)
        for t in tracks if forget is not None else ():
            sid = self.table.by_track.get(t)
            if sid is not None:
                forget(self.table.instances[sid].id)

    # ------------------------------------------------------------------ acting
    def send(self, round: int, inbox) -> None:
        self.inner.send(round, inbox)

    def act(self, inbox) -> object:
        return self._aim(self.inner.act(inbox))

    def _aim(self, action):
        if not isinstance(action, Targeted):
            if action == Action.PickUp:  # plain: the env takes the object covering most pixels
                self.aimed = self._largest_object()
                self.aimed_in_frame = self.aimed is not None
            return action
        if action.action == Action.PickUp:
            sid = self._in_view(self.table.by_id.get(action.target))
            self.aimed = sid
            pixel = self._pixel(sid)
            pixel = pixel if pixel != (-1, -1) else self._recalled(sid)
            self.aimed_in_frame = pixel != (-1, -1)
            return Targeted(action.action, pixel)
        fid, _, surface = str(action.target).partition("/")
        return Targeted(action.action, self._pixel(self.table.furniture.get(fid), surface, fid))

    def _in_view(self, sid: int | None) -> int | None:
        """``sid`` if this frame shows it, else the object of its type shown nearest where its
        track lies (within ``REAIM``): the same object seen as another track this time."""
        if sid is None or sid in self.in_frame:
            return sid
        tracks = self.table.tracks_of(sid)
        if not tracks:
            return sid
        track = self.tracker.tracks[tracks[-1]]
        best, dist = sid, REAIM
        for other, (cls, p) in self.in_frame.items():
            d = float(np.linalg.norm(p - track.position))
            if cls == track.cls and d <= dist:
                best, dist = other, d
        return best

    def _recalled(self, sid: int | None) -> tuple[int, int]:
        """The pixel where the frame shows the spot of ``sid``'s track in clear view within
        reach, though the segmenter found no mask of it this time; (-1, -1) if it shows none.
        The gripper then closes on whatever lies there: the object, or nothing (which refutes
        the track, as for any PickUp whose pixel showed no object)."""
        tracks = self.table.tracks_of(sid) if sid is not None else []
        if not tracks or tracks[-1] in self.refuted or self.points is None:
            return (-1, -1)
        depth, K, E = self.points
        where = self.tracker.tracks[tracks[-1]].position[None]
        if not clear_view(where, depth, K, E, VERIFY_RANGE)[0]:
            return (-1, -1)
        u, v, _, _ = project(where, K, E)
        return int(u[0]), int(v[0])

    def _largest_object(self) -> int | None:
        ids, counts = np.unique(self.seg[self.seg >= OBJECT_BASE], return_counts=True)
        return int(ids[np.argmax(counts)]) if len(ids) else None

    def _pixel(self, sid: int | None, surface: str = "", fid: str = "") -> tuple[int, int]:
        """A pixel of ``sid``'s mask in this frame: nearest its middle, or for a surface, the
        one nearest where the surface's centre projects; (-1, -1) if it is not in view. Only
        the pixels the labels were made at (for furniture a cell's first, for an object any of
        its refined mask), and of those the mask's inner ones where it has any: a cell's other
        pixels, and a mask's rim, may show what lies beside it (an object on the table, the
        floor behind), where the env would find no target."""
        if sid is None or self.seg is None:
            return (-1, -1)
        g = 1 if sid >= OBJECT_BASE else self.grid
        cells = self.seg[::g, ::g] == sid
        inner = ndimage.binary_erosion(cells)
        rows, cols = np.nonzero(inner if inner.any() else cells)
        if not len(rows):
            return (-1, -1)
        rows, cols = rows * g, cols * g
        if surface:
            # the env tries the piece's surfaces whose centre projects nearest the pixel
            # first: aim where this one's centre projects (floor plan), else at its point
            f = self.furniture_by_id[fid]
            centre = np.asarray(f.surface_world(f.surface(surface))[0]) + [0.0, 0.0, 0.02]
            depth, K, E = self.points
            u, v, z, _ = project(centre[None], K, E)
            if z[0] > 0:
                k = int(np.argmin((cols - u[0]) ** 2 + (rows - v[0]) ** 2))
            else:
                pts = back_project(rows, cols, depth, K, E)
                k = int(np.argmin(np.linalg.norm(pts - centre, axis=1)))
        else:
            k = int(np.argmin((rows - rows.mean()) ** 2 + (cols - cols.mean()) ** 2))
        return int(cols[k]), int(rows[k])

    def label(self):
        return self.inner.label()

    def trace(self) -> dict:
        return self.inner.trace()


def pixels_perception(own: str) -> str:
    """A camera-only team's perception in the pixels track: its own words, its ground-truth
    segmentation replaced by the predicted masks (the weights' sha256 is the run's
    ``segmentation`` field)."""
    return "learned segmenter from RGB-D and the floor plan (pixels track); " + own.replace(
        "ground-truth segmentation", "predicted masks"
    )


class PixelsTeam(Team):
    """``inner`` (a camera-only team) in the pixels track, with the segmenter in ``weights``."""

    observations: ClassVar[str] = PIXELS_OBSERVATION
    targets: ClassVar[str] = "pixels"
    pixels: ClassVar[bool] = True

    def __init__(self, inner: Team, weights: str) -> None:
        if inner.privileged or not inner.needs_images:
            raise ValueError(f"{inner.name}: only a camera-only team plays the pixels track")
        self.inner, self.segmenter = inner, Segmenter(weights)
        self.name = inner.name
        for attr in ("communication", "central", "rounds", "team_override", "rules"):
            setattr(self, attr, getattr(inner, attr))
        self.perception = pixels_perception(inner.perception)

    def make_agent(self, name: str, public: PublicInfo, outbox: Outbox) -> Agent:
        return PixelsAgent(self.inner.make_agent, name, public, outbox, self.segmenter)

    def prepare(self, observations: dict[str, dict]) -> None:
        """Before the agents observe: their frames through the segmenter in one batch (each
        output depends on its own frame only, and goes to its own agent alone)."""
        self.segmenter.batch({n: frame_arrays(o) for n, o in observations.items()})

    def make_central(self, public: PublicInfo, outbox: Outbox):
        return self.inner.make_central(public, outbox)
