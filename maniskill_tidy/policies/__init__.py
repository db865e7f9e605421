"""Teams: the privileged expert, the Random baseline, heuristic teams that see through their
cameras with the communication patterns of the paper's baselines, the learned team (the paper's
model), QMIX, and the object-memory team."""

from __future__ import annotations

from pathlib import Path

from maniskill_tidy.policies.agent_config import QmixConfig, trainer_of
from maniskill_tidy.policies.base import AnyTeam
from maniskill_tidy.policies.expert import ExpertTeam
from maniskill_tidy.policies.heuristic import (
    BroadcastTeam,
    CentralTeam,
    DetectionCommTeam,
    NoCommTeam,
    SingleAgent,
)
from maniskill_tidy.policies.learned import LearnedTeam, learned_team_class
from maniskill_tidy.policies.memory import MemoryTeam
from maniskill_tidy.policies.qmix_team import QmixTeam
from maniskill_tidy.policies.random_team import RandomTeam

POLICIES: dict[str, type[AnyTeam]] = {
    cls.name: cls
    for cls in (
        ExpertTeam,
        RandomTeam,
        SingleAgent,
        NoCommTeam,
        DetectionCommTeam,
        BroadcastTeam,
        CentralTeam,
        LearnedTeam,
        QmixTeam,
        MemoryTeam,
    )
}


def team_class(policy: str) -> type[AnyTeam]:
    """A registered name, or the path of an agent config (``agents/*.yaml``)."""
    if policy in POLICIES:
        return POLICIES[policy]
    if str(policy).endswith((".yaml", ".yml")):
        from maniskill_tidy.policies.learned import resolve

        trainer = trainer_of(resolve(policy))
        if trainer == "qmix":
            cfg = QmixConfig.load(resolve(policy))
            return type(f"QmixTeam_{cfg.name}", (QmixTeam,), {"name": cfg.name,
                                                             "folder": Path(cfg.out)})  # fmt: skip
        if trainer == "memory":
            from maniskill_tidy.policies.memory import memory_team_class

            return memory_team_class(policy)
        return learned_team_class(policy)
    raise ValueError(
        f"unknown policy {policy!r}; choose one of {sorted(POLICIES)} or an agent config "
        "(agents/*.yaml)"
    )


def make_team(policy: str) -> AnyTeam:
    team = team_class(policy)()
    team.spec = policy  # what an agent's own process makes its team from (eval/agent_processes)
    return team
