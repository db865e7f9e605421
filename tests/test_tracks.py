"""The pixels track's association: masks of one agent's frames joined into tracks by class and
position, checked on synthetic frames and against the renderer's instances on a real render."""

from __future__ import annotations

import numpy as np
import pytest

from maniskill_tidy.perception.instances import Mask2D, coarse
from maniskill_tidy.perception.seg_classes import seg_classes
from maniskill_tidy.perception.tracks import (
    Tracker,
    clear_view,
    coarse_intrinsics,
    mask_position,
    mask_positions,
)

K = np.array([[100.0, 0, 50], [0, 100.0, 50], [0, 0, 1]], dtype=np.float32)


def camera_at(x: float) -> np.ndarray:
    """World-to-camera extrinsics of a camera at (x, 0, 0) looking along world +z."""
    ext = np.eye(4, dtype=np.float32)
    ext[0, 3] = -x
    return ext


def located(masks, depth, intrinsics, extrinsics) -> list:
    """Masks with their positions, each on its own (these synthetic masks may overlap)."""
    return [(m, mask_position(m, depth, intrinsics, extrinsics)) for m in masks]


def box(r0, r1, c0, c1) -> np.ndarray:
    m = np.zeros((100, 100), dtype=bool)
    m[r0:r1, c0:c1] = True
    return m


def test_masks_become_tracks_by_class_and_position():
    depth = np.full((100, 100), 2.0, dtype=np.float32)
    # pixels are centred at +0.5: rows and columns 49 and 50 straddle the principal point
    p = mask_position(box(49, 51, 49, 51), depth, K, camera_at(0.0))
    assert np.allclose(p, [0.0, 0.0, 2.0], atol=1e-3)
    tracker = Tracker()
    left, right = Mask2D(7, box(40, 60, 10, 20), 1.0), Mask2D(7, box(40, 60, 80, 90), 1.0)
    first = tracker.update(located([left, right], depth, K, camera_at(0.0)), 0)
    assert [t.id for _, _, t in first] == [1, 2]
    # the camera moved 0.3 m to the right: the same two objects, further left in the frame
    moved = [Mask2D(7, box(40, 60, 65, 75), 1.0), Mask2D(7, box(40, 60, 0, 10), 1.0),
             Mask2D(9, box(40, 60, 65, 75), 1.0)]  # fmt: skip
    again = tracker.update(located(moved, depth, K, camera_at(0.3)), 1)
    assert [t.id for _, _, t in again] == [2, 1, 3]  # another class at the same place: new track
    assert tracker.tracks[2].sightings == 2 and tracker.tracks[3].cls == 9


def test_clear_view_needs_the_point_in_frame_within_reach_and_nothing_in_front():
    depth = np.full((100, 100), 2.0, dtype=np.float32)
    depth[45:55, 70:80] = 0.5  # something near the camera, right of the middle
    points = np.array([
        [0.0, 0.0, 1.2],  # straight ahead, 1.2 m: shown
        [0.0, 0.0, 1.9],  # ahead, beyond the 1.5 m reach
        [0.3, 0.0, 1.2],  # behind the near thing (column 75)
        [-0.7, 0.0, 1.2],  # left of the frame (column -8)
        [0.0, 0.0, -1.0],  # behind the camera
        [0.0, 0.0, 2.05],  # the wall itself, within 0.1 m of the depth there: shown
    ])  # fmt: skip
    got = clear_view(points, depth, K, camera_at(0.0), reach=1.5)
    assert got.tolist() == [True, False, False, False, False, False]
    assert clear_view(points, depth, K, camera_at(0.0), reach=3.0).tolist() == [
        True, True, False, False, False, True
    ]  # fmt: skip
    # the camera 0.3 m to the right: the first point now lies left of the middle, still clear
    assert clear_view(points[:1], depth, K, camera_at(0.3), reach=1.5).tolist() == [True]


def test_a_track_counts_the_clear_views_it_was_seen_in_and_missed_in():
    depth = np.full((100, 100), 2.0, dtype=np.float32)
    depth[40:60, 40:60] = 1.0
    tracker = Tracker()
    mug = Mask2D(7, box(40, 60, 40, 60), 1.0)
    tracker.update(located([mug], depth, K, camera_at(0.0)), 0)
    assert tracker.looked_at(0, depth, K, camera_at(0.0), reach=1.5) == []
    tracker.update([], 1)  # the detector missed it
    (missed,) = tracker.looked_at(1, depth, K, camera_at(0.0), reach=1.5)
    assert (missed.seen_clear, missed.missed_clear) == (1, 1)
    far = camera_at(0.0)
    far[2, 3] = 1.0  # the camera 1 m back: out of reach, neither counted
    assert tracker.looked_at(2, depth, K, far, reach=1.5) == [] and missed.missed_clear == 1


@pytest.fixture(scope="module")
def render(tmp_path_factory):
    from maniskill_tidy.training.segmenter_data import SegDataConfig, build_segmenter_data

    out = tmp_path_factory.mktemp("tracks") / "test"
    cfg = SegDataConfig(None, "test", "HeteroTidy-v1", every=3, max_steps=30, houses=1)
    build_segmenter_data(cfg, out, progress=False)
    with np.load(sorted(out.glob("house_*.npz"))[0]) as z:
        return {k: z[k] for k in z.files}


def test_tracks_of_true_masks_follow_the_renderers_instances(render):
    """With perfect masks, association alone: a track holds one object, an object few tracks."""
    c = seg_classes()
    track_to_truth: dict[tuple, list[int]] = {}
    truth_to_tracks: dict[int, set] = {}
    for team in np.unique(render["team"]):
        for agent in np.unique(render["agent"]):
            tracker = Tracker()
            for k in np.nonzero((render["team"] == team) & (render["agent"] == agent))[0]:
                inst, cls = render["instance"][k], render["cls"][k]
                masks, truths = [], []
                for i in np.unique(inst[inst > 0]):
                    m = inst == i
                    if c.is_pickupable(int(cls[m][0])) and m.sum() >= 20:
                        masks.append(Mask2D(int(cls[m][0]), m, 1.0))
                        truths.append(int(i))
                depth = render["depth_mm"][k].astype(np.float32) / 1000
                seen = located(masks, depth, render["intrinsics"][k], render["extrinsics"][k])
                pairs = tracker.update(seen, int(render["t"][k]))
                for (_, _, track), truth in zip(pairs, truths, strict=True):
                    track_to_truth.setdefault((team, agent, track.id), []).append(truth)
                    truth_to_tracks.setdefault(truth, set()).add((team, agent, track.id))
    sightings = sum(len(v) for v in track_to_truth.values())
    pure = sum(max(v.count(t) for t in set(v)) for v in track_to_truth.values())
    assert sightings >= 30  # objects were seen
    assert pure / sightings >= 0.95
    agents_per_truth = [len({(te, a) for te, a, _ in v}) for v in truth_to_tracks.values()]
    tracks_per_truth = [len(v) for v in truth_to_tracks.values()]
    assert sum(tracks_per_truth) <= 1.3 * sum(agents_per_truth)  # rarely split in two


def test_a_track_keeps_the_type_most_of_its_sightings_vote_for():
    """A segmenter unsure in one frame joins the track it is close to (within RADIUS less the
    penalty); the track's type follows the votes, and its label slot follows the type."""
    from types import SimpleNamespace

    from maniskill_tidy.policies.pixels import LabelTable

    c = seg_classes()
    mug, cup = c.index["Mug"], c.index["Cup"]
    depth = np.full((100, 100), 2.0, dtype=np.float32)
    tracker = Tracker()
    here = box(40, 60, 40, 60)
    for step, (cls, score) in enumerate([(mug, 0.9), (cup, 0.5), (mug, 0.8)]):
        seen = located([Mask2D(cls, here, score)], depth, K, camera_at(0.0))
        ((_, _, track),) = tracker.update(seen, step)
    assert len(tracker.tracks) == 1 and track.cls == mug and track.sightings == 3
    public = SimpleNamespace(house=SimpleNamespace(furniture=[]))
    table = LabelTable(public)
    first = table.object_id(track)
    assert table.instances[first].type == "Mug"
    for step in range(3, 7):  # seen as a cup from now on: the votes turn
        tracker.update(located([Mask2D(cup, here, 0.9)], depth, K, camera_at(0.0)), step)
    assert len(tracker.tracks) == 1 and track.cls == cup
    second = table.object_id(track)
    assert table.instances[second].type == "Cup" and table.object_id(track) == second
    # another type 0.2 m away is another object: beyond RADIUS less the penalty
    aside = box(40, 60, 50, 70)  # 10 px at 2 m: 0.2 m
    ((_, _, other),) = tracker.update(
        located([Mask2D(mug, aside, 0.9)], depth, K, camera_at(0.0)), 7
    )
    assert other.id != track.id


@pytest.mark.parametrize("grid", [2, 4])
def test_a_mask_on_the_segmenters_grid_lies_where_its_full_pixels_do(grid):
    """Agents locate masks on the segmenter's grid (every ``grid``-th pixel, its own camera
    matrix): each cell must back-project to the point of the full-resolution pixel it samples."""
    rng = np.random.default_rng(0)
    depth = rng.uniform(0.5, 4.0, (100, 100)).astype(np.float32)
    E = camera_at(0.3)
    small, Kg = coarse(depth, grid), coarse_intrinsics(K, grid)
    for r, c in [(0, 0), (3, 7), (12, 20)]:
        cell = np.zeros(small.shape, dtype=bool)
        cell[r, c] = True
        full = np.zeros(depth.shape, dtype=bool)
        full[r * grid, c * grid] = True
        assert np.allclose(mask_position(cell, small, Kg, E), mask_position(full, depth, K, E))
    assert not np.allclose(mask_position(cell, small, K, E), mask_position(full, depth, K, E))


def test_positions_of_a_frames_masks_are_each_masks_own():
    """The whole frame back-projected once gives each mask the median of its own pixels with a
    depth, as one mask at a time would, and None to a mask with no depth."""
    rng = np.random.default_rng(1)
    depth = rng.uniform(0.5, 4.0, (100, 100)).astype(np.float32)
    depth[70:, :] = 0  # no depth here
    masks = [Mask2D(7, box(10, 30, 5, 25), 1.0, (slice(10, 30), slice(5, 25))),
             Mask2D(8, box(60, 80, 40, 90), 1.0), Mask2D(9, box(75, 90, 0, 10), 1.0)]  # fmt: skip
    got = mask_positions(masks, depth, K, camera_at(0.7))
    for m, p in zip(masks[:2], got, strict=False):
        assert np.allclose(p, mask_position(m.mask, depth, K, camera_at(0.7)))
    assert not np.allclose(got[0], got[1]) and got[2] is None
    with pytest.raises(ValueError, match="overlaps"):  # one pixel, two owners: refused
        mask_positions([masks[0], masks[0]], depth, K, camera_at(0.7))


def test_an_upscaled_mask_covers_the_blocks_of_its_cells():
    m = np.zeros((4, 5), dtype=bool)
    m[1, 2] = m[2, 2] = True
    big = Mask2D(3, m, 0.7, (slice(1, 3), slice(2, 3))).upscaled(2)
    assert big.mask.shape == (8, 10) and big.area == 8 and big.cls == 3 and big.score == 0.7
    assert big.mask[2:6, 4:6].all() and big.box == (slice(2, 6), slice(4, 6))
