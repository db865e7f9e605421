"""One episode, played the one way every path plays it: evaluation, demonstrations, recordings.

This loop is where "what a team may see" (``policies/base.py``) is enforced. A camera-only
team's agents are made fresh for the episode, each bound to its own outbox; every step each
active agent is given its own :class:`AgentView` (its observation, read-only, and the outcome
of its own last action) and nothing else; the communication rounds run through the counting
:class:`Channel`; each agent then acts on its inbox. A privileged team (the expert) is handed
the env instead.

Observers watch the episode with full access (they are the benchmark's instruments, not part
of the team): a recorder, the demonstration writer. Each may define ``start(env, team,
channel)``, ``executing(agents)`` (the team's agents, for instruments that compare what they
made of their frames with the truth), ``observed(t, obs, info)`` (the observation the team
decides on at step ``t``), ``decided(t, actions, labels)`` (before the env steps),
``traced(t, traces)`` (what the agents report beyond their labels, e.g. HanGrCom's T and
groups), ``log_step(t, obs, actions, info, channel, labels)`` (after) and ``finish(record)``.
"""

from __future__ import annotations

import dataclasses
import re
import time
from typing import Any

import numpy as np

from maniskill_tidy.common.parallel import agent_pool
from maniskill_tidy.eval import agent_processes
from maniskill_tidy.eval.metrics import EpisodeRecord
from maniskill_tidy.policies.base import (
    OBSERVATION_KEYS,
    Agent,
    AgentAction,
    AgentView,
    AnyTeam,
    Label,
    PrivilegedTeam,
    PublicInfo,
)
from maniskill_tidy.policies.channel import CENTRAL, Channel, Outbox
from maniskill_tidy.policies.pixels import PixelsTeam


def _read_only(obs: dict) -> dict[str, np.ndarray]:
    out = {}
    for key, value in obs.items():
        if key not in OBSERVATION_KEYS:
            raise KeyError(f"observation key {key!r} is not one an agent may see")
        view = np.asarray(value).view()
        view.flags.writeable = False
        out[key] = view
    return out


def _pixels_only(obs: dict) -> dict:
    """What a pixels-track agent may see of its observation (DESIGN.md, "Perception tracks"):
    no segmentation, and of what it holds only whether it holds something."""
    out = {k: v for k, v in obs.items() if k != "segmentation"}
    if "held" in out:
        out["held"] = np.int32(int(out["held"]) > 0)
    return out


def _id_redactor(env: Any):
    """For a pixels team: a failure reason with every object id in it replaced by "an object"
    (the env's reasons may name what a pixel or a plain PickUp resolved to, "Apple_3 is out of
    reach"); furniture ids are the public floor plan's and stay."""
    ids = sorted({i.id for i in env.instances.values() if i.kind == "object"}, key=len,
                 reverse=True)  # fmt: skip
    if not ids:
        return lambda reason: reason
    pattern = re.compile("|".join(re.escape(i) for i in ids))  # longest first: Apple_10 wins
    return lambda reason: pattern.sub("an object", reason)


class Execution:
    """One team playing one episode: builds its agents and steps them decentrally. A pixels
    team (``team.pixels``) is given no instance table and observations without segmentation
    or instance ids, whatever the env renders (recordings may want every image)."""

    def __init__(self, team: AnyTeam, env: Any, seed: int) -> None:
        self.team, self.env = team, env
        self.pixels = bool(getattr(team, "pixels", False))
        self.redact = _id_redactor(env) if self.pixels else (lambda reason: reason)
        public = PublicInfo.of(env, seed, oracle=getattr(team, "oracle", False))
        if self.pixels:
            public = dataclasses.replace(public, instances={})
        self.channel = Channel(public.agents, central=team.central)
        self.agents: dict[str, Agent] = {}
        self.central_node = None
        self.t = 0
        self.pool = agent_pool() if getattr(team, "threadsafe_agents", False) else None
        self.remote = False  # agents in processes of their own (eval/agent_processes.py)
        self.decide_every = 1  # the team's sub-goal steps (see below)
        if isinstance(team, PrivilegedTeam):
            team.reset(public, env)
            return
        if agent_processes.wanted(team, len(public.agents)):
            self.remote = True
            hosts = agent_processes.hosts(len(public.agents))
            self.agents = {
                name: agent_processes.RemoteAgent(
                    host, team, name, public, Outbox(self.channel, name)
                )
                for host, name in zip(hosts, public.agents, strict=True)
            }
            for agent in self.agents.values():  # built side by side, in the hosts
                agent.collect()
        else:
            self.agents = {
                name: team.make_agent(name, public, Outbox(self.channel, name))
                for name in public.agents
            }
        if team.central:  # the central node thinks in this process either way
            self.central_node = team.make_central(public, Outbox(self.channel, CENTRAL))
        # the steps between sub-goal steps are quiet (no message sent or read) where the whole
        # team keeps one cadence and no central node sends
        cadences = {a.decide_every for a in self.agents.values()}
        self.decide_every = cadences.pop() if len(cadences) == 1 and not team.central else 1

    def step(self, obs: dict, info: dict) -> dict[str, AgentAction]:
        """Every active agent's action for this step."""
        self.channel.new_step()
        if isinstance(self.team, PrivilegedTeam):
            return self.team.act(info)
        active = [a.name for a in self.env.agents if not a.stopped]
        failed = info.get("failed", {})
        seen = _pixels_only if self.pixels else (lambda o: o)
        views = {
            n: AgentView(n, self.t, _read_only(seen(obs[n])), self.redact(failed.get(n, "")))
            for n in active
        }
        if self.t % self.decide_every:  # between the team's sub-goal steps
            acts = self._each("quiet_step", {n: (views[n], self.team.rounds) for n in active})
            if self.channel.step_messages:  # every sender named: the agents ran side by side
                sent = sorted({f"{m.sender} ({m.kind})" for m in self.channel.step_messages})
                raise RuntimeError(
                    f"{', '.join(sent)} sent at step {self.t}, between the team's sub-goal "
                    f"steps (decide_every {self.decide_every}: expected no message)"
                )
            self.t += 1
            return dict(zip(active, acts, strict=True))
        if isinstance(self.team, PixelsTeam) and not self.remote:  # the benchmark's segmenter,
            # one call for all frames; a team's own code never gets its frames together
            self.team.prepare({n: views[n].obs for n in active})
        self._each("observe", {n: (views[n],) for n in active})
        for r in range(self.team.rounds):
            self.channel.round = r
            # what is sent in round r is read from round r + 1 on: the agents may send at once
            self._each("send", {n: (r, self.channel.inbox(n, before_round=r)) for n in active})
            if self.central_node is not None:
                self.central_node.send(r, self.channel.inbox(CENTRAL, before_round=r + 1))
        self.t += 1
        acts = self._each("act", {n: (self.channel.inbox(n),) for n in active})
        return dict(zip(active, acts, strict=True))

    def _each(self, method: str, args: dict[str, tuple]) -> list:
        """``agent.method(*args[name])`` for every agent, in order. Where the team allows (each
        agent touches only its own state, so the results are those of one thread), on the agent
        threads, or posted to every agent's process before any answer is read; their messages
        reach the channel in the agents' order either way."""
        names = list(args)
        if self.remote:
            for n in names:
                self.agents[n].post(method, *args[n])
            results, failure = [], None
            for n in names:  # every answer is read, so no host is left busy by one that failed
                try:
                    results.append(self.agents[n].collect())
                except RuntimeError as err:
                    failure = failure or err
            if failure is not None:
                raise failure
            return results
        if self.pool is None or len(names) < 2 or method == "send":
            return [getattr(self.agents[n], method)(*args[n]) for n in names]
        return list(self.pool.map(lambda n: getattr(self.agents[n], method)(*args[n]), names))

    def traces(self) -> dict[str, dict]:
        if isinstance(self.team, PrivilegedTeam):
            return {}
        return {name: tr for name, agent in self.agents.items() if (tr := agent.trace())}

    def labels(self) -> dict[str, Label]:
        if isinstance(self.team, PrivilegedTeam):
            return self.team.labels()
        out = {}
        for name, agent in self.agents.items():
            label = agent.label()
            if label is not None:
                out[name] = label
        return out


def _call(observers, method: str, *args) -> None:
    for o in observers:
        fn = getattr(o, method, None)
        if fn is not None:
            fn(*args)


def play_episode(env, team: AnyTeam, index: int, seed: int, observers=()) -> EpisodeRecord:
    """Play episode ``index`` of the env's split with ``team``; returns its record."""
    u = env.unwrapped
    start = time.perf_counter()
    obs, info = env.reset(seed=seed, options={"episode": index})
    execution = Execution(team, u, seed)
    _call(observers, "start", u, team, execution.channel)
    _call(observers, "executing", execution.agents)
    done, t, failed = False, 0, 0
    while not done:
        _call(observers, "observed", t, obs, info)
        actions = execution.step(obs, info)
        labels = {n: label for n, label in execution.labels().items() if n in actions}
        _call(observers, "decided", t, actions, labels)
        _call(
            observers, "traced", t, {n: tr for n, tr in execution.traces().items() if n in actions}
        )
        obs, _, terminated, truncated, info = env.step(actions)
        t += 1
        failed += sum(1 for reason in info["failed"].values() if reason)
        _call(observers, "log_step", t, obs, actions, info, execution.channel, labels)
        done = terminated or truncated
    misplaced = set(u.misplaced)
    record = EpisodeRecord(
        episode=u.episode.id,
        task_kind=u.episode.task.kind,
        k=len(misplaced),
        success=bool(info["success"]),
        reasonable=int(info["n_reasonable"]),
        found=len(misplaced & set(info["picked"])),
        length=max(a.steps for a in u.agents),
        comm=execution.channel.total,
        agents=len(u.agents),
        seed=seed,
        seconds=round(time.perf_counter() - start, 3),
        failed_actions=failed,
    )
    _call(observers, "finish", record)
    return record
