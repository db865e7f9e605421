"""Which code produced a result: every run file, card and manifest records it."""

from __future__ import annotations

import subprocess
from pathlib import Path


def code_version() -> str:
    """The commit, with "-dirty" if the package's tracked files differ from it (result files
    elsewhere in the checkout, such as eval/results, do not count)."""
    package = Path(__file__).resolve().parents[1]

    def git(*args: str) -> str:
        return subprocess.run(
            ["git", "-C", str(package), *args], capture_output=True, text=True, check=True
        ).stdout.strip()

    try:
        rev = git("rev-parse", "--short", "HEAD")
        changed = git("status", "--porcelain", "--untracked-files=no", "--", str(package))
        return (rev + "-dirty" if changed else rev) or "unknown"
    except (OSError, subprocess.CalledProcessError):
        from importlib.metadata import version

        return f"maniskill-tidy {version('maniskill-tidy')}"
