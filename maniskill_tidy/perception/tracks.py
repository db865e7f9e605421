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
    fx, fy, cx, cy = open3d_intrinsics(intrinsics).astype(np.float64)
    z = d[rows, cols].astype(np.float64)
    camera = np.stack([(cols - cx) * z / fx, (rows - cy) * z / fy, z])
    pose = open3d_pose(extrinsics).astype(np.float64)
    world = pose[:, :3] @ camera + pose[:, 3:]
    return np.median(world, axis=1)


class Tracker:
    """One agent's tracks; :meth:`update` with each frame's masks."""

    def __init__(self, radius: float = RADIUS) -> None:
        self.radius = radius
        self.tracks: dict[int, Track] = {}

    def update(
        self, masks: list[Mask2D], depth: np.ndarray, intrinsics, extrinsics, step: int
    ) -> list[tuple[Mask2D, Track]]:
        """Each mask with a world position, paired with the track it continues or starts."""
        located = []
        for m in masks:
            p = mask_position(m, depth, intrinsics, extrinsics)
            if p is not None:
                located.append((m, p))
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
            else:
                t = Track(len(self.tracks) + 1, p, 1, step)
                self.tracks[t.id] = t
            t.votes[m.cls] = t.votes.get(m.cls, 0.0) + max(m.score, 1e-6)
            out.append((m, t))
        return out
