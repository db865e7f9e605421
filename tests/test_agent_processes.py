"""Agents in processes of their own (eval/agent_processes.py): when the runner uses them, what
crosses to a host and back, and how a host's failure reaches the runner. That the records are
those of one thread is tests/test_teams.py's threads-or-processes test."""

from __future__ import annotations

import os

import numpy as np
import pytest

from maniskill_tidy.eval import agent_processes
from maniskill_tidy.eval.agent_processes import SharedFrames, _unpack, wanted
from maniskill_tidy.policies import make_team
from maniskill_tidy.policies.heuristic import NoCommTeam


@pytest.mark.parametrize(
    ("policy", "knob", "threads", "agents", "expected"),
    [
        ("hangrcom", None, "2", 3, True),  # a learned team where its process has 2 cores
        ("hangrcom", None, "1", 3, False),  # one core each (eval --workers 2 on 2 cores)
        ("hangrcom", "0", "2", 3, False),
        ("hangrcom", None, "2", 1, False),  # SA: nobody to think beside
        ("heuristic-none", None, "2", 3, False),  # its agents think too little to pay
        ("heuristic-none", "1", "1", 3, True),  # asked for
        ("expert", "1", "2", 3, False),  # privileged: one controller, no agents
    ],
)
def test_agents_get_processes_where_they_pay_or_are_asked_for(
    policy, knob, threads, agents, expected, monkeypatch
):
    if knob is None:
        monkeypatch.delenv("TIDY_AGENT_PROCESSES", raising=False)
    else:
        monkeypatch.setenv("TIDY_AGENT_PROCESSES", knob)
    monkeypatch.setenv("TIDY_AGENT_THREADS", threads)
    assert wanted(make_team(policy), agents) is expected


def test_a_team_not_made_by_make_team_stays_in_process_and_a_bad_knob_is_named(monkeypatch):
    monkeypatch.setenv("TIDY_AGENT_PROCESSES", "1")
    assert not wanted(NoCommTeam(), 3)  # a host could not make it again
    monkeypatch.setenv("TIDY_AGENT_PROCESSES", "yes")
    with pytest.raises(ValueError, match="TIDY_AGENT_PROCESSES='yes': expected 0 or 1"):
        wanted(make_team("hangrcom"), 3)


def test_frames_cross_through_shared_memory_as_private_read_only_copies():
    frames = SharedFrames()
    rng = np.random.default_rng(0)
    obs = {
        "rgb": rng.integers(0, 255, (224, 224, 3), dtype=np.uint8),
        "depth": rng.random((224, 224), dtype=np.float32),
        "pose": np.array([1.0, 2.0, 90.0], dtype=np.float32),  # small: inline
        "held": np.array(-1, dtype=np.int32),
    }
    buffers: dict = {}
    try:
        path, packed = frames.pack(obs)
        assert packed["pose"] is not None and not isinstance(packed["pose"], tuple)
        assert packed["rgb"][0] == "shared" and packed["depth"][0] == "shared"
        got = _unpack(buffers, path, packed)
        frames.mapped()  # the host has it: the name goes
        assert not os.path.exists(path)
        for key, value in obs.items():
            assert got[key].dtype == value.dtype and np.array_equal(got[key], value), key
            assert not got[key].flags.writeable, key
        frames.pack({k: np.zeros_like(v) for k, v in obs.items()})  # the next step's frames
        assert got["rgb"].any()  # the agent's copy is its own
        bigger = {"rgb": np.ones((448, 448, 3), dtype=np.uint8)}
        path2, packed = frames.pack(bigger)  # a buffer too small is replaced
        assert path2 != path and os.path.exists(path2)
        assert np.array_equal(_unpack(buffers, path2, packed)["rgb"], bigger["rgb"])
    finally:
        for b in buffers.values():
            b.close()
        frames.close()
    assert frames.path is None and not os.path.exists(path2)


def test_a_hosts_failure_reaches_the_runner_with_its_cause_and_a_dead_host_is_replaced():
    import gymnasium as gym

    from maniskill_tidy.eval.runner import RunConfig
    from maniskill_tidy.policies.base import AgentView, PublicInfo
    from maniskill_tidy.policies.channel import Channel, Outbox

    cfg = RunConfig("heuristic-none", "I", "test", None)
    env = gym.make(cfg.env, **cfg.env_kwargs(False), max_steps=5)
    try:
        obs, _ = env.reset(seed=0, options={"episode": 0})
        public = PublicInfo.of(env.unwrapped, 0)
    finally:
        env.close()
    name = public.agents[0]
    (host,) = agent_processes.hosts(1)
    agent = agent_processes.RemoteAgent(
        host, make_team("heuristic-none"), name, public, Outbox(Channel(public.agents), name)
    )
    agent.collect()
    agent.observe(AgentView(name, 0, obs[name], ""))  # a real step works
    with pytest.raises(RuntimeError, match="(?s)during 'observe'.*KeyError"):
        agent.observe(AgentView(name, 1, {}, ""))  # no observation at all
    host.process.kill()
    host.process.join()
    with pytest.raises(RuntimeError, match="host process died during 'act'"):
        agent.act([])
    (again,) = agent_processes.hosts(1)
    assert again is not host and again.process.is_alive()


def test_a_step_that_fails_in_one_host_leaves_every_host_free_for_the_next(monkeypatch):
    import gymnasium as gym

    from maniskill_tidy.eval.episode import Execution
    from maniskill_tidy.eval.runner import RunConfig

    monkeypatch.setenv("TIDY_AGENT_PROCESSES", "1")
    cfg = RunConfig("heuristic-none", "I", "test", None)
    env = gym.make(cfg.env, **cfg.env_kwargs(False), max_steps=5)
    try:
        obs, info = env.reset(seed=0, options={"episode": 0})
        team = make_team("heuristic-none")
        execution = Execution(team, env.unwrapped, 0)
        assert execution.remote
        names = list(obs)
        with pytest.raises(RuntimeError, match="during 'observe'"):
            execution.step({**obs, names[1]: {}}, info)  # one agent's observation missing
        actions = Execution(team, env.unwrapped, 0).step(obs, info)  # no host left busy
        assert set(actions) == set(names)
    finally:
        env.close()
