"""The v2 look's assets: derived meshes, textures and their manifest (package data).

``derive.py`` makes them once from offline sources (``maniskill-tidy derive-assets``); at run
time the env reads only what is here, through :func:`manifest` and :func:`path`.
"""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path

HERE = Path(__file__).parent
ASSET_DIR = HERE / "data"
SELECTION = HERE / "selection.toml"


@cache
def manifest() -> dict[str, dict]:
    """Every derived file (relative to ``data/``) -> kind, type, sources, sha256, triangles."""
    path = ASSET_DIR / "manifest.json"
    if not path.exists():
        raise FileNotFoundError(
            f"{path}: the v2 asset set is missing; it ships with the package "
            "(re-derive it with `make assets`)"
        )
    return json.loads(path.read_text())


def path(rel: str) -> Path:
    return ASSET_DIR / rel


def variants(kind: str, type_name: str) -> list[str]:
    """The files that can dress a furniture or object type, in a fixed order."""
    prefix = f"{'furniture' if kind == 'furniture' else 'objects'}/{type_name}/"
    return sorted(rel for rel in manifest() if rel.startswith(prefix))
