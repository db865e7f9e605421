"""The type catalog: which object types exist, which are pickupable or receptacles, their sizes."""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources

ROOM_TYPES: tuple[str, ...] = ("Kitchen", "LivingRoom", "Bedroom", "Bathroom")


@dataclass(frozen=True)
class TypeInfo:
    name: str
    pickupable: bool
    receptacle: bool
    openable: bool
    size: tuple[float, float, float] | None  # (width x, depth y, height z) in metres, median asset
    room_weights: dict[str, int]  # ProcTHOR's 0/1/2 likelihood of the type per room type


@dataclass(frozen=True)
class Catalog:
    """Categories derived from ProcTHOR's databases (see ``knowledge/derive.py``)."""

    categories: tuple[str, ...]  # every object type, architecture excluded: map channels
    pickupable: tuple[str, ...]
    receptacles: tuple[str, ...]  # includes "Floor", where D is always false
    tidyable: tuple[str, ...]  # pickupables with at least one reasonable location
    types: dict[str, TypeInfo]

    def info(self, name: str) -> TypeInfo:
        try:
            return self.types[name]
        except KeyError:
            raise KeyError(f"unknown object type {name!r}; see Catalog.categories") from None

    def category_index(self, name: str) -> int:
        return self.categories.index(name)


def _read(name: str) -> dict:
    return json.loads(
        resources.files("maniskill_tidy.knowledge").joinpath("data", name).read_text()
    )


@lru_cache(maxsize=1)
def load_catalog() -> Catalog:
    raw = _read("catalog.json")
    types = {
        name: TypeInfo(
            name=name,
            pickupable=t["pickupable"],
            receptacle=t["receptacle"],
            openable=t["openable"],
            size=tuple(t["size"]) if t["size"] else None,
            room_weights=t["room_weights"],
        )
        for name, t in raw["types"].items()
    }
    return Catalog(
        categories=tuple(raw["categories"]),
        pickupable=tuple(raw["pickupable"]),
        receptacles=tuple(raw["receptacles"]),
        tidyable=tuple(raw["tidyable"]),
        types=types,
    )


@lru_cache(maxsize=1)
def load_assets() -> dict[str, tuple[str, float, float, float]]:
    """ProcTHOR asset id -> (object type, width x, depth y, height z), for importing houses."""
    return {k: tuple(v) for k, v in _read("assets.json")["assets"].items()}
