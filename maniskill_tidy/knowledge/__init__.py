"""Commonsense placement knowledge: type catalog and the reasonable-placement discriminator D."""

from maniskill_tidy.knowledge.catalog import ROOM_TYPES, Catalog, TypeInfo, load_catalog
from maniskill_tidy.knowledge.placement import FLOOR, PlacementKnowledge, load_placement

__all__ = [
    "FLOOR",
    "ROOM_TYPES",
    "Catalog",
    "PlacementKnowledge",
    "TypeInfo",
    "load_catalog",
    "load_placement",
]
