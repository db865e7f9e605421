"""Teams: the privileged expert, the Random baseline, heuristic teams that see through their
cameras with the communication patterns of the paper's baselines, the learned team (the paper's
model), QMIX, and the object-memory team."""

from __future__ import annotations

import importlib
import inspect
import os
import sys
from importlib.metadata import entry_points
from pathlib import Path

from maniskill_tidy.common.agent_files import resolve
from maniskill_tidy.policies.agent_config import (
    PerceptionLook,
    QmixConfig,
    read_config,
    trainer_of,
)
from maniskill_tidy.policies.base import AnyTeam, PrivilegedTeam, Team
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


ENTRY_POINTS = "maniskill_tidy.teams"  # installed packages' teams: name = "module:TeamClass"


def plugin_class(spec: str, options: dict | None = None, name: str | None = None) -> type[AnyTeam]:
    """A team class named by ``package.module:TeamClass``, importable from the working folder
    too (as ``python -m`` would), so that worker processes find it by the same path;
    ``options``: keyword arguments its constructor gets, ``name``: its row's name (a YAML
    config's ``options:`` and ``name:``)."""
    module_name, _, attr = str(spec).partition(":")
    if not module_name or not attr:
        raise ValueError(f"--policy {spec!r}: expected package.module:TeamClass")
    if os.getcwd() not in sys.path and "" not in sys.path:
        sys.path.insert(0, os.getcwd())
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as e:
        raise ValueError(f"--policy {spec}: no module {e.name!r}; expected package.module:"
                         "TeamClass importable from the working folder") from None  # fmt: skip
    cls = getattr(module, attr, None)
    if not (isinstance(cls, type) and issubclass(cls, (Team, PrivilegedTeam))):
        raise ValueError(f"--policy {spec}: {module_name} has no Team class {attr!r}")
    if not options and name is None:
        return cls
    try:
        inspect.signature(cls).bind(**(options or {}))
    except TypeError as e:
        raise ValueError(f"{spec}: options {options}: {e}") from None

    def __init__(self) -> None:
        cls.__init__(self, **(options or {}))

    return type(cls.__name__, (cls,), {"__init__": __init__, "name": name or cls.name})


def installed_teams() -> dict[str, str]:
    """Teams of installed packages, by the ``maniskill_tidy.teams`` entry-point group."""
    return {ep.name: ep.value for ep in entry_points(group=ENTRY_POINTS)}


def team_class(policy: str) -> type[AnyTeam]:
    """A registered name, ``package.module:TeamClass``, a team of an installed package (entry
    point ``maniskill_tidy.teams``), or the path of an agent config (``agents/*.yaml``; one
    with ``team_class: package.module:TeamClass`` names its team that way, ``options:`` its
    arguments)."""
    if policy in POLICIES:
        return POLICIES[policy]
    if ":" in str(policy) and not str(policy).endswith((".yaml", ".yml")):
        return plugin_class(policy)
    if (installed := installed_teams()).get(policy):
        return plugin_class(installed[policy])
    if str(policy).endswith((".yaml", ".yml")):
        config = read_config(resolve(policy))
        if "team_class" in config:  # (``team:`` is a learned config's team of capabilities)
            options = config.get("options") or {}
            if not isinstance(options, dict):
                raise ValueError(f"{policy}: options: expected a mapping of arguments")
            return plugin_class(config["team_class"], options, config.get("name"))
        trainer = trainer_of(resolve(policy))
        if trainer == "qmix":
            cfg = QmixConfig.load(resolve(policy))
            return type(
                f"QmixTeam_{cfg.name}",
                (QmixTeam,),
                {
                    "name": cfg.name,
                    "folder": Path(cfg.out),
                    "look": PerceptionLook(cfg.perception),
                },
            )
        if trainer == "memory":
            from maniskill_tidy.policies.memory import memory_team_class

            return memory_team_class(policy)
        return learned_team_class(policy)
    raise ValueError(
        f"unknown policy {policy!r}; choose one of {sorted(POLICIES | installed_teams())}, "
        "package.module:TeamClass or an agent config (agents/*.yaml)"
    )


def make_team(policy: str) -> AnyTeam:
    team = team_class(policy)()
    team.spec = policy  # what an agent's own process makes its team from (eval/agent_processes)
    return team
