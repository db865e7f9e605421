"""Objects as what the floor plan does not explain.

Every agent knows the house's floor plan (``PublicInfo.house``): its rooms, walls and the boxes
and surfaces of its furniture, not where any object lies. So a point of the agent's depth that
rests on a known surface, above its height and inside no other piece's box, or stands on the
floor clear of every piece and wall, is something the floor plan does not hold: an object (or
a robot). This is change detection against a known map, as a robot with a map of its home
would do it; it finds the extent of objects too small or too plain for the segmenter, whose
types then name them (:func:`object_masks`). On 400 v2 val frames (``docs/research/probes/
floor_plan_masks.py``, the int8 graph) such masks, typed by the segmenter's votes, find 0.57
of the objects at their best-F1 score against 0.50 for the segmenter's own masks (AP small 0.41
against 0.29).

Approximations, named: the renderer's depth is exact to its millimetre quantisation, which
lets a 5 mm rise above a surface count (a real depth camera's noise would need more); the
surfaces are the floor plan's rectangles, so parts of a piece's mesh that rise inside its own
surface's rectangle (a tap over a sink) are "unexplained" too, and are left to the segmenter's
votes; articulated parts are taken as closed.
"""

from __future__ import annotations

import numpy as np
from matplotlib.path import Path as PolygonPath
from numba import njit

from maniskill_tidy.houses.schema import House
from maniskill_tidy.perception.instances import Mask2D, coarse, refined, split_instances
from maniskill_tidy.perception.semantic_map import open3d_intrinsics, open3d_pose

CELL = 0.03  # metres: the plan's raster; a cell is a surface's only where it lies wholly on it
RISE = 0.005  # metres above a surface (or the floor) where unexplained points start
OPEN_ABOVE = 0.6  # metres above an open surface (or the floor) where objects may stand
BOX_MARGIN = 0.01  # metres around each piece's box, for its own mesh's slack
WALL_MARGIN = 0.03  # metres beyond a wall's half thickness: skirting, the mesh's slack


class ObjectSpace:
    """Per cell of the floor plan's raster, the heights where an object may be that the plan
    does not explain: intervals ``lo[row, col, k] < z < hi[row, col, k]`` (``k`` over the
    surfaces stacked there, the floor among them; empty slots hold lo = inf)."""

    def __init__(self, house: House, cell: float = CELL) -> None:
        corners = np.array([p for r in house.rooms for p in r.polygon], float).reshape(-1, 2)
        self.cell = cell
        self.origin = corners.min(axis=0, initial=0.0) - cell
        cols, rows = np.ceil((corners.max(axis=0, initial=0.0) + cell - self.origin) / cell)
        self.shape = (int(rows), int(cols)) if len(corners) else (0, 0)  # no rooms: no space
        self.lo = np.full((1, *self.shape), np.inf, np.float32)
        self.hi = np.full((1, *self.shape), -np.inf, np.float32)
        if len(corners):
            self._build(house)
        # built slot by slot, kept (rows, cols, slots): a cell's slots side by side for the lookup
        self.lo = np.ascontiguousarray(self.lo.transpose(1, 2, 0))
        self.hi = np.ascontiguousarray(self.hi.transpose(1, 2, 0))

    def _build(self, house: House) -> None:
        cell = self.cell
        pieces = [(f, self._window(f.footprint(), BOX_MARGIN)) for f in house.furniture]
        for j, f in enumerate(house.furniture):
            for s in f.surfaces:
                win = self._window(f.surface_world(s)[1], 0.0)
                xy = self._centres(win)
                on = self._inside(f, xy, s.size[0] / 2 - cell / 2, s.size[1] / 2 - cell / 2,
                                  s.center[:2])  # fmt: skip
                z = f.position[2] + s.center[2]
                lo = np.where(on, z + RISE, np.inf)
                hi = np.where(on, z + (s.clearance if s.inside else OPEN_ABOVE), -np.inf)
                for g, (other, other_win) in enumerate(pieces):  # pieces standing in that space
                    if g == j or not _overlap(win, other_win):
                        continue
                    box = self._inside(other, xy, other.size[0] / 2 + BOX_MARGIN,
                                       other.size[1] / 2 + BOX_MARGIN)  # fmt: skip
                    g0 = other.position[2] - BOX_MARGIN
                    g1 = other.position[2] + other.size[2] + BOX_MARGIN
                    hi = np.where(box & (g0 > lo), np.minimum(hi, g0), hi)  # its base caps hi
                    lo = np.where(box & (g0 <= lo), np.maximum(lo, g1), lo)  # its top caps lo
                self._add(win, lo, hi)
        whole = (slice(0, self.shape[0]), slice(0, self.shape[1]))
        xy = self._centres(whole)
        floor = np.zeros(self.shape, bool)
        for r in house.rooms:
            floor |= PolygonPath(r.polygon).contains_points(xy.reshape(-1, 2)).reshape(self.shape)
        for f, win in pieces:
            floor[win] &= ~self._inside(f, xy[win], f.size[0] / 2 + BOX_MARGIN + cell / 2,
                                        f.size[1] / 2 + BOX_MARGIN + cell / 2)  # fmt: skip
        for w in house.walls:
            a, b = np.asarray(w.start[:2], float), np.asarray(w.end[:2], float)
            reach = w.thickness / 2 + WALL_MARGIN + cell / 2
            win = self._window((*np.minimum(a, b), *np.maximum(a, b)), reach)
            p = xy[win] - a
            ab = b - a
            t = np.clip(p @ ab / max(float(ab @ ab), 1e-9), 0.0, 1.0)
            floor[win] &= np.linalg.norm(p - t[..., None] * ab, axis=-1) > reach
        self._add(whole, np.where(floor, RISE, np.inf), np.where(floor, OPEN_ABOVE, -np.inf))

    def _window(self, bounds, margin: float) -> tuple[slice, slice]:
        """The raster's rows and columns covering world bounds (x0, y0, x1, y1) plus a margin."""
        x0, y0, x1, y1 = bounds
        c0, r0 = np.floor((np.array([x0, y0]) - margin - self.origin) / self.cell).astype(int)
        c1, r1 = np.ceil((np.array([x1, y1]) + margin - self.origin) / self.cell).astype(int)
        return (slice(max(r0, 0), max(min(r1, self.shape[0]), 0)),
                slice(max(c0, 0), max(min(c1, self.shape[1]), 0)))  # fmt: skip

    def _centres(self, win: tuple[slice, slice]) -> np.ndarray:
        """World (x, y) of the window's cell centres, (rows, cols, 2)."""
        r, c = np.mgrid[win[0], win[1]]
        return np.stack([self.origin[0] + (c + 0.5) * self.cell,
                         self.origin[1] + (r + 0.5) * self.cell], axis=-1)  # fmt: skip

    @staticmethod
    def _inside(f, xy: np.ndarray, half_w: float, half_d: float,
                offset=(0.0, 0.0)) -> np.ndarray:  # fmt: skip
        """Points (..., 2) inside a rectangle of ``f``'s local frame centred at ``offset``."""
        c, s = np.cos(f.yaw), np.sin(f.yaw)
        dx, dy = xy[..., 0] - f.position[0], xy[..., 1] - f.position[1]
        lx, ly = c * dx + s * dy - offset[0], -s * dx + c * dy - offset[1]
        return (np.abs(lx) < half_w) & (np.abs(ly) < half_d)

    def _add(self, win: tuple[slice, slice], lo: np.ndarray, hi: np.ndarray) -> None:
        """Store the window's intervals (empty where lo >= hi) in each cell's first free slot."""
        rows, cols = np.nonzero(lo < hi)
        rows, cols = rows + win[0].start, cols + win[1].start
        if not len(rows):
            return
        vals_lo, vals_hi = lo[lo < hi], hi[lo < hi]
        slot = np.argmax(self.lo[:, rows, cols] == np.inf, axis=0)
        full = ~np.any(self.lo[:, rows, cols] == np.inf, axis=0)
        if full.any():
            self.lo = np.concatenate([self.lo, np.full((1, *self.shape), np.inf, np.float32)])
            self.hi = np.concatenate([self.hi, np.full((1, *self.shape), -np.inf, np.float32)])
            slot[full] = len(self.lo) - 1
        self.lo[slot, rows, cols], self.hi[slot, rows, cols] = vals_lo, vals_hi

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Per world point (N, 3): whether it lies where the floor plan explains nothing."""
        p = np.asarray(points, np.float64).reshape(-1, 3)
        return np.array([_free(x, y, z, self.origin.astype(np.float64), self.cell,
                               self.lo, self.hi) for x, y, z in p], bool)  # fmt: skip


def _overlap(a: tuple[slice, slice], b: tuple[slice, slice]) -> bool:
    return all(x.start < y.stop and y.start < x.stop for x, y in zip(a, b, strict=True))


def unexplained(space: ObjectSpace, depth: np.ndarray, intrinsics, extrinsics) -> np.ndarray:
    """The frame's pixels (H, W) whose point the floor plan does not explain (pixels back-
    projected as the maps and tracks do: ``tracks.back_project``)."""
    d = np.ascontiguousarray(depth.reshape(depth.shape[:2]), dtype=np.float32)
    fx, fy, cx, cy = open3d_intrinsics(intrinsics).astype(np.float64)
    pose = open3d_pose(extrinsics).astype(np.float64)
    return _unexplained(d, fx, fy, cx, cy, pose, space.origin.astype(np.float64), space.cell,
                        space.lo, space.hi)  # fmt: skip


@njit(cache=True, nogil=True)
def _unexplained(d, fx, fy, cx, cy, pose, origin, cell, lo, hi):
    h, w = d.shape
    out = np.zeros((h, w), np.bool_)
    for r in range(h):
        for c in range(w):
            z = d[r, c]
            if z <= 0:
                continue
            px, py = (c - cx) * z / fx, (r - cy) * z / fy
            x = pose[0, 0] * px + pose[0, 1] * py + pose[0, 2] * z + pose[0, 3]
            y = pose[1, 0] * px + pose[1, 1] * py + pose[1, 2] * z + pose[1, 3]
            height = pose[2, 0] * px + pose[2, 1] * py + pose[2, 2] * z + pose[2, 3]
            out[r, c] = _free(x, y, height, origin, cell, lo, hi)
    return out


@njit(cache=True, nogil=True)
def _free(x, y, height, origin, cell, lo, hi) -> bool:
    """Whether a world point lies in one of its raster cell's intervals."""
    rows, cols, slots = lo.shape
    gc = int(np.floor((x - origin[0]) / cell))
    gr = int(np.floor((y - origin[1]) / cell))
    if gr < 0 or gr >= rows or gc < 0 or gc >= cols:
        return False
    for k in range(slots):
        if lo[gr, gc, k] < height < hi[gr, gc, k]:
            return True
    return False


def object_masks(unexplained_px: np.ndarray, depth: np.ndarray, labels: np.ndarray,
                 margins: np.ndarray, pickupable: np.ndarray,
                 min_pixels: int) -> list[Mask2D]:  # fmt: skip
    """One mask per part of the unexplained pixels with no depth jump inside, typed by the
    segmenter's votes: the pickupable label its pixels carry most (each vote weighted by the
    label's margin), scored by the share of its pixels labelled some pickupable type times
    that type's share of their votes. ``labels`` and ``margins`` are on the segmenter's grid
    (a whole divisor of the frame's size); ``pickupable``: label -> bool."""
    parts = split_instances(unexplained_px.astype(np.uint8), depth, [1], None, min_pixels)
    out = []
    for m in parts:
        votes, share = type_votes(m, labels, margins, pickupable)
        if share == 0.0:
            continue
        cls = int(votes.argmax())
        out.append(Mask2D(cls, m.mask, float(share * votes[cls] / votes.sum()), m.box))
    return out


def type_votes(m: Mask2D, labels: np.ndarray, margins: np.ndarray, pickupable: np.ndarray,
               ) -> tuple[np.ndarray, float]:  # fmt: skip
    """Per label, the margins summed over the mask's pixels the segmenter labels some
    pickupable type (on its grid, a whole divisor of the mask's size), and the share of the
    mask's pixels so labelled."""
    step = m.mask.shape[0] // labels.shape[0]
    w = m.window
    rows, cols = np.nonzero(m.mask[w])
    rows, cols = (rows + (w[0].start or 0)) // step, (cols + (w[1].start or 0)) // step
    lab, mar = labels[rows, cols], margins[rows, cols]
    voted = pickupable[lab]
    votes = np.bincount(lab[voted], weights=mar[voted], minlength=len(pickupable))
    return votes, float(voted.mean()) if len(lab) else 0.0


def frame_objects(masks: list[Mask2D], free: np.ndarray, depth: np.ndarray, labels: np.ndarray,
                  margins: np.ndarray, pickupable: np.ndarray, keep: float, start: float,
                  plan_keep: float, plan_start: float, covered: float, min_pixels: int,
                  ) -> tuple[list[Mask2D], list[float]]:  # fmt: skip
    """A pixels agent's object masks of one frame, at its resolution, and the score each needs
    to start a track: the masks of what the floor plan does not explain (``free``, typed by
    :func:`object_masks`) of ``plan_keep`` or more, and the segmenter's own object ``masks``
    (on its grid) of ``keep`` or more whose cells are less than ``covered`` unexplained (flat
    objects within :data:`RISE` of their surface), refined to the frame's pixels and cut to
    the explained ones, so that no two masks overlap."""
    grid = depth.shape[0] // labels.shape[0]
    plan = [m for m in object_masks(free, depth, labels, margins, pickupable, min_pixels)
            if m.score >= plan_keep]  # fmt: skip
    own = own_masks(masks, free, depth, grid, pickupable, keep, covered, min_pixels)
    return plan + own, [plan_start] * len(plan) + [start] * len(own)


def own_masks(masks: list[Mask2D], cut: np.ndarray, depth: np.ndarray, grid: int,
              pickupable: np.ndarray, keep: float, covered: float, min_pixels: int,
              ) -> list[Mask2D]:  # fmt: skip
    """The segmenter's own object ``masks`` of ``keep`` or more whose cells lie less than
    ``covered`` within ``cut`` (frame pixels other masks take), refined to the frame's pixels
    and cut to the rest; those of ``min_pixels`` or more."""
    cut_g = coarse(cut, grid)
    own = [m for m in masks if pickupable[m.cls] and m.score >= keep
           and cut_g[m.window][m.mask[m.window]].mean() < covered]  # fmt: skip
    own = [Mask2D(m.cls, m.mask & ~cut, m.score, m.box)
           for m in refined(own, depth, grid, min_pixels)]  # fmt: skip
    return [m for m in own if m.area >= min_pixels]
