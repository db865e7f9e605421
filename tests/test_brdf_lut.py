"""The cached BRDF table (sim/brdf_lut.py): the same pixels as SAPIEN's own, computed once."""

from __future__ import annotations

import hashlib

import gymnasium as gym
import numpy as np
import pytest

import maniskill_tidy.envs  # noqa: F401  (registers the envs)
from maniskill_tidy.sim import brdf_lut


def pictures(env, seed: int, steps: int = 4) -> str:
    """A hash of every camera's rgb, depth and segmentation over a few seeded steps, and of the
    third-person view."""
    digest = hashlib.sha256()
    env.action_space.seed(seed)
    obs, _ = env.reset(seed=seed)
    for _ in range(steps):
        obs, *_ = env.step(env.action_space.sample())
        for view in obs.values():
            for key in ("rgb", "depth", "segmentation"):
                digest.update(np.ascontiguousarray(view[key]).tobytes())
    digest.update(np.ascontiguousarray(env.unwrapped.render()).tobytes())
    return digest.hexdigest()


@pytest.mark.parametrize("env_id", ["HeteroTidy-v1", "HeteroTidy-v2"])
def test_cameras_lent_the_cached_table_draw_what_sapiens_own_table_draws(env_id, monkeypatch):
    # the env lends the table at every reset (the scene and its cameras are rebuilt), so one
    # env plays the same episode with the cached table and with SAPIEN's own
    env = gym.make(env_id, setting="I", split="test", render_mode="rgb_array")
    try:
        lent = pictures(env, seed=3)
        monkeypatch.setattr(brdf_lut, "lend", lambda cameras: None)
        own = pictures(env, seed=3)
    finally:
        env.close()
    assert lent == own


def test_the_table_is_read_back_once_then_read_from_the_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    brdf_lut.table.cache_clear()
    try:
        fresh = brdf_lut.table()
        assert brdf_lut.cache_file().is_relative_to(tmp_path) and brdf_lut.cache_file().exists()
        assert fresh.shape == (brdf_lut.SIZE, brdf_lut.SIZE, 2) and fresh.dtype == np.float16
        # a split-sum table: scale and bias of the Fresnel term, both in [0, ~1.5], varying
        wide = fresh.astype(np.float32)
        assert 0 <= wide.min() and wide.max() < 2 and wide.std() > 0.1

        def no_render():
            raise AssertionError("read back again although the cache holds the table")

        read_back = brdf_lut.read_back
        monkeypatch.setattr(brdf_lut, "read_back", no_render)
        brdf_lut.table.cache_clear()
        assert np.array_equal(brdf_lut.table(), fresh)

        brdf_lut.cache_file().write_bytes(b"damaged")  # a worker killed mid-write, say
        monkeypatch.setattr(brdf_lut, "read_back", read_back)
        brdf_lut.table.cache_clear()
        assert np.array_equal(brdf_lut.table(), fresh)
        assert np.array_equal(np.load(brdf_lut.cache_file()), fresh)
    finally:
        brdf_lut.table.cache_clear()  # later tests read the user's cache again
