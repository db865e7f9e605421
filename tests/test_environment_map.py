"""v2's environment map prefiltered once (sim/environment_map.py): the same pixels as SAPIEN's
own prefiltering, and a cache that is made once, read after, and remade when damaged."""

from __future__ import annotations

import hashlib
import struct

import gymnasium as gym
import numpy as np
import sapien

import maniskill_tidy.envs  # noqa: F401  (registers the envs)
from maniskill_tidy import assets
from maniskill_tidy.sim import environment_map


def pictures(env) -> str:
    """A hash of every camera's rgb over a few seeded steps, and of the third-person view."""
    digest = hashlib.sha256()
    env.action_space.seed(3)
    obs, _ = env.reset(seed=3)
    for _ in range(4):
        obs, *_ = env.step(env.action_space.sample())
        for view in obs.values():
            digest.update(np.ascontiguousarray(view["rgb"]).tobytes())
    digest.update(np.ascontiguousarray(env.unwrapped.render()).tobytes())
    return digest.hexdigest()


def level_zeroed(path, level: int, out) -> None:
    """A copy of the KTX file ``path`` with the texels of mip ``level`` set to zero."""
    data = bytearray(path.read_bytes())
    offset, length, _ = struct.unpack_from("<3Q", data, 80 + 24 * level)
    data[offset : offset + length] = bytes(length)
    out.write_bytes(bytes(data))


def test_the_cached_map_draws_what_sapiens_own_prefiltering_draws(tmp_path, monkeypatch):
    # the env builds its scene, and sets its cube map, at every reset
    env = gym.make("HeteroTidy-v2", setting="I", split="test", render_mode="rgb_array")
    source = str(assets.path(environment_map.SOURCE))
    try:
        cached = pictures(env)
        monkeypatch.setattr(environment_map, "cubemap", lambda: sapien.render.RenderCubemap(source))
        own = pictures(env)
        # the rough reflections read the prefiltered levels: a wrong level shows
        damaged = tmp_path / "damaged.ktx"
        level_zeroed(environment_map.cache_file(assets.path(environment_map.SOURCE)), 1, damaged)
        monkeypatch.setattr(
            environment_map, "cubemap", lambda: sapien.render.RenderCubemap(str(damaged))
        )
        wrong = pictures(env)
    finally:
        env.close()
    assert cached == own
    assert wrong != own


def test_the_map_is_prefiltered_once_then_read_from_the_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    made = []
    real = sapien.render.RenderCubemap

    def recording(path):
        made.append(path)
        return real(path)

    monkeypatch.setattr(environment_map.sapien.render, "RenderCubemap", recording)
    environment_map.cubemap.cache_clear()
    try:
        environment_map.cubemap()
        path = environment_map.cache_file(assets.path(environment_map.SOURCE))
        assert path.is_relative_to(tmp_path) and environment_map.complete(path)
        assert made == [str(assets.path(environment_map.SOURCE))]
        assert not [p for p in path.parent.iterdir() if p != path]  # no temporary file left

        environment_map.cubemap.cache_clear()
        environment_map.cubemap()
        assert made[-1] == str(path)  # read, not prefiltered again

        exported = path.read_bytes()
        path.write_bytes(exported[: len(exported) // 2])  # a worker killed mid-write, say
        assert not environment_map.complete(path)
        environment_map.cubemap.cache_clear()
        environment_map.cubemap()
        assert made[-1] == str(assets.path(environment_map.SOURCE))
        assert path.read_bytes() == exported

        blocked = tmp_path / "a file"
        blocked.write_text("")
        monkeypatch.setenv("XDG_CACHE_HOME", str(blocked))  # no cache can be made under it
        environment_map.cubemap.cache_clear()
        assert environment_map.cubemap() is not None  # prefiltered here, as SAPIEN would
        assert made[-1] == str(assets.path(environment_map.SOURCE))
    finally:
        environment_map.cubemap.cache_clear()  # later tests read the user's cache again
