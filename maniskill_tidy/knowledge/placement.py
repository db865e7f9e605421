"""The discriminator D(object, receptacle, room) and the reasonable locations of each type.

The derivation rule lives in ``knowledge/derive.py`` and is copied into ``placement.json``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

from maniskill_tidy.knowledge.catalog import ROOM_TYPES, _read

FLOOR = "Floor"


@dataclass(frozen=True)
class PlacementKnowledge:
    reasonable: dict[str, frozenset[tuple[str, str]]]  # object type -> {(receptacle, room)}
    rule: str

    def D(self, object_type: str, receptacle_type: str, room_type: str) -> bool:  # noqa: N802
        """True when ``object_type`` may rest on/in ``receptacle_type`` in ``room_type``.

        Unknown room types raise; unknown object or receptacle types are simply not reasonable.
        Nothing is reasonable on the floor.
        """
        if room_type not in ROOM_TYPES:
            raise ValueError(f"unknown room type {room_type!r}; expected one of {ROOM_TYPES}")
        if receptacle_type == FLOOR:
            return False
        return (receptacle_type, room_type) in self.reasonable.get(object_type, frozenset())

    def locations(self, object_type: str) -> frozenset[tuple[str, str]]:
        """Every reasonable (receptacle type, room type) for ``object_type``."""
        return self.reasonable.get(object_type, frozenset())

    def receptacles_in(self, object_type: str, room_type: str) -> set[str]:
        return {p for p, r in self.locations(object_type) if r == room_type}


@lru_cache(maxsize=1)
def load_placement() -> PlacementKnowledge:
    raw = _read("placement.json")
    reasonable = {
        o: frozenset((e["receptacle"], e["room"]) for e in entries.values())
        for o, entries in raw["reasonable"].items()
    }
    return PlacementKnowledge(reasonable=reasonable, rule=raw["rule"])
