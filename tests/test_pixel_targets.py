"""PickUp and PutDown aimed at a pixel of the agent's own frame (the pixels track), and an env
that takes pixel targets only."""

from __future__ import annotations

import numpy as np
import pytest

from maniskill_tidy.envs.actions import Action, Targeted
from maniskill_tidy.envs.hetero_tidy import HeteroTidyEnv


def _pixel_of(seg: np.ndarray, sid: int) -> tuple[int, int]:
    rows, cols = np.nonzero(seg.reshape(seg.shape[:2]) == sid)
    k = np.argmin((rows - rows.mean()) ** 2 + (cols - cols.mean()) ** 2)  # a pixel of the mask
    return int(cols[k]), int(rows[k])


def _surface_pixel(env, name: str, seg: np.ndarray, sid: int, target: str) -> tuple[int, int]:
    """The pixel of the piece's mask nearest where the named surface's centre projects."""
    from maniskill_tidy.envs.manipulation import project

    fid, _, sname = target.partition("/")
    f = env.hs.furniture[fid]
    centre = env.manipulation.surface_centre(f, f.surface(sname))
    intrinsic, extrinsic, _, _ = env._camera_matrices(name)
    uv = project(centre + [0, 0, 0.02], intrinsic, extrinsic)
    rows, cols = np.nonzero(seg.reshape(seg.shape[:2]) == sid)
    k = np.argmin((cols + 0.5 - uv[0]) ** 2 + (rows + 0.5 - uv[1]) ** 2)
    return int(cols[k]), int(rows[k])


def test_the_expert_tidies_with_pixel_targets_instead_of_ids():
    """The expert's named PickUp and PutDown targets, replaced by a pixel of that object, or of
    that furniture where its surface projects, pick and place the same things."""
    from maniskill_tidy.eval.episode import Execution
    from maniskill_tidy.policies import make_team

    env = HeteroTidyEnv(setting="I", split="test", obs_mode="rgb+depth+segmentation")
    try:
        obs, info = env.reset(seed=0, options={"episode": 0})
        execution = Execution(make_team("expert"), env, 0)
        ids = {inst.id: sid for sid, inst in env.instances.items()}
        aimed = {"PickUp": 0, "PutDown": 0}
        placed = []  # (object, the surface the expert named, the one it landed on)
        done = False
        while not done:
            actions = execution.step(obs, info)
            intended = {}
            for name, act in actions.items():
                if isinstance(act, Targeted) and isinstance(act.target, str):
                    kind = Action(act.action).name
                    sid = ids.get(act.target.split("/")[0])
                    seg = obs[name]["segmentation"]
                    if sid is None or not (seg == sid).any():
                        continue
                    if "/" in act.target:
                        pixel = _surface_pixel(env, name, seg, sid, act.target)
                        intended[name] = (env.agents[env.agent_names.index(name)].held,
                                          act.target)  # fmt: skip
                    else:
                        pixel = _pixel_of(seg, sid)
                    actions[name] = Targeted(act.action, pixel)
                    aimed[kind] += 1
            obs, _, terminated, truncated, info = env.step(actions)
            for name, (oid, target) in intended.items():
                if not info["failed"][name]:
                    st = env.hs.state[oid]
                    placed.append((oid, target, f"{st.receptacle}/{st.surface}"))
            done = terminated or truncated
        assert aimed["PickUp"] >= 1 and aimed["PutDown"] >= 1, aimed
        assert placed and all(want == got for _, want, got in placed), placed
        assert info["success"], "the episode the expert solves with ids, solved with pixels"
    finally:
        env.close()


def test_a_pixels_env_refuses_id_targets_and_names_a_bad_pixel():
    env = HeteroTidyEnv(setting="I", split="test", obs_mode="rgb+depth", targets="pixels")
    try:
        obs, _ = env.reset(seed=0, options={"episode": 0})
        assert "segmentation" not in obs["agent_2"]
        some = {n: int(Action.LookDown) for n in env.agent_names}
        with pytest.raises(ValueError, match="pixel targets only"):
            env.step(some | {"agent_2": Targeted(Action.PickUp, "Apple_0")})
        with pytest.raises(TypeError, match=r"\(x, y\), two integers"):
            env.step(some | {"agent_2": Targeted(Action.PickUp, (1.5, 2))})
        _, _, _, _, info = env.step(some | {"agent_2": Targeted(Action.PickUp, (500, 3))})
        assert "outside the 224 x 224 frame" in info["failed"]["agent_2"]
        _, _, _, _, info = env.step(some | {"agent_2": Targeted(Action.PickUp, (112, 2))})
        assert "no object drawn there" in info["failed"]["agent_2"]
    finally:
        env.close()
    with pytest.raises(ValueError, match="targets='names'"):
        HeteroTidyEnv(setting="I", split="test", targets="names")
