"""HeteroTidy-v1: registration, API conformance, action semantics, segmentation, determinism."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import maniskill_tidy
from maniskill_tidy.envs.actions import MIN_PIXELS, REACH, Action, Targeted
from maniskill_tidy.envs.episodes import EpisodeSet
from maniskill_tidy.envs.hetero_tidy import HeteroTidyEnv
from maniskill_tidy.knowledge import FLOOR, load_placement
from maniskill_tidy.policies.viewpoints import viewpoints
from maniskill_tidy.tasks.metatask import reasonable_surfaces

MANI = 2  # agent_2 is Setting I's manipulator


@pytest.fixture(scope="module")
def env():
    e = HeteroTidyEnv(setting="I", split="test")
    yield e
    e.close()


def teleport(env, i: int, cell, rotation: int, horizon: int = 0) -> dict:
    """Scripted set-up: put agent i somewhere and return fresh observations."""
    a = env.agents[i]
    a.cell, a.rotation, a.horizon = tuple(cell), rotation, horizon
    env._place_robot(i)
    return env.get_obs()


def step_one(env, i: int, action) -> tuple[dict, dict]:
    """Agent i acts; the others turn in place (never blocking anyone)."""
    actions = {n: Action.RotateLeft.value for n in env.agent_names}
    actions[env.agent_names[i]] = action
    obs, _, _, _, info = env.step(actions)
    return obs, info


def seen_from(env, i: int, seg_id: int, point, height: float):
    """A viewpoint within reach from which agent i's camera shows seg_id."""
    for vp in viewpoints(env.house, np.asarray(point), height)[:40]:
        if any(b.cell == vp.cell for j, b in enumerate(env.agents) if j != i):
            continue
        obs = teleport(env, i, vp.cell, vp.rotation, vp.horizon)
        if (obs[env.agent_names[i]]["segmentation"] == seg_id).sum() >= MIN_PIXELS:
            return vp, obs
    return None, None


def object_centre(env, oid: str) -> np.ndarray:
    m = env.manipulation
    return m._centre(oid)


def test_registered_with_gymnasium_after_import():
    e = gym.make("HeteroTidy-v1", setting="I", split="test", obs_mode="none")
    try:
        assert isinstance(e.unwrapped, HeteroTidyEnv)
        assert list(e.action_space.keys()) == ["agent_0", "agent_1", "agent_2"]
    finally:
        e.close()


def test_gym_make_with_module_prefix_in_fresh_interpreter():
    code = (
        "import gymnasium as gym\n"
        "e = gym.make('maniskill_tidy:HeteroTidy-v1', setting='I')\n"
        "o, i = e.reset(seed=0)\n"
        "print(sorted(o), o['agent_0']['rgb'].shape, i['episode'])\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "['agent_0', 'agent_1', 'agent_2'] (224, 224, 3) house_" in out.stdout


def test_gymnasium_env_checker(env):
    from gymnasium.utils.env_checker import check_env

    check_env(env, skip_render_check=True)


def test_pettingzoo_parallel_api():
    from pettingzoo.test import parallel_api_test

    p = maniskill_tidy.parallel_env(setting="II", split="test", obs_mode="rgb")  # default: v2
    try:
        assert p.env.visuals == "realistic" and p.metadata["name"] == "heterotidy_v2"
        assert p.possible_agents == ["agent_0", "agent_1", "agent_2", "agent_3"]
        assert p.action_space("agent_0").n == 8 and p.action_space("agent_3").n == 11
        parallel_api_test(p, num_cycles=20)
    finally:
        p.close()
    v1 = maniskill_tidy.parallel_env(env_id="HeteroTidy-v1", split="test", obs_mode="rgb")
    try:
        assert v1.env.visuals == "flat" and v1.metadata["name"] == "heterotidy_v1"
        obs, _ = v1.reset(seed=0)
        assert obs["agent_0"]["rgb"].shape == (224, 224, 3)
    finally:
        v1.close()
    with pytest.raises(ValueError, match="expected one of"):
        maniskill_tidy.parallel_env(env_id="HeteroTidy-v9")


def test_capabilities_spaces_and_camera_heights(env):
    obs, _ = env.reset(options={"episode": 0})
    assert [env.action_space[n].n for n in env.agent_names] == [8, 8, 11]
    for name, cap, height in zip(
        env.agent_names, [(1, 0, 0), (1, 0, 1), (1, 1, 1)], [0.22, 0.9, 1.0], strict=True
    ):
        o = obs[name]
        assert tuple(o["capability"]) == cap
        cam_to_world = np.linalg.inv(o["extrinsics"])
        assert cam_to_world[2, 3] == pytest.approx(height, abs=1e-3)
        assert env.observation_space[name].contains(o)
    with pytest.raises(ValueError, match="agent_0 cannot manipulate"):
        env.step({"agent_0": Action.PickUp.value, "agent_1": 0, "agent_2": 0})


def test_bad_input_errors_name_the_problem(env):
    env.reset(options={"episode": 0})
    with pytest.raises(KeyError, match="unknown agents"):
        env.step({"agent_0": 0, "agent_1": 0, "agent_2": 0, "agent_9": 0})
    with pytest.raises(KeyError, match="no action for"):
        env.step({"agent_0": 0})
    with pytest.raises(ValueError, match="out of range"):
        env.step({"agent_0": 0, "agent_1": 0, "agent_2": 11})
    for bad in (1.5, "3", True, np.float32(2.0), None):  # not integers: refused, not converted
        with pytest.raises(TypeError, match="expected an integer action index"):
            env.step({"agent_0": bad, "agent_1": 0, "agent_2": 0})
    with pytest.raises(ValueError, match="agent_1 cannot manipulate"):
        env.step({"agent_0": 0, "agent_1": Action.Drop, "agent_2": 0})
    with pytest.raises(ValueError, match=r"only PickUp and PutDown take a target"):
        env.step({"agent_0": 0, "agent_1": 0, "agent_2": Targeted(Action.Drop, "x")})
    assert all(a.steps == 0 for a in env.unwrapped.agents), "a refused step changed the episode"
    with pytest.raises(ValueError, match="team of 5 agents"):
        HeteroTidyEnv(setting=[(1, 0, 0)] * 5, split="test")
    with pytest.raises(ValueError, match="unknown setting"):
        HeteroTidyEnv(setting="III")
    with pytest.raises(KeyError, match="no episode"):
        env.reset(options={"episode": "house_99999/task_0/start_0"})


def test_blocked_moves_do_not_move(env):
    env.reset(options={"episode": 0})
    nav = env.house.navgrid
    free = [(r, c) for r in range(nav.shape[0]) for c in range(nav.shape[1]) if nav.free(r, c)]
    others = {b.cell for b in env.agents[1:]}
    # a free cell whose east neighbour is blocked by a wall or furniture
    cell = next(c for c in free if not nav.free(c[0], c[1] + 1) and c not in others)
    obs = teleport(env, 0, cell, 0)
    before = obs["agent_0"]["pose"].copy()
    obs, info = step_one(env, 0, Action.MoveAhead.value)
    assert np.array_equal(obs["agent_0"]["pose"], before)
    assert "wall or furniture" in info["failed"]["agent_0"]
    # another robot in the way
    cell = next(
        c
        for c in free
        if nav.free(c[0], c[1] + 1) and c not in others and (c[0], c[1] + 1) not in others
    )
    teleport(env, 0, cell, 0)
    teleport(env, 1, (cell[0], cell[1] + 1), 90)
    obs, info = step_one(env, 0, Action.MoveAhead.value)
    assert info["failed"]["agent_0"] == "MoveAhead blocked by agent_1"
    assert tuple(env.agents[0].cell) == cell
    # a free move goes one cell; MoveLeft strafes without turning
    teleport(env, 1, (cell[0], cell[1] + 1), 90)
    env.agents[1].cell = (-5, -5)  # out of the way
    obs, info = step_one(env, 0, Action.MoveAhead.value)
    assert info["failed"]["agent_0"] == ""
    assert obs["agent_0"]["pose"][0] == pytest.approx(nav.center(cell[0], cell[1] + 1)[0])
    assert obs["agent_0"]["pose"][2] == 0


def test_a_stopped_agents_camera_is_off(env, monkeypatch):
    """Once an agent stops, its camera is no longer drawn and its observation keeps (copies
    of) the pictures it took last; the others' cameras still draw, and its pose stays current."""
    drawn: list[list[str]] = []
    take = env._take_pictures
    monkeypatch.setattr(env, "_take_pictures", lambda cams: (drawn.append(list(cams)), take(cams)))
    env.reset(options={"episode": 0})
    last, _ = step_one(env, 0, Action.RotateLeft.value)
    kept = {key: last["agent_0"][key].copy() for key in ("rgb", "depth", "segmentation")}
    obs, info = step_one(env, 0, Action.Stop.value)
    assert info["stopped"]["agent_0"]
    assert drawn[-1] == ["agent_1", "agent_2"]
    for _ in range(2):
        before = obs
        obs, *_ = env.step({"agent_1": Action.RotateLeft.value, "agent_2": Action.RotateLeft.value})
        assert drawn[-1] == ["agent_1", "agent_2"]
        for key in ("rgb", "depth", "segmentation"):
            assert np.array_equal(obs["agent_0"][key], kept[key])
            assert not np.shares_memory(obs["agent_0"][key], before["agent_0"][key])
            assert not np.array_equal(obs["agent_1"][key], before["agent_1"][key])
            # a caller writing into what it was handed changes no later observation
            before["agent_0"][key][...] = 0
            last["agent_0"][key][...] = 0
    np.testing.assert_array_equal(obs["agent_0"]["pose"], last["agent_0"]["pose"])
    env.reset(options={"episode": 0})  # every camera draws again
    assert drawn[-1] == env.agent_names


def test_look_is_bounded_and_stop_ends_the_agent(env):
    env.reset(options={"episode": 0})
    _, info = step_one(env, 0, Action.LookUp.value)
    assert info["failed"]["agent_0"] == ""
    _, info = step_one(env, 0, Action.LookUp.value)
    assert "beyond the camera's range" in info["failed"]["agent_0"]
    _, info = step_one(env, 0, Action.Stop.value)
    assert info["stopped"]["agent_0"] and info["steps"]["agent_0"] == 3
    obs, _, terminated, _, info = env.step({"agent_1": 7, "agent_2": 0})
    assert not terminated and info["steps"]["agent_0"] == 3
    obs, _, terminated, truncated, info = env.step({"agent_2": 7})
    assert terminated and not truncated


def test_truncation_at_max_steps():
    e = HeteroTidyEnv(setting=[(1, 0, 0)], split="test", obs_mode="none", max_steps=3)
    try:
        e.reset(seed=0)
        flags = [e.step({"agent_0": Action.RotateLeft.value})[3] for _ in range(3)]
        assert flags == [False, False, True]
    finally:
        e.close()


def test_episodes_free_their_scenes_and_the_last_close_thaws_the_frozen_heap(monkeypatch):
    """The env freezes what the process loaded before its first episode out of ManiSkill's
    per-episode full collections (they walked it all): an old episode's scene must still be
    freed, the heap must stay frozen while any env is open (a second env's close must not slow
    the first one's resets) and the last close must thaw it for the rest of the process."""
    import gc
    import weakref

    from maniskill_tidy.envs import hetero_tidy

    gc.unfreeze()
    monkeypatch.setattr(hetero_tidy, "_open_envs", 0)  # a module fixture's env may be open
    envs = []
    try:
        e = HeteroTidyEnv(setting="I", split="test", obs_mode="none")
        envs.append(e)
        other = HeteroTidyEnv(setting="I", split="test", obs_mode="none")
        envs.append(other)
        assert gc.get_freeze_count() > 0
        scenes = []
        for i in range(4):
            e.reset(seed=i, options={"episode": i})
            scenes.append(weakref.ref(e.scene))
        gc.collect()  # the previous scene is still referenced while the next one is built
        assert [s() is None for s in scenes] == [True, True, True, False]
        other.close()
        other.close()  # a second close changes nothing
        assert gc.get_freeze_count() > 0
    finally:
        for env in envs:
            env.close()
    assert gc.get_freeze_count() == 0


def test_rgb_is_the_colour_picture_without_alpha(env):
    """The observation's rgb is the camera's colour picture, alpha dropped, as a C-contiguous
    (H, W, 3) uint8 array (OpenCV drops alpha; numpy's copy of the view was slower)."""
    obs, _ = env.reset(options={"episode": 1})
    for name in env.agent_names:
        rgb = obs[name]["rgb"]
        colour = env._sensors[name].camera._render_cameras[0].get_picture("Color")
        assert rgb.dtype == np.uint8 and rgb.shape == (*colour.shape[:2], 3)
        assert rgb.flags["C_CONTIGUOUS"] and np.array_equal(rgb, colour[..., :3])
        assert len(np.unique(rgb.reshape(-1, 3), axis=0)) > 50  # a picture, not a blank


def test_segmentation_ids_and_depth_land_on_the_instance(env):
    """Back-project every pixel of an instance with depth + camera matrices: it must lie in the
    instance's box. This checks segmentation, depth, intrinsics and extrinsics together."""
    obs, _ = env.reset(options={"episode": 0})
    checked = 0
    for oid in env.misplaced:
        sid = env.manipulation.seg_of_object[oid]
        vp, obs = seen_from(env, MANI, sid, object_centre(env, oid), 1.0)
        if vp is None:
            continue
        o = obs["agent_2"]
        v, u = np.nonzero(o["segmentation"] == sid)
        z = o["depth"][v, u]
        K = o["intrinsics"]
        cam = np.stack(
            [
                (u + 0.5 - K[0, 2]) * z / K[0, 0],
                (v + 0.5 - K[1, 2]) * z / K[1, 1],
                z,
                np.ones_like(z),
            ]
        )
        world = (np.linalg.inv(o["extrinsics"]) @ cam)[:3].T
        bottom = env.hs.object_bottom(oid)
        size = env.manipulation.sizes[oid]
        half = max(size[0], size[1]) / 2 * 1.5 + 0.03
        assert np.all(np.abs(world[:, 0] - bottom[0]) < half)
        assert np.all(np.abs(world[:, 1] - bottom[1]) < half)
        assert np.all((world[:, 2] > bottom[2] - 0.03) & (world[:, 2] < bottom[2] + size[2] + 0.03))
        assert env.instances[sid].kind == "object" and env.instances[sid].id == oid
        checked += 1
    assert checked >= 1


def _task_with_pickable(env):
    """An episode and a misplaced object the manipulator can see and reach."""
    for ep in range(0, len(env.episodes), 5):
        env.reset(options={"episode": ep})
        for oid in env.misplaced:
            sid = env.manipulation.seg_of_object[oid]
            vp, _ = seen_from(env, MANI, sid, object_centre(env, oid), 1.0)
            if vp is not None:
                return oid
    raise AssertionError("no misplaced object could be seen from any viewpoint")


def test_pickup_out_of_reach_fails_and_in_reach_succeeds(env):
    oid = _task_with_pickable(env)
    sid = env.manipulation.seg_of_object[oid]
    centre = object_centre(env, oid)
    # out of reach but in view: look from farther away
    far = [vp for vp in viewpoints(env.house, centre, 1.0, reach=4.0) if vp.distance > REACH + 0.1]
    tried = 0
    for vp in far[:60]:
        if any(b.cell == vp.cell for b in env.agents[:MANI]):
            continue
        obs = teleport(env, MANI, vp.cell, vp.rotation, vp.horizon)
        if (obs["agent_2"]["segmentation"] == sid).sum() >= MIN_PIXELS:
            _, info = step_one(env, MANI, Targeted(Action.PickUp, oid))
            assert "out of reach" in info["failed"]["agent_2"]
            assert info["held"]["agent_2"] is None
            tried += 1
            break
    assert tried == 1, "no far viewpoint saw the object"
    vp, _ = seen_from(env, MANI, sid, centre, 1.0)
    obs, info = step_one(env, MANI, Targeted(Action.PickUp, oid))
    assert info["failed"]["agent_2"] == ""
    assert info["held"]["agent_2"] == oid and oid in info["picked"]
    assert int(obs["agent_2"]["held"]) == sid
    # a navigation-only agent has no PickUp at all
    with pytest.raises(ValueError, match="cannot manipulate"):
        env.step({"agent_0": 8, "agent_1": 0, "agent_2": 0})


def test_putdown_on_reasonable_receptacle_makes_d_true(env):
    oid = _task_with_pickable(env)
    sid = env.manipulation.seg_of_object[oid]
    seen_from(env, MANI, sid, object_centre(env, oid), 1.0)
    _, info = step_one(env, MANI, Targeted(Action.PickUp, oid))
    assert info["held"]["agent_2"] == oid
    assert oid not in info["reasonable"]
    otype = env.instances[sid].type
    size = env.manipulation.sizes[oid]
    placed = False
    for fid, sname in reasonable_surfaces(env.house, otype, size):
        f = env.hs.furniture[fid]
        s = f.surface(sname)
        link_ids = [k for k, inst in env.instances.items() if inst.id.split("/")[0] == fid]
        centre = env.manipulation.surface_centre(f, s)
        for vp in viewpoints(env.house, centre, 1.0)[:30]:
            if any(b.cell == vp.cell for b in env.agents[:MANI]):
                continue
            obs = teleport(env, MANI, vp.cell, vp.rotation, vp.horizon)
            if not np.isin(obs["agent_2"]["segmentation"], link_ids).sum() >= MIN_PIXELS:
                continue
            _, info = step_one(env, MANI, Targeted(Action.PutDown, f"{fid}/{sname}"))
            if info["failed"]["agent_2"]:
                continue
            placed = True
            break
        if placed:
            break
    assert placed, "no reasonable surface accepted the object"
    state = env.hs.state[oid]
    rooms = {r.id: r.type for r in env.house.rooms}
    assert state.receptacle == fid and state.surface == sname
    assert load_placement().D(otype, s.receptacle_type, rooms[f.room])
    assert oid in info["reasonable"] and info["held"]["agent_2"] is None
    bottom = env.hs.object_bottom(oid)
    assert (
        bottom[2] == pytest.approx(env.manipulation.surface_centre(f, s)[2], abs=0.05)
        or s.name == "bar"
    )


def test_drop_puts_the_object_down_where_it_falls(env):
    oid = _task_with_pickable(env)
    sid = env.manipulation.seg_of_object[oid]
    seen_from(env, MANI, sid, object_centre(env, oid), 1.0)
    step_one(env, MANI, Targeted(Action.PickUp, oid))
    _, info = step_one(env, MANI, Action.Drop.value)
    assert info["failed"]["agent_2"] == "" and info["held"]["agent_2"] is None
    assert env.hs.state[oid].receptacle in (FLOOR, "unknown") or env.hs.state[oid].surface
    assert env.hs.object_bottom(oid)[2] < 1.0


def test_same_seed_same_episode_and_observations():
    a = HeteroTidyEnv(setting="I", split="test")
    try:
        o1, i1 = a.reset(seed=7)
        actions = [
            {n: int(x) for n, x in zip(a.agent_names, row, strict=True)}
            for row in np.random.default_rng(1).integers(0, 7, (5, 3))
        ]
        for act in actions:
            o1, *_ = a.step(act)
        o2, i2 = a.reset(seed=7)
        for act in actions:
            o2, *_ = a.step(act)
        assert i1["episode"] == i2["episode"]
        for n in a.agent_names:
            for k in ("rgb", "depth", "segmentation", "pose"):
                assert np.array_equal(o1[n][k], o2[n][k]), (n, k)
        _, i3 = a.reset(seed=8)
        _, i4 = a.reset(seed=9)
        assert len({i1["episode"], i3["episode"], i4["episode"]}) > 1
    finally:
        a.close()


def test_objects_settle_without_moving_in_default_houses():
    """Physics settles every object where the task put it (a wrong shape would push it away)."""
    e = HeteroTidyEnv(setting="I", split="train", obs_mode="none")
    try:
        seen = set()
        for i in range(0, len(e.episodes), 10):
            _, info = e.reset(options={"episode": i})
            seen.add(e.episode.house_id)
            assert info["fallen"] == [], (e.episode.id, info["fallen"])
        assert len(seen) == 8
    finally:
        e.close()


def test_render_third_person(env):
    e = HeteroTidyEnv(setting="I", split="test", render_mode="rgb_array", obs_mode="none")
    try:
        e.reset(seed=0)
        img = e.render()
        assert img.shape == (480, 640, 3) and img.dtype == np.uint8
        assert img.std() > 10  # not a blank frame
    finally:
        e.close()


def test_shipped_default_dataset_regenerates_bit_for_bit(tmp_path):
    import json

    from maniskill_tidy.envs.episodes import default_dataset
    from maniskill_tidy.tasks.dataset import generate_dataset

    shipped = json.loads((default_dataset() / "manifest.json").read_text())
    fresh = generate_dataset(
        tmp_path / "d", shipped["houses"], seed=shipped["seed"], workers=1, progress=False
    )
    assert fresh["dataset_hash"] == shipped["dataset_hash"]


def test_preset_files_match_the_builtin_settings_and_custom_teams_run():
    from pathlib import Path

    from maniskill_tidy.tasks.teams import SETTINGS, load_preset

    root = Path(__file__).resolve().parents[1] / "envs"
    for name in ("I", "II"):
        setting, members = load_preset(root / f"setting_{name}.json")
        assert setting == name and members == SETTINGS[name]
    e = HeteroTidyEnv(setting=str(root / "two_manipulators.json"), split="test", obs_mode="none")
    try:
        assert [e.action_space[n].n for n in e.agent_names] == [11, 11]
        obs, _ = e.reset(seed=0)
        heights = [np.linalg.inv(obs[n]["extrinsics"])[2, 3] for n in e.agent_names]
        assert heights == pytest.approx([1.0, 0.25], abs=1e-3)
        # commands list the episodes an env would play without building its scene
        listed = EpisodeSet.for_setting(None, "test", str(root / "two_manipulators.json"))
        assert [ep.id for ep in listed.episodes] == [ep.id for ep in e.episodes.episodes]
        assert [ep.starts for ep in listed.episodes] == [ep.starts for ep in e.episodes.episodes]
    finally:
        e.close()
    ii = EpisodeSet.for_setting(None, "test", "II")
    assert ii.setting == "II" and len(ii.episodes[0].starts) == len(SETTINGS["II"])
    with pytest.raises(ValueError, match="not a team preset"):
        load_preset(root / "README.md")


def test_v1_is_not_called_out_of_date_beside_v2():
    """gymnasium warns that an id with a higher version is out of date; v1 is the default
    look, so making it must not tell users to move to v2."""
    import warnings

    import gymnasium as gym

    from maniskill_tidy.envs.registration import register_gym

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("default")
        register_gym()  # puts its filter in front of the test's
        gym.make("HeteroTidy-v1", setting="I", split="test", obs_mode="none").close()
    assert not [w for w in caught if "out of date" in str(w.message)]


@pytest.mark.parametrize("visuals", ["flat", "realistic"])
def test_previews_segment_every_pixel_as_the_agents_own_camera(visuals):
    """The expert's previews (and the PickUp / PutDown checks without pictures) draw with a
    segmentation-only shader on a second camera: from viewpoints on the house's objects, its
    ids must be the agent camera's, pixel for pixel (v2 hides unseen rooms and has textures
    whose alpha discards pixels)."""
    e = HeteroTidyEnv(setting="I", split="test", visuals=visuals)
    name = e.agent_names[MANI]
    try:
        e.reset(options={"episode": 2})
        seen = set()
        for oid in sorted(e.hs.objects)[::3]:
            vps = viewpoints(e.house, object_centre(e, oid), e.kinds[MANI].camera_height)
            for vp in vps[:2]:
                if any(b.cell == vp.cell for b in e.agents[:MANI]):
                    continue
                own = teleport(e, MANI, vp.cell, vp.rotation, vp.horizon)[name]["segmentation"]
                assert np.array_equal(e._render_segmentations([name])[name], own), (oid, vp)
                seen |= set(np.unique(own).tolist())
        assert len(seen) > 20  # objects, furniture, walls and floors, not one blank wall
    finally:
        e.close()


def test_v1_cameras_draw_sapiens_minimal_pixels():
    """v1's agent cameras use SAPIEN's minimal pack without image-based light
    (``sim/shaders/no_ibl``), which adds exactly zero where there is no environment map: from
    viewpoints on the house's objects, looking down, level and up, every colour, position and
    segmentation value must be the minimal pack's own."""
    import sapien

    from maniskill_tidy.envs.actions import HORIZON_RANGE
    from maniskill_tidy.sim import brdf_lut

    e = HeteroTidyEnv(setting="I", split="test", visuals="flat")
    name = e.agent_names[MANI]
    try:
        e.reset(options={"episode": 2})
        assert e._camera_shader.shader_pack.endswith("no_ibl")
        own = e._agent_camera(name)
        minimal = str(Path(sapien.__file__).parent / "vulkan_shader" / "minimal")
        ref = sapien.render.RenderCameraComponent(own.width, own.height, minimal)
        ref.set_fovy(own.fovy, compute_x=True)
        ref.near, ref.far = own.near, own.far
        e.robots[MANI].add_component(ref)
        if e.backend.render_device.is_cpu():
            brdf_lut.lend([ref])
        compared = 0
        for oid in sorted(e.hs.objects)[::4]:
            vps = viewpoints(e.house, object_centre(e, oid), e.kinds[MANI].camera_height)
            for vp in vps[:1]:
                if any(b.cell == vp.cell for b in e.agents[:MANI]):
                    continue
                for horizon in (vp.horizon, HORIZON_RANGE[0]):
                    obs = teleport(e, MANI, vp.cell, vp.rotation, horizon)[name]
                    ref.set_local_pose(own.get_local_pose())
                    e.scene.update_render(update_sensors=True, update_human_render_cameras=False)
                    ref.take_picture()
                    rgb = ref.get_picture("Color")[..., :3]
                    pos = ref.get_picture("PositionSegmentation")
                    assert np.array_equal(rgb, obs["rgb"]), (oid, vp, horizon)
                    assert np.array_equal(pos[..., 3], obs["segmentation"]), (oid, vp, horizon)
                    assert np.array_equal(own.get_picture("PositionSegmentation"), pos)
                    compared += 1
        assert compared > 10
    finally:
        e.close()
    v2 = HeteroTidyEnv(setting="I", split="test", visuals="realistic", obs_mode="none")
    try:
        assert v2._camera_shader.shader_pack == "minimal"  # v2 lights with its environment map
    finally:
        v2.close()
