"""Teams as capability vectors va = (Nav, Mani, Hei), after the paper's Section 5.3."""

from __future__ import annotations

import json
from pathlib import Path

Capability = tuple[int, int, int]

LOW_SCOUT: Capability = (1, 0, 0)  # navigation only, camera at about 0.22 m
HIGH_SCOUT: Capability = (1, 0, 1)  # navigation only, camera at about 0.9 m
MANIPULATOR: Capability = (1, 1, 1)  # navigation and manipulation, camera at about 0.9 m

SETTINGS: dict[str, tuple[Capability, ...]] = {
    "I": (LOW_SCOUT, HIGH_SCOUT, MANIPULATOR),
    "II": (LOW_SCOUT, HIGH_SCOUT, MANIPULATOR, MANIPULATOR),
}


def setting_of(members) -> str | None:
    """The named setting whose team is exactly these capabilities, or None."""
    members = tuple(tuple(int(v) for v in m) for m in members)
    return next((name for name, team in SETTINGS.items() if team == members), None)


def load_preset(path: str | Path) -> tuple[str | None, tuple[Capability, ...]]:
    """A team preset file (the top-level ``envs/*.json``): its setting name and its team."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
        members = data["team"]
    except (OSError, json.JSONDecodeError, KeyError, TypeError) as e:
        raise ValueError(
            f'{path}: not a team preset ({e}); expected JSON with a "team" list of '
            '(Nav, Mani, Hei) triples and optionally a "setting" name'
        ) from None
    try:
        return data.get("setting"), team(members)
    except (ValueError, TypeError) as e:
        raise ValueError(f"{path}: {e}") from None


def team(setting: str | list | tuple) -> tuple[Capability, ...]:
    """A preset name ("I", "II"), a preset file, or a list of capability triples, checked."""
    if isinstance(setting, str) and setting.endswith(".json"):
        return load_preset(setting)[1]
    if isinstance(setting, str):
        try:
            return SETTINGS[setting]
        except KeyError:
            raise ValueError(
                f"unknown setting {setting!r}; expected one of {sorted(SETTINGS)} "
                "or a list of (Nav, Mani, Hei) triples"
            ) from None
    try:
        members = tuple(tuple(int(v) for v in member) for member in setting)
    except (TypeError, ValueError):
        raise ValueError(
            f"team {setting!r}: expected a list of (Nav, Mani, Hei) triples of 0/1"
        ) from None
    for i, member in enumerate(members):
        if len(member) != 3 or any(v not in (0, 1) for v in member):
            raise ValueError(f"team member {i}: {member} is not a (Nav, Mani, Hei) triple of 0/1")
        if member[0] != 1:
            raise ValueError(f"team member {i}: {member} cannot navigate; every agent needs Nav=1")
    if not members:
        raise ValueError("a team needs at least one agent")
    return members  # type: ignore[return-value]


def setting_team(setting: str | list) -> tuple[str | None, tuple[Capability, ...]]:
    """What an env's ``setting`` argument names: a setting ("I"), a preset file or a list of
    capabilities, as (the setting's name or None, the team)."""
    if isinstance(setting, str) and setting.endswith(".json"):
        return load_preset(setting)
    return (setting if isinstance(setting, str) else None), team(setting)
