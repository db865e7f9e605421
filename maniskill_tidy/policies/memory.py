"""A learned team that remembers what it saw (DESIGN.md, "Beyond the paper").

Each agent keeps the memory of a camera-only heuristic agent (``policies/heuristic.py``): the
objects it detected, each judged misplaced with the placement knowledge D, its teammates'
reports, the cells it searched and the teammates it knows of; it sends and reads the messages
of its teacher's pattern (``MemoryConfig.teacher``). What is learned is the choice of the next
job: when an agent has none, a pointer (``models/memory_pointer.py``) scores every job it could
take (``policies/memory_candidates.py``: fetch one of the objects it remembers, check a
report, put down on one of the surfaces where D holds, explore, inspect, park) and the agent
takes the best; the walker carries the job out by shortest path, as the teacher's does. The
pointer is trained by behaviour cloning on the teacher's own choices over the same candidates
(``training/memory_trainer.py``).

Stand-ins, as for the heuristic teams: detections are the renderer's ground-truth
segmentation; whether an object is misplaced is D's answer for the surface it rests on, not a
learned detector's. The inspect candidate is the heuristic's choice of surface; the explore
candidates are the heuristic's choice of cell and, if the config asks (``explore``), the first
unsearched cell of other rooms. Because the pointer runs only when a job ends, an agent's step
costs about what a heuristic agent's does
(``python -m maniskill_tidy.bench --only teams --teams memory``).
"""

from __future__ import annotations

from pathlib import Path
from typing import ClassVar

import numpy as np
import torch

from maniskill_tidy.common.agent_files import resolve
from maniskill_tidy.models.checkpoints import (
    CheckpointError,
    load_memory,
    read,
    weights_digest,
)
from maniskill_tidy.policies.agent_config import MemoryConfig
from maniskill_tidy.policies.base import Agent, PublicInfo
from maniskill_tidy.policies.channel import Outbox
from maniskill_tidy.policies.heuristic import HeuristicAgent, HeuristicTeam
from maniskill_tidy.policies.heuristic_jobs import JobChoice
from maniskill_tidy.policies.memory_candidates import (
    KINDS,
    MemoryCandidates,
    numeric_width,
    teacher_slot,
)
from maniskill_tidy.policies.navigation import Cell
from maniskill_tidy.policies.walker import Job
from maniskill_tidy.tasks.teams import SETTINGS, setting_of

DEFAULT_CONFIG = Path("agents/memory.yaml")


class MemoryAgent(MemoryCandidates, HeuristicAgent):
    def __init__(self, name: str, public: PublicInfo, outbox: Outbox, team: MemoryTeam) -> None:
        super().__init__(name, public, outbox, team.communication)
        self.pointer = None if team.recording else team.pointer(public.capabilities)
        # teacher mode: (step, rows, the teacher's slot); sampling: (step, rows, slot, log p);
        # keeping the best choices (forks' bases): (step, rows, slot)
        self.decisions: list[tuple] = []
        self._choice: dict = {}
        self.index, self.choices = public.agents.index(name), 0  # this agent's decisions so far
        self.sampler = None  # the heuristic's own ``rng`` breaks its ties, as the teacher's
        if team.sampling_seed is not None:  # one stream per run seed, episode and agent
            self.sampler = np.random.default_rng([team.sampling_seed, public.seed, self.index])
        self.temperature = team.temperature
        self.explore = team.config.explore
        mine = team.override is not None and team.override[0] == self.index
        self.override = team.override if mine else None  # (agent, n, slot): one other choice
        self.keep = team.keep_decisions

    def _new_job(self, avoid: set[Cell]) -> Job:
        dist = self.planner.distances(self.state.cell, set(self.parked.values()))
        cands = self._candidates(avoid, dist)
        rows = self._rows(cands, dist)
        if self.pointer is None:  # teacher mode: the heuristic's own choice, recorded
            job = JobChoice._new_job(self, avoid)
            self.decisions.append((self.t, rows, teacher_slot(cands, job, self._looking)))
            return job
        inputs = (rows.kind[None], rows.type[None], rows.rest[None], rows.numeric[None],
                  rows.context[None])  # fmt: skip
        with torch.inference_mode():
            logits = self.pointer(*map(torch.from_numpy, inputs))[0]
        p = torch.softmax(logits, 0)
        if self.sampler is None:
            best = int(logits.argmax())
            if self.override is not None and self.override[1] == self.choices:
                best = self.override[2]  # a fork: another job at this one decision
            if self.keep:
                self.decisions.append((self.t, rows, best))
        else:  # training's rollouts: a choice drawn from the pointer's tempered distribution
            tempered = torch.log_softmax(logits / self.temperature, 0)
            q = tempered.double().exp().numpy()
            best = int(self.sampler.choice(len(q), p=q / q.sum()))
            self.decisions.append((self.t, rows, best, float(tempered[best])))
        self.choices += 1
        self._choice = {"job": KINDS[int(rows.kind[best])], "p": round(float(p[best]), 3),
                        "candidates": len(cands)}  # fmt: skip
        return self._job_for(cands[best], avoid)

    def trace(self) -> dict:
        """The pointer's choice in this step, if it made one (kind, its probability, how many
        candidates it had): recordings show it (``agents/NAME/choice``)."""
        choice, self._choice = self._choice, {}
        return choice


class MemoryTeam(HeuristicTeam):
    """Heuristic memory and messages, a learned choice of job (see the top)."""

    name = "memory"
    communication = "detection"
    perception = (
        "ground-truth segmentation + depth, open3d semantic map; misplaced by D; learned "
        "pointer over the remembered objects and jobs"
    )
    config_file: ClassVar[Path] = DEFAULT_CONFIG

    def __init__(
        self, recording: bool = False, sampling_seed: int | None = None, temperature: float = 1.0,
        override: tuple[int, int, int] | None = None, keep_decisions: bool = False,
    ) -> None:  # fmt: skip
        """``recording``: play the teacher's choices and keep every decision's candidates
        (``MemoryAgent.decisions``, of the agents in ``made``): training data.
        ``sampling_seed``: draw each choice from the pointer's distribution instead of taking
        the best, and keep it with its log-probability (the rollouts of
        ``training/memory_reinforce.py``); ``temperature`` divides the scores first (above 1:
        choices other than the best more often; the best is the same).
        ``override`` ``(agent, n, slot)``: the agent at that index takes candidate ``slot`` at
        its ``n``-th decision and the best everywhere else (a fork of
        ``training/memory_forks.py``); ``keep_decisions``: keep every best choice with its
        candidates, as ``(step, rows, slot)``."""

        self.config = MemoryConfig.load(resolve(self.config_file))
        self.recording = recording
        self.sampling_seed, self.temperature = sampling_seed, temperature
        self.override, self.keep_decisions = override, keep_decisions
        self.made: list[MemoryAgent] = []
        self._loaded: dict = {}

    @classmethod
    def trained_setting(cls, capabilities) -> str:
        setting = setting_of(capabilities)
        if setting is None:
            team = list(map(tuple, capabilities))
            raise ValueError(
                f"{cls.name} is trained for the teams of Settings {sorted(SETTINGS)}, not {team}"
            )
        return setting

    @classmethod
    def model_folder(cls, team) -> Path:
        cfg = MemoryConfig.load(resolve(cls.config_file))
        return resolve(cfg.out) / f"setting_{cls.trained_setting(team)}"

    @classmethod
    def missing_model(cls, team: tuple) -> str | None:
        hint = f"maniskill-tidy train {cls.config_file} --setting {cls.trained_setting(team)}"
        try:
            saved = read(cls.model_folder(team), hint)
        except CheckpointError as err:
            return str(err)

        explore = MemoryConfig.load(resolve(cls.config_file)).explore
        why = _other_candidates(saved, explore)
        return f"{cls.model_folder(team)}: {why}; train it again with `{hint}`" if why else None

    @classmethod
    def model_hash(cls, team: tuple) -> str:
        """A fingerprint of the pointer's weights (a resumed run with others is refused)."""
        return weights_digest(cls.model_folder(team))

    def pointer(self, capabilities: list):
        setting = self.trained_setting(capabilities)
        if setting not in self._loaded:
            torch.set_num_threads(1)  # batch-of-one inference beside the env and teammates
            model, saved = load_memory(self.model_folder(capabilities))
            why = _other_candidates(saved, self.config.explore)
            if why:
                raise CheckpointError(f"{self.model_folder(capabilities)}: {why}")
            self._loaded[setting] = model
        return self._loaded[setting]

    def use_pointer(self, setting: str, model) -> None:
        """Play ``model`` in ``setting`` instead of the saved weights (training's rollouts)."""
        torch.set_num_threads(1)
        self._loaded[setting] = model.eval()

    def make_agent(self, name: str, public: PublicInfo, outbox: Outbox) -> Agent:
        agent = MemoryAgent(name, public, outbox, self)
        if self.recording or self.sampling_seed is not None or self.keep_decisions:
            self.made.append(agent)
        return agent


def _other_candidates(saved: dict, explore: int) -> str | None:
    """Why a saved pointer does not fit a config's ``explore`` (None: it does)."""
    width, trained = saved["sizes"]["numeric"], saved.get("explore")  # saved only above 1
    if width != numeric_width(explore) or trained not in (None, explore):
        had = trained or ("1" if width == numeric_width(1) else "above 1")
        return f"a pointer trained with explore {had}, where the config asks for {explore}"
    return None


def memory_team_class(config: str | Path) -> type[MemoryTeam]:
    """A team class named after an object-memory config's ``name``; it sends its teacher's
    messages, or memory entries over HanGrCom links when the config has ``links``."""
    from maniskill_tidy.policies import POLICIES

    cfg = MemoryConfig.load(resolve(config))
    attrs = {"name": cfg.name, "config_file": resolve(config)}
    if cfg.links:  # the handshake's links carry memory entries
        from maniskill_tidy.policies.memory_links import LinkedMemoryTeam

        return type(f"MemoryTeam_{cfg.name}", (LinkedMemoryTeam,), attrs)
    attrs["communication"] = POLICIES[cfg.teacher].communication
    return type(f"MemoryTeam_{cfg.name}", (MemoryTeam,), attrs)
