"""Objects associated across one agent's frames by type and position (the pixels track).

With ground truth, an object's segmentation id names it in every frame. A segmenter gives
per-frame masks with a class and nothing more, so an agent that remembers objects must decide
itself which mask of this frame is which object seen before: here, the nearest track whose
position lies within :data:`RADIUS` of the mask's back-projected median, a track of another
type only within ``RADIUS - CLASS_PENALTY`` (each track matched once per frame, cheapest pairs
first), else a new track. A track's type is the one its sightings voted for most (each vote
the mask's score): a segmenter unsure between two types in one frame is outvoted by the
others, where a track per type would keep both. Track ids are the agent's own labels
(1, 2, ...): they carry no origin and mean nothing to another agent.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit

from maniskill_tidy.perception.instances import Mask2D
from maniskill_tidy.perception.semantic_map import open3d_intrinsics, open3d_pose

RADIUS = 0.3  # metres: one object's sightings fall this close together
CLASS_PENALTY = 0.15  # metres added to the distance from a track of another type


@dataclass
class Track:
    id: int
    position: np.ndarray  # world (x, y, z): the mean of its sightings' medians
    sightings: int
    last_step: int
    votes: dict[int, float] = field(default_factory=dict)  # class -> summed scores
    # frames that showed its position in clear view (:meth:`Tracker.looked_at`): with a
    # sighting of it, and without
    seen_clear: int = 0
    missed_clear: int = 0

    @property
    def cls(self) -> int:
        """The type most of its sightings voted for (the first seen on a tie)."""
        return max(self.votes, key=self.votes.__getitem__)


def camera_position(extrinsics) -> np.ndarray:
    """The camera's centre in the world, from its world-to-camera extrinsics (3 x 4 or 4 x 4)."""
    E = np.asarray(extrinsics, dtype=np.float64)
    return -E[:3, :3].T @ E[:3, 3]


def coarse_intrinsics(intrinsics, step: int) -> np.ndarray:
    """The pinhole matrix of an image keeping every ``step``-th pixel from the first: its pixel
    u is pixel ``step`` * u of the full image, whose centre (the renderer puts pixel u's at
    u + 0.5) lies at u + 0.5 / ``step`` in the coarse image's units."""
    K = np.array(intrinsics, dtype=np.float64)
    K[:2] /= step
    K[:2, 2] += 0.5 - 0.5 / step
    return K


def mask_position(
    mask: np.ndarray | Mask2D, depth: np.ndarray, intrinsics, extrinsics
) -> np.ndarray | None:
    """The median world point of a mask's pixels with a depth (None if none has one); a
    :class:`Mask2D` is looked at inside its box only."""
    d = depth.reshape(depth.shape[:2])
    window = mask.window if isinstance(mask, Mask2D) else (slice(None), slice(None))
    mask = mask.mask if isinstance(mask, Mask2D) else mask
    rows, cols = np.nonzero(mask[window] & (d[window] > 0))
    if not len(rows):
        return None
    rows = rows + (window[0].start or 0)
    cols = cols + (window[1].start or 0)
    return np.median(back_project(rows, cols, d, intrinsics, extrinsics), axis=0)


def back_project(rows: np.ndarray, cols: np.ndarray, depth: np.ndarray, intrinsics,
                 extrinsics) -> np.ndarray:  # fmt: skip
    """The world points (N, 3) of pixels (``rows``, ``cols``) at their depth, as open3d
    unprojects them (pixel u at u: the maps, the tracks and :func:`project` agree)."""
    d = depth.reshape(depth.shape[:2])
    fx, fy, cx, cy = open3d_intrinsics(intrinsics).astype(np.float64)
    z = d[rows, cols].astype(np.float64)
    camera = np.stack([(cols - cx) * z / fx, (rows - cy) * z / fy, z])
    pose = open3d_pose(extrinsics).astype(np.float64)
    return (pose[:, :3] @ camera + pose[:, 3:]).T


@njit(cache=True, nogil=True)
def _medians(owner, n, depth, fx, fy, cx, cy, pose):
    """Per owner 1..n, the median world point of its pixels with a depth (NaN if none)."""
    h, w = owner.shape
    counts = np.zeros(n + 1, np.int64)
    for r in range(h):
        for c in range(w):
            if owner[r, c] > 0 and depth[r, c] > 0:
                counts[owner[r, c]] += 1
    start = np.zeros(n + 2, np.int64)
    for k in range(1, n + 1):
        start[k + 1] = start[k] + counts[k]
    fill = start.copy()
    points = np.empty((start[n + 1], 3), np.float64)
    for r in range(h):
        for c in range(w):
            k, z = owner[r, c], np.float64(depth[r, c])
            if k == 0 or z <= 0:
                continue
            x, y = (c - cx) * z / fx, (r - cy) * z / fy
            for a in range(3):
                points[fill[k], a] = pose[a, 0] * x + pose[a, 1] * y + pose[a, 2] * z + pose[a, 3]
            fill[k] += 1
    out = np.full((n, 3), np.nan)
    for k in range(1, n + 1):
        if counts[k]:
            for a in range(3):
                out[k - 1, a] = np.median(points[start[k] : start[k + 1], a])
    return out


def mask_positions(
    masks: list[Mask2D], depth: np.ndarray, intrinsics, extrinsics
) -> list[np.ndarray | None]:
    """:func:`mask_position` of each of a frame's masks, which must not overlap (as
    ``split_instances`` makes them), in one compiled pass: one call per mask cost 2 ms per
    agent frame, most of it in ``np.median``'s overhead."""
    d = depth.reshape(depth.shape[:2])
    owner = np.zeros(d.shape, dtype=np.int32)
    for k, m in enumerate(masks, start=1):
        w = m.window
        inside = m.mask[w]
        if owner[w][inside].any():
            raise ValueError(f"mask {k - 1} overlaps an earlier one: expected disjoint masks")
        owner[w][inside] = k
    fx, fy, cx, cy = open3d_intrinsics(intrinsics).astype(np.float64)
    pose = open3d_pose(extrinsics).astype(np.float64)
    found = _medians(owner, len(masks), np.ascontiguousarray(d), fx, fy, cx, cy, pose)
    return [None if np.isnan(p[0]) else p for p in found]


def project(points: np.ndarray, intrinsics, extrinsics) -> tuple[np.ndarray, ...]:
    """World points (N, 3) -> pixel columns and rows (nearest; pixel u lies at u, as
    :func:`mask_position` back-projects), depth along the optical axis and distance from the
    camera. Points behind the camera get column and row -1."""
    E = np.asarray(extrinsics, dtype=np.float64)
    cam = np.asarray(points, dtype=np.float64).reshape(-1, 3) @ E[:3, :3].T + E[:3, 3]
    fx, fy, cx, cy = open3d_intrinsics(intrinsics).astype(np.float64)
    z = cam[:, 2]
    ahead = z > 1e-6
    safe = np.where(ahead, z, 1.0)
    u = np.where(ahead, np.rint(fx * cam[:, 0] / safe + cx), -1).astype(np.int64)
    v = np.where(ahead, np.rint(fy * cam[:, 1] / safe + cy), -1).astype(np.int64)
    return u, v, z, np.linalg.norm(cam, axis=1)


def clear_view(points: np.ndarray, depth: np.ndarray, intrinsics, extrinsics, reach: float,
               margin: int = 2) -> np.ndarray:  # fmt: skip
    """Per world point (N, 3): whether the frame shows it, within ``reach`` metres of the
    camera, ``margin`` pixels inside the border, with nothing more than 0.1 m nearer in front
    of it (the pixel's depth)."""
    u, v, z, dist = project(points, intrinsics, extrinsics)
    d = depth.reshape(depth.shape[:2])
    h, w = d.shape
    inside = (z > 0.2) & (dist <= reach)
    inside &= (u >= margin) & (u < w - margin) & (v >= margin) & (v < h - margin)
    out = np.zeros(len(z), dtype=bool)
    out[inside] = d[v[inside], u[inside]] > z[inside] - 0.1
    return out


class Tracker:
    """One agent's tracks; :meth:`update` with each frame's masks."""

    def __init__(self, radius: float = RADIUS) -> None:
        self.radius = radius
        self.tracks: dict[int, Track] = {}

    def update(
        self, located: list[tuple[Mask2D, np.ndarray]], step: int, starts=None
    ) -> list[tuple[Mask2D, np.ndarray, Track]]:
        """Each mask with its world position (:func:`mask_positions`), with the track it
        continues or starts. ``starts``: per mask, whether it may start a track (default all);
        one that may not and continues none is left out (a detector's hysteresis: a confident
        sighting starts an object, a less confident one only keeps it)."""
        pairs = []  # (cost, mask index, track id) of every admissible match
        tracks = list(self.tracks.values())
        if tracks and located:
            where = np.array([t.position for t in tracks])
            kinds = np.array([t.cls for t in tracks])
            for i, (m, p) in enumerate(located):
                cost = np.linalg.norm(where - p, axis=1) + np.where(kinds == m.cls, 0.0,
                                                                   CLASS_PENALTY)  # fmt: skip
                for j in np.nonzero(cost <= self.radius)[0]:
                    pairs.append((float(cost[j]), i, tracks[j].id))
        matched: dict[int, int] = {}
        taken: set[int] = set()
        for _, i, tid in sorted(pairs):
            if i not in matched and tid not in taken:
                matched[i] = tid
                taken.add(tid)
        out = []
        for i, (m, p) in enumerate(located):
            if i in matched:
                t = self.tracks[matched[i]]
                t.position = (t.position * t.sightings + p) / (t.sightings + 1)
                t.sightings += 1
                t.last_step = step
            elif starts is None or starts[i]:
                t = Track(len(self.tracks) + 1, p, 1, step)
                self.tracks[t.id] = t
            else:
                continue
            t.votes[m.cls] = t.votes.get(m.cls, 0.0) + max(m.score, 1e-6)
            out.append((m, p, t))
        return out

    def looked_at(self, step: int, depth: np.ndarray, intrinsics, extrinsics,
                  reach: float) -> list[Track]:  # fmt: skip
        """After this step's :meth:`update`: count, for every track whose position this frame
        shows in clear view within ``reach`` (:func:`clear_view`), whether the update saw it.
        A track missed where it should have been seen is evidence that nothing is there (a
        false detection, or an object moved). Returns the tracks missed this time."""
        tracks = list(self.tracks.values())
        if not tracks:
            return []
        shown = clear_view(np.array([t.position for t in tracks]), depth, intrinsics,
                           extrinsics, reach)  # fmt: skip
        missed = []
        for t, clear in zip(tracks, shown, strict=True):
            if not clear:
                continue
            if t.last_step == step:
                t.seen_clear += 1
            else:
                t.missed_clear += 1
                missed.append(t)
        return missed
