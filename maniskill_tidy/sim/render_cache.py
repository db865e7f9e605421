"""Where the renderer's once-per-machine results live (the BRDF table, the prefiltered
environment map): the user's cache, one file per driver, since another driver may compute other
bits."""

from __future__ import annotations

import os
from pathlib import Path

import sapien


def driver() -> str:
    """SAPIEN, the render device and lavapipe's library file (path, size, time)."""
    summary = sapien.render.get_device_summary()  # also loads the driver
    try:
        with open("/proc/self/maps") as maps:  # Linux: the libraries this process mapped
            libraries = sorted({line.split()[-1] for line in maps if "libvulkan_lvp" in line})
    except OSError:
        libraries = []
    files = [f"{p} {os.stat(p).st_size} {os.stat(p).st_mtime_ns}" for p in libraries]
    return "\n".join([sapien.__version__, summary, *files])


def cache_dir() -> Path:
    root = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return root / "maniskill-tidy"
