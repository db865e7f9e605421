"""Teams: the privileged expert, the Random baseline and heuristic teams that see through
their cameras, with the communication patterns of the paper's baselines."""

from __future__ import annotations

from maniskill_tidy.policies.base import AnyTeam
from maniskill_tidy.policies.expert import ExpertTeam
from maniskill_tidy.policies.heuristic import (
    BroadcastTeam,
    CentralTeam,
    DetectionCommTeam,
    NoCommTeam,
    SingleAgent,
)
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
    )
}


def make_team(name: str) -> AnyTeam:
    if name not in POLICIES:
        raise ValueError(f"unknown policy {name!r}; choose one of {sorted(POLICIES)}")
    return POLICIES[name]()
