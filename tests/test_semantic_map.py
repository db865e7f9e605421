"""Semantic maps: against the house spec after a look-around, and their pieces on synthetic maps."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
import sapien

import maniskill_tidy  # noqa: F401  (registers the env)
from maniskill_tidy.envs.actions import Action
from maniskill_tidy.perception.accuracy import (
    CAMERAS,
    SURVEY_TEAM,
    messy_house,
    room_cells,
    start_room_iou,
    survey_iou,
)
from maniskill_tidy.perception.benchmark import open3d_backprojection
from maniskill_tidy.perception.crops import egocentric_crop, wide_layout
from maniskill_tidy.perception.detections import LOW, detect_objects, point_stats, seen_robots
from maniskill_tidy.perception.frame_inputs import image_boxes
from maniskill_tidy.perception.frontiers import find_frontiers
from maniskill_tidy.perception.look_around import look_around
from maniskill_tidy.perception.map_grid import (
    EXPLORED,
    FIRST_CATEGORY,
    FIRST_CHANNEL,
    FLOOR_LABEL,
    OBSTACLE,
    MapFrame,
)
from maniskill_tidy.perception.map_kernels import merge_unique
from maniskill_tidy.perception.map_sharing import share_maps
from maniskill_tidy.perception.map_truth import box_cells, open_links
from maniskill_tidy.perception.semantic_map import (
    MapConfig,
    SemanticMap,
    backproject,
)
from maniskill_tidy.policies.channel import Channel

TEAM = SURVEY_TEAM
EPISODES = (0, 4, 8, 12)  # test split of the shipped dataset: bathrooms to living rooms


@pytest.fixture(scope="module")
def env():
    e = gym.make("HeteroTidy-v1", obs_mode="rgb+depth+segmentation", setting=TEAM, split="test")
    yield e.unwrapped
    e.close()


def looked_around(u, episode: int, agent: str) -> SemanticMap:
    """The map, with the start position and the objects seen well (100+ pixels) on the way."""
    obs, _ = u.reset(seed=0, options={"episode": episode})
    state = u.agents[u.agent_names.index(agent)]
    start = u.house.navgrid.center(*state.cell)
    seen = set()

    def note(frame, _map) -> None:
        ids, counts = np.unique(frame["segmentation"], return_counts=True)
        for sid, n in zip(ids, counts, strict=True):
            inst = u.instances.get(int(sid))
            if inst is not None and inst.kind == "object" and n >= 100:
                seen.add(inst.id)

    semantic = look_around(u, agent, obs, on_frame=note)
    semantic.start = start
    semantic.seen = {oid: u.hs.object_bottom(oid) for oid in seen}  # where they are now
    return semantic


@pytest.fixture(scope="module")
def surveys(env):
    """Every agent's map after a look-around from its start, in each episode of EPISODES."""
    out = {}
    for episode in EPISODES:
        for agent in env.agent_names:
            m = looked_around(env, episode, agent)
            out[episode, agent] = (m, messy_house(env))
    return out


@pytest.mark.parametrize("camera", ["low", "high"])
def test_obstacle_iou_after_looking_around_a_room(surveys, camera):
    ious = [
        start_room_iou(m, house, m.start)
        for (_, agent), (m, house) in surveys.items()
        if CAMERAS[agent] == camera
    ]
    assert np.mean(ious) >= 0.85, ious
    assert min(ious) >= 0.7, ious


def test_look_around_explores_most_of_the_start_room(surveys):
    for (_, agent), (m, house) in surveys.items():
        room = room_cells(house, m.frame, *m.start)
        explored = (m.top_down()[..., EXPLORED] > 0) & room
        assert explored.sum() / room.sum() > 0.4, agent


@pytest.mark.parametrize("agent", ["agent_0", "agent_2"])
def test_floor_lands_at_height_zero_for_low_and_high_cameras(env, agent):
    env.reset(seed=0, options={"episode": 0})
    obs = env.step({a: int(Action.LookDown) for a in env.agent_names})[0]
    m = SemanticMap(env.house, env.instances)
    frame = obs[agent]
    label = m.labels[frame["segmentation"]]
    depth = np.ascontiguousarray(frame["depth"], dtype=np.float32)
    _, _, points, labels, _ = backproject(depth, label, frame, m.config)
    floor = points[labels == FLOOR_LABEL]
    assert len(floor) > 1000
    # a camera put at the wrong height or tilt would lift or sink the floor
    assert abs(np.median(floor[:, 2])) < 0.01
    assert np.percentile(np.abs(floor[:, 2]), 99) < 0.03


def test_the_same_frames_give_the_same_map(env):
    """Fusion keeps the last label written to a voxel: the points must come in one order,
    row-major, every time."""
    env.reset(seed=0, options={"episode": 0})
    frames = [env.step({a: int(Action.RotateRight) for a in env.agent_names})[0]["agent_2"]
              for _ in range(4)]  # fmt: skip
    maps = []
    for _ in range(3):
        m = SemanticMap(env.house, env.instances)
        for f in frames:
            m.update(f)
        maps.append(m)
    for m in maps[1:]:
        assert np.array_equal(m.voxels, maps[0].voxels)
    label = maps[0].labels[frames[0]["segmentation"]]
    depth = np.ascontiguousarray(frames[0]["depth"], dtype=np.float32)
    *_, pixels = backproject(depth, label, frames[0], maps[0].config)
    flat = pixels[:, 0] * label.shape[1] + pixels[:, 1]
    assert len(flat) > 1000 and (np.diff(flat) > 0).all()


@pytest.mark.parametrize("stride", [1, 2])
def test_the_backprojection_kernel_is_open3ds_bit_for_bit(env, stride):
    """The map's kernel repeats open3d's unprojection: every point, id, label and pixel of
    rendered frames (low and high cameras, tilted, turning) must be open3d's, bit for bit, with the
    frame's largest instance unmapped as a held object is."""
    env.reset(seed=0, options={"episode": 4})
    config = MapConfig(stride=stride)
    labels = SemanticMap(env.house, env.instances, config).labels
    points = mapped = 0
    for action in (Action.LookDown, Action.RotateRight, Action.RotateRight):  # tilted: every
        obs = env.step({a: int(action) for a in env.agent_names})[0]  # term of the pose counts
        for frame in obs.values():
            seg = np.asarray(frame["segmentation"])
            label = labels[seg]
            label[seg == np.bincount(seg.ravel()).argmax()] = 0
            depth = np.ascontiguousarray(frame["depth"], dtype=np.float32)
            ours = backproject(depth, label, frame, config)
            theirs = open3d_backprojection(depth, label, frame, config)
            for a, b in zip(ours, theirs, strict=True):
                assert a.dtype == b.dtype and a.shape == b.shape
                assert np.array_equal(a, b)
            points, mapped = points + len(ours[0]), mapped + len(ours[2])
    assert 0 < mapped < points  # some points unmapped, some kept
    assert points > 9 * 4000 // stride**2  # thousands of points in each of nine frames


def test_category_channels_put_objects_in_their_cells(surveys):
    hits = misses = wrong = checked = 0
    for m, house in surveys.values():
        td = m.top_down()
        for k, name in enumerate(m.categories):
            cells = np.argwhere(td[..., FIRST_CHANNEL + k] > 0)
            if len(cells) == 0:
                continue
            truth = np.zeros(m.frame.shape, dtype=bool)
            for thing in [*house.furniture, *house.objects]:
                if thing.type == name:
                    truth |= footprint_cells(m.frame, *box_of(thing), pad=0.1)
                    for box in open_links(thing) if thing in house.furniture else []:
                        truth |= footprint_cells(m.frame, *box, pad=0.1)  # open doors, drawers
            inside = truth[cells[:, 0], cells[:, 1]]
            wrong += int((~inside).sum())
            hits += int(inside.sum())
        for o in house.objects:  # every object seen well is in its own cells
            if o.id in m.seen:
                k = m.categories.index(o.type)
                own = footprint_cells(m.frame, m.seen[o.id][:2], *o.size[:2], o.yaw, pad=0.0)
                misses += int(not td[..., FIRST_CHANNEL + k][own].any())
                checked += 1
    assert checked >= 10
    assert hits > 1000
    assert wrong / hits < 0.02
    assert misses == 0


def box_of(thing) -> tuple:
    return thing.position, thing.size[0], thing.size[1], thing.yaw


def footprint_cells(frame: MapFrame, centre, w: float, d: float, yaw: float, pad: float):
    """Cells within ``pad`` (plus half a cell) of a box."""
    return box_cells(frame, centre, w, d, yaw, frame.cell / 2 + pad + 1e-9)


def _bits(x) -> bytes:
    return np.asarray(x).tobytes()


def test_point_stats_are_numpys_median_and_percentile():
    """One pass over the points gives per id what a mask, ``np.median`` and ``np.percentile``
    gave: groups of 1 to 80 points (odd and even), with ties, in shuffled order."""
    rng = np.random.default_rng(0)
    sizes = rng.integers(1, 80, 400)
    ids = np.sort(rng.choice(5000, len(sizes), replace=False)) + 1
    seg = np.repeat(ids, sizes)
    points = rng.normal(0, 2, (len(seg), 3)).astype(np.float32)
    # ties; + 0 turns -0.0 into 0.0, as back-projected points never carry -0.0 (one sum of
    # nonzero products and a translation), so equal values are equal bits
    points[::3] = np.round(points[::3], 1) + np.float32(0)
    order = rng.permutation(len(seg))
    seg, points = (
        np.concatenate([seg[order], [0, 7000]]),
        np.vstack([points[order], [[9, 9, 9]] * 2]),
    )
    count, median, low = point_stats(seg, points.astype(np.float32), ids, LOW / 100)
    for i, sid in enumerate(ids):
        pts = points.astype(np.float32)[seg == sid]
        assert count[i] == len(pts)
        assert _bits(median[i]) == _bits(np.median(pts, axis=0))
        assert _bits(low[i]) == _bits(np.float32(np.percentile(pts[:, 2], LOW)))


def test_merging_movable_voxels_is_numpys_union():
    """The map's list of object voxels grows by merging, as ``np.union1d`` did: repeats within
    and across the lists, either list empty, values past 2^32."""
    rng = np.random.default_rng(2)
    for n, m in [(0, 0), (0, 5), (7, 0), (1, 1), (300, 40), (5000, 900)]:
        kept = np.unique(rng.integers(0, 3 * max(n, 1), n)) + 2**33
        more = rng.integers(0, 3 * max(n, 1), m) + 2**33
        if n and m:
            more[: m // 2] = rng.choice(kept, m // 2)  # some already kept
        got = merge_unique(kept, more)
        assert got.dtype == np.int64
        assert _bits(got) == _bits(np.union1d(kept, more))


def test_image_boxes_are_the_extremes_of_each_ids_pixels():
    rng = np.random.default_rng(1)
    seg = rng.integers(0, 40, (60, 80)).astype(np.int32)
    seg[rng.random(seg.shape) < 0.7] = 0  # sparse ids, some absent
    ids = np.array([3, 7, 12, 39, 45, 400])
    boxes = image_boxes(seg, ids)
    for sid, box in zip(ids, boxes, strict=True):
        rows, cols = np.nonzero(seg == sid)
        want = [rows.min(), cols.min(), rows.max() + 1, cols.max() + 1] if len(rows) else [0] * 4
        assert box.tolist() == want
    assert image_boxes(seg, np.zeros(0, np.int64)).shape == (0, 4)


def _masked_detections(frame, instances, kind):
    """What detections were before ``point_stats``: a mask, np.median and np.percentile."""
    out = {}
    ids, counts = np.unique(frame.seg, return_counts=True)
    for sid, n in zip(ids, counts, strict=True):
        inst = instances.get(int(sid))
        if inst is not None and inst.kind == kind and n * frame.stride**2 >= 20:
            pts = frame.points[frame.seg == sid]
            out[inst.id] = (np.median(pts, axis=0), float(np.percentile(pts[:, 2], LOW)), len(pts))
    return out


def test_detections_on_rendered_frames_are_the_masked_ones(env):
    """Objects and robots read off the map's frames: the same positions, lowest points and
    pixel counts, bit for bit, as per-instance masks and numpy's median and percentile."""
    objects = robots = 0
    for episode in (0, 4, 8):
        obs, _ = env.reset(seed=0, options={"episode": episode})
        for action in (None, Action.RotateRight, Action.LookDown):
            if action is not None:
                obs = env.step({a: int(action) for a in env.agent_names})[0]
            for frame in obs.values():
                m = SemanticMap(env.house, env.instances, MapConfig(stride=2))
                m.update(frame)
                want = _masked_detections(m.last_frame, env.instances, "object")
                got = {d.object_id: d for d in detect_objects(m.last_frame, env.instances)}
                assert got.keys() == want.keys()
                for oid, (position, bottom, n) in want.items():
                    d = got[oid]
                    assert _bits(d.position) == _bits(position) and d.bottom == bottom
                    assert d.pixels == n * 4
                    assert d.distance == float(np.linalg.norm(position - m.last_frame.camera))
                want = _masked_detections(m.last_frame, env.instances, "robot")
                seen = seen_robots(m.last_frame, env.instances)
                assert seen.keys() == want.keys()
                assert all(_bits(seen[r]) == _bits(want[r][0][:2]) for r in seen)
                objects, robots = objects + len(got), robots + len(seen)
    assert objects > 10 and robots > 0  # the comparison saw both


def object_in_view(u, obs, agent: str, min_distance: float = 0.0):
    """The object covering most pixels (over 150), at least ``min_distance`` from the camera."""
    seg = obs[agent]["segmentation"]
    camera = np.linalg.inv(obs[agent]["extrinsics"])[:3, 3]
    ids, counts = np.unique(seg, return_counts=True)
    for sid, n in sorted(zip(ids, counts, strict=True), key=lambda p: -p[1]):
        inst = u.instances.get(int(sid))
        if inst is not None and inst.kind == "object" and n > 150:
            if np.linalg.norm(u.hs.object_bottom(inst.id) - camera) >= min_distance:
                return int(sid), inst
    return None, None


def find_view_of_an_object(u, agent: str, min_distance: float = 0.0):
    for episode in range(20):
        obs, _ = u.reset(seed=0, options={"episode": episode})
        sid, inst = object_in_view(u, obs, agent, min_distance)
        if sid is not None:
            return obs, sid, inst
    pytest.fail("no start view with an object in the first 20 test episodes")


def project_points(cam: np.ndarray, k: np.ndarray, shape: tuple[int, int]):
    """Pixel (u, v) of camera-frame points and whether it lies in the image, in front."""
    h, w = shape
    ahead = cam[:, 2] > 1e-6
    z = np.where(ahead, cam[:, 2], 1.0)
    u = np.floor(k[0, 0] * cam[:, 0] / z + k[0, 2]).astype(np.int64)
    v = np.floor(k[1, 1] * cam[:, 1] / z + k[1, 2]).astype(np.int64)
    return u, v, ahead & (u >= 0) & (u < w) & (v >= 0) & (v < h)


def test_an_object_that_moves_away_is_cleared_from_the_map(env):
    """Every voxel of a moved object that the next frame can see goes: seen through, or seen to
    be something else at its own depth (the table under a flat object). Voxels out of view
    stay, as they should."""
    agent = "agent_1"
    obs, sid, inst = find_view_of_an_object(env, agent, min_distance=0.5)
    m = SemanticMap(env.house, env.instances)
    m.update(obs[agent])
    k = FIRST_CATEGORY + m.categories.index(inst.type)
    before = int((m.voxels == k).sum())
    assert before >= 10
    # spirit the object away (below the floor, out of every view) and look again
    env.hs.objects[inst.id].set_pose(sapien.Pose(p=[0.0, 0.0, -5.0]))
    frame = env.get_obs()[agent]
    m.update(frame)
    r, c, z = np.nonzero(m.voxels == k)
    world = np.column_stack([m.frame.centres(r, c), (z + 0.5) * m.config.cell])
    ext = np.asarray(frame["extrinsics"], dtype=np.float64)
    cam = world @ ext[:3, :3].T + ext[:3, 3]
    u, v, inside = project_points(
        cam, np.asarray(frame["intrinsics"], np.float64), frame["depth"].shape
    )
    in_view = inside & (frame["depth"][v.clip(0, 223), u.clip(0, 223)] > cam[:, 2] - 0.05)
    assert not in_view.any(), f"{in_view.sum()} of {before} voxels in plain view were kept"
    assert len(r) < before


def test_the_held_object_is_left_out(env):
    agent = "agent_1"
    obs, sid, inst = find_view_of_an_object(env, agent)
    k = FIRST_CHANNEL + SemanticMap(env.house, env.instances).categories.index(inst.type)
    seen, held = SemanticMap(env.house, env.instances), SemanticMap(env.house, env.instances)
    seen.update(obs[agent])
    held.update({**obs[agent], "held": np.array(sid)})
    assert seen.top_down()[..., k].sum() > held.top_down()[..., k].sum()


# ---------------------------------------------------------------------- synthetic maps
FRAME = MapFrame((0.0, 0.0), (100, 100), 0.05)  # 5 m x 5 m


@pytest.mark.parametrize("rotation", [0, 90, 180, 270])
def test_crop_turns_with_the_agent(rotation):
    td = np.zeros((100, 100, 3), dtype=np.uint8)
    x, y = 2.5, 2.5  # a cell corner: the crop's centre, between its cells 9 and 10
    yaw = math.radians(rotation)
    fwd, right = np.array([math.cos(yaw), math.sin(yaw)]), np.array([math.sin(yaw), -math.cos(yaw)])
    ahead = np.array([x, y]) + 1.125 * fwd + 0.125 * right  # 4.5 crop cells up, 0.5 right
    left = np.array([x, y]) + 0.125 * fwd - 0.875 * right  # 0.5 up, 3.5 left
    for point, ch in ((ahead, 0), (left, 1)):
        r, c = FRAME.cells_of(point[None])
        td[r[0], c[0], ch] = 1
    crop = egocentric_crop(td, FRAME, (x, y, rotation), size=20, cell=0.25)
    assert crop.shape == (20, 20, 3)
    assert np.argwhere(crop[..., 0]).tolist() == [[5, 10]]  # row 0 is the far end ahead
    assert np.argwhere(crop[..., 1]).tolist() == [[9, 6]]  # column 0 the far left


@pytest.mark.parametrize("rotation", [0, 90])
def test_the_wide_layout_gives_shares_of_the_whole_map_turned_with_the_agent(rotation):
    frame = MapFrame((0.0, 0.0), (400, 400), 0.05)  # 20 m x 20 m
    td = np.zeros((400, 400, 3), dtype=np.uint8)  # obstacle, explored, one category
    td[:, 200:, EXPLORED] = 1  # the eastern half (x >= 10 m) is explored
    td[200:205, 280:285, FIRST_CHANNEL] = 1  # an object at x 14-14.25 m, y 10-10.25 m
    wide = wide_layout(td, frame, (10.0, 10.0, rotation))
    assert wide.shape == (20, 20, 3) and wide.dtype == np.uint8
    explored = wide[..., EXPLORED]
    if rotation == 0:  # facing east: the explored half is ahead (rows 0-9)
        assert (explored[:10] == 255).all() and (explored[10:] == 0).all()
        # 4-4.25 m ahead, 0-0.25 m to the left: one of the cell's 16 samples
        assert np.argwhere(wide[..., 2]).tolist() == [[5, 9]] and wide[5, 9, 2] == 16
    else:  # facing north: the explored half is to the right (columns 10-19)
        assert (explored[:, 10:] == 255).all() and (explored[:, :10] == 0).all()
    td[:, 200:210, EXPLORED] = 0  # a metre explored only in part: x 10.5-11 m of it
    assert wide_layout(td, frame, (10.0, 10.0, 0))[..., EXPLORED][9, 0] == 128


def weighted_argmax_labels(crop: np.ndarray, small: np.ndarray) -> np.ndarray:
    """A crop's labels as the numpy fold the map messages first used: small-object categories
    weighted 2, the others 1, the first maximum wins; else obstacle 2, explored 1, unknown 0."""
    cats = crop[..., FIRST_CHANNEL:].astype(np.float32) * np.where(small, 2.0, 1.0)
    return np.where(
        cats.max(axis=-1) > 0,
        FIRST_CATEGORY + cats.argmax(axis=-1),
        np.where(crop[..., OBSTACLE] > 0, 2, np.where(crop[..., EXPLORED] > 0, 1, 0)),
    ).astype(np.float32)


def test_crops_read_off_the_maps_bits_and_ranks_are_the_pooled_top_down(env, surveys):
    """The channel crop read off the map's bits against the top-down map max-pooled, and the
    label crop read off its per-column ranks against that crop folded as before, on random
    voxel grids (every mix of categories, floor, walls and explored cells in a column) and on
    the surveys' maps, in poses all over the house and past its edges."""
    from maniskill_tidy.knowledge import load_catalog

    rng = np.random.default_rng(5)
    catalog = load_catalog()
    categories = catalog.categories  # a map's, by default
    k, pickupable = len(categories), set(catalog.pickupable)
    small = np.array([c in pickupable for c in categories])
    assert small.any() and not small.all()

    def agree(semantic: SemanticMap) -> np.ndarray:
        (x0, y0), (rows, cols) = semantic.frame.origin, semantic.frame.shape
        cell, labels = semantic.frame.cell, []
        for _ in range(8):
            x, y = rng.uniform(-1, cols * cell + 1) + x0, rng.uniform(-1, rows * cell + 1) + y0
            pose = (x, y, int(rng.choice([0, 90, 180, 270])))
            crop = egocentric_crop(semantic.top_down(), semantic.frame, pose, 20, 0.25)
            got_crop = semantic.local_crop(pose)
            assert got_crop.dtype == np.uint8 and np.array_equal(got_crop, crop)
            want = weighted_argmax_labels(crop, small)
            got = semantic.label_crop(pose)
            assert got.dtype == np.float32 and np.array_equal(got, want)
            labels.append(got)
        return np.concatenate(labels)

    for density in (0.001, 0.01, 0.1):
        random = SemanticMap(env.house, {})
        shape = random.voxels.shape
        labels = rng.integers(0, FIRST_CATEGORY + k, shape, dtype=np.uint8)
        random.voxels[...] = np.where(rng.random(shape) < density, labels, 0)
        random.explored[...] = rng.random(shape[:2]) < 0.5
        random._refresh_columns(np.arange(shape[0] * shape[1]))
        got = agree(random)
        assert len(np.unique(got)) > 3  # several categories, beside the other labels
    got = np.concatenate([agree(m) for m, _ in surveys.values()])
    assert all((got == code).any() for code in (0, 1, 2)) and (got >= FIRST_CATEGORY).any()


def test_crop_cells_outside_the_map_are_zero():
    td = np.ones((100, 100, 3), dtype=np.uint8)
    # an agent 0.1 m from the map's west edge, facing west: ahead of it is off the map
    crop = egocentric_crop(td, FRAME, (0.1, 2.5, 180), size=20, cell=0.25)
    assert crop[10:].all()  # behind it (the lower half of the crop) lies on the map
    assert not crop[:9].any()  # more than 0.25 m ahead does not


def test_frontiers_lie_where_explored_free_space_meets_the_unknown():
    td = np.zeros((100, 100, 2 + 1), dtype=np.uint8)
    td[20:60, 20:60, EXPLORED] = 1  # a 2 m x 2 m explored room...
    td[20:60, 20, OBSTACLE] = td[20:60, 59, OBSTACLE] = td[20, 20:60, OBSTACLE] = 1
    td[59, 20:40, OBSTACLE] = 1  # ...walled but for the north wall's east half
    frontiers = find_frontiers(td, FRAME, min_cells=5)
    assert len(frontiers) == 1
    f = frontiers[0]
    assert f.cells[:, 0].min() >= 57  # along the north edge
    assert 40 <= f.cells[:, 1].mean() <= 60
    x, y = f.centroid
    assert 2.0 <= x <= 3.0 and 2.85 <= y <= 3.0
    td[59, 20:60, OBSTACLE] = 1  # close it: nothing left to explore
    assert find_frontiers(td, FRAME) == []


def test_sharing_maps_counts_every_value_and_merges(env):
    obs, _ = env.reset(seed=0, options={"episode": 0})
    maps = {a: SemanticMap(env.house, env.instances) for a in ("agent_0", "agent_1")}
    for a, m in maps.items():
        m.update(obs[a])
    channel = Channel(["agent_0", "agent_1", "agent_2"])
    merged = share_maps(maps, channel)
    size = maps["agent_0"].top_down().size
    assert channel.total == 2 * size  # each of two maps to one other agent
    for m in maps.values():
        assert (merged >= m.top_down()).all()
    explored = [m.top_down()[..., EXPLORED] > 0 for m in maps.values()]
    assert ((merged[..., EXPLORED] > 0) == (explored[0] | explored[1])).all()


def test_planner_grid_pools_map_cells_into_planner_cells(env):
    env.reset(seed=0, options={"episode": 0})
    m = SemanticMap(env.house, env.instances)
    m._top_down[7, 12, OBSTACLE] = 1  # map cell (7, 12) lies in planner cell (1, 2)
    grid = m.planner_grid()
    assert grid.shape[:2] == tuple(env.house.navgrid.shape)
    assert np.argwhere(grid[..., OBSTACLE]).tolist() == [[1, 2]]


def test_bad_input_is_named(env):
    obs, _ = env.reset(seed=0, options={"episode": 0})
    m = SemanticMap(env.house, env.instances)
    frame = dict(obs["agent_0"])
    del frame["depth"]
    with pytest.raises(KeyError, match="depth"):
        m.update(frame)
    with pytest.raises(ValueError, match="another house"):
        m.update({**obs["agent_0"], "segmentation": obs["agent_0"]["segmentation"] + 10_000})
    with pytest.raises(ValueError, match="divide"):
        SemanticMap(env.house, env.instances, MapConfig(cell=0.07))
    with pytest.raises(ValueError, match="reachable"):
        look_around(env, "agent_0", obs, horizons=(45,))


@pytest.mark.slow
@pytest.mark.parametrize("camera", ["low", "high"])
def test_obstacle_iou_over_twenty_test_episodes(env, camera):
    ious = survey_iou(env, range(20))[camera]
    assert np.mean(ious) >= 0.85, ious
    assert np.percentile(ious, 10) >= 0.75, ious


def test_show_map_draws_an_agents_map(tmp_path, capsys):
    from maniskill_tidy.cli import main

    out = tmp_path / "map.png"
    assert main(["show-map", "--episode", "4", "--agent", "agent_2", "--out", str(out)]) == 0
    assert out.stat().st_size > 20_000
    printed = capsys.readouterr().out
    iou = float(printed.split("obstacle IoU ")[1].split()[0])
    assert iou > 0.8, printed


def test_frontier_targets_are_free_planner_cells_near_their_frontiers(surveys):
    checked = 0
    for m, house in surveys.values():
        nav = house.navgrid
        targets = m.frontier_targets(nav)
        frontiers = m.frontiers()
        assert len(targets) <= len(frontiers)
        for row, col in targets:
            assert nav.free(row, col)
            x, y = nav.center(row, col)
            assert min(math.dist((x, y), f.centroid) for f in frontiers) <= 1.0
            checked += 1
    assert checked >= 10


def _numpy_egocentric_cells(frame, pose, size, cell, sub):
    """The numpy reading ``egocentric_cells`` replaced: a meshgrid of sample points."""
    x, y, rotation = (float(v) for v in pose)
    yaw = math.radians(rotation)
    fwd = np.array([math.cos(yaw), math.sin(yaw)])
    right = np.array([math.sin(yaw), -math.cos(yaw)])
    offsets = (np.arange(size * sub) + 0.5) / sub - size / 2
    a, s = np.meshgrid(-offsets * cell, offsets * cell, indexing="ij")
    world = np.stack([x + a * fwd[0] + s * right[0], y + a * fwd[1] + s * right[1]], axis=-1)
    return frame.cells_of(world.reshape(-1, 2))


def test_the_crop_kernel_samples_the_cells_numpy_did():
    """Bit for bit: at poses whose sample points fall on cell borders (whole metres, a
    0.05 m map) and at odd ones, turned every way."""
    from maniskill_tidy.perception.crops import _egocentric_cells
    from maniskill_tidy.perception.map_grid import MapFrame

    rng = np.random.default_rng(5)
    frame = MapFrame((-1.25, 2.0), (300, 260), 0.05)
    poses = [(2.0, 5.0, r) for r in (0, 90, 180, 270)]
    poses += [(*rng.uniform(-2, 14, 2), r) for r in rng.integers(0, 360, 20)]
    for pose in poses:
        for size, cell, sub in ((20, 0.25, 5), (20, 1.0, 4)):
            got = _egocentric_cells(frame, pose, size, cell, sub)
            want = _numpy_egocentric_cells(frame, pose, size, cell, sub)
            assert all(np.array_equal(g, w) for g, w in zip(got, want, strict=True)), pose


def _egocentric_samples(top_down, frame, pose, size, cell, sub):
    """The numpy reading the crop kernels replaced: (size, sub, size, sub, channels) samples
    of the map (0 off the map)."""
    from maniskill_tidy.perception.crops import _egocentric_cells

    rows, cols = _egocentric_cells(frame, pose, size, cell, sub)
    inside = (rows >= 0) & (rows < top_down.shape[0]) & (cols >= 0) & (cols < top_down.shape[1])
    samples = np.zeros((len(rows), top_down.shape[2]), dtype=top_down.dtype)
    samples[inside] = top_down[rows[inside], cols[inside]]
    return samples.reshape(size, sub, size, sub, -1)


def test_the_pooled_crop_is_the_maximum_of_its_samples():
    """The crop's kernel against the numpy reading it replaced: every crop cell the maximum
    of its samples, off-map samples 0, at any pose (near edges, turned)."""
    from maniskill_tidy.perception.crops import egocentric_crop
    from maniskill_tidy.perception.map_grid import MapFrame

    rng = np.random.default_rng(3)
    frame = MapFrame((-1.0, 2.0), (60, 80), 0.05)
    top_down = (rng.random((60, 80, 7)) < 0.05).astype(np.uint8)
    for pose in [(0.0, 3.0, 0), (2.9, 4.9, 30), (-0.9, 2.1, 270), (1.3, 3.3, 135)]:
        crop = egocentric_crop(top_down, frame, pose)
        ref = _egocentric_samples(top_down, frame, pose, 20, 0.25, 5).max(axis=(1, 3))
        assert crop.dtype == np.uint8 and np.array_equal(crop, ref)
        assert 0 < crop.sum() < top_down.sum()


def test_the_wide_layout_is_the_share_of_its_samples():
    """The wide layout's kernel against the numpy reading it replaced (the float32 mean of
    16 samples, times 255, rounded half to even), off-map samples 0."""
    from maniskill_tidy.perception.crops import wide_layout
    from maniskill_tidy.perception.map_grid import EXPLORED, FIRST_CHANNEL, OBSTACLE, MapFrame

    rng = np.random.default_rng(4)
    frame = MapFrame((-1.0, 2.0), (300, 260), 0.05)
    top_down = (rng.random((300, 260, 9)) < 0.3).astype(np.uint8)
    for pose in [(4.0, 9.0, 0), (0.2, 2.4, 60), (11.0, 16.0, 180)]:
        s = _egocentric_samples(top_down, frame, pose, 20, 1.0, 4)
        shares = np.stack(
            [s[..., OBSTACLE], s[..., EXPLORED], s[..., FIRST_CHANNEL:].any(-1)], axis=-1
        ).astype(np.float32)
        ref = np.round(shares.mean(axis=(1, 3)) * 255).astype(np.uint8)
        layout = wide_layout(top_down, frame, pose)
        assert layout.dtype == np.uint8 and np.array_equal(layout, ref)
        assert 128 in layout  # 8 of 16: the tie rounds to even


def test_the_map_bench_times_every_row_on_the_same_frames():
    """``bench --only map``: every row measured on each agent frame of the walk, reported."""
    from maniskill_tidy.perception.benchmark import bench_map, report

    r = bench_map(steps=2)
    assert r["frames"] == 2 * 3  # two steps of Setting I's three agents
    for key in ("env_ms", "map_ms", "stride2_ms", "tsdf_ms", "kernel_ms", "open3d_ms"):
        assert r[key] > 0, key
    assert "open3d ms" in report(r)
