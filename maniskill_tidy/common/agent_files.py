"""Where a learned team's files are: configs and weights named ``agents/...`` as configs name them.

One search order, for every command and every process: the path as given (absolute, or
relative to the working folder, where ``maniskill-tidy train`` writes); then under
``$MANISKILL_TIDY_AGENTS``, a folder that stands for ``agents/`` (weights trained or kept
elsewhere); then the agents this package ships (``maniskill_tidy/agents``: in a checkout a link
to its ``agents/``, in the wheel the shipped configs and fp16 weights, experiments left out).
So a team trained in the working folder replaces the shipped one of the same name.
"""

from __future__ import annotations

import os
from pathlib import Path

AGENTS_ENV = "MANISKILL_TIDY_AGENTS"
SHIPPED = Path(__file__).resolve().parents[1] / "agents"
WHERE = (f"looked in the working folder, ${AGENTS_ENV} (a folder standing for agents/) and the "
         "agents the package ships")  # fmt: skip


def candidates(path: str | Path) -> list[Path]:
    """The places ``path`` may be, in the order they are tried."""
    path = Path(path)
    if path.is_absolute() or not path.parts or path.parts[0] != "agents":
        return [path]
    rest = Path(*path.parts[1:])
    out = [path]
    if os.environ.get(AGENTS_ENV):
        out.append(Path(os.environ[AGENTS_ENV]) / rest)
    out.append(SHIPPED / rest)
    return out


def resolve(path: str | Path) -> Path:
    """The first of :func:`candidates` that exists, else the path as given (the place a
    missing file's error names, and where training writes it)."""
    found = next((p for p in candidates(path) if p.exists()), None)
    return found if found is not None else Path(path)
