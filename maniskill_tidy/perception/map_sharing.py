"""Maps of a team: merging them, and sharing them over the counting channel."""

from __future__ import annotations

import numpy as np

from maniskill_tidy.houses.schema import House
from maniskill_tidy.perception.semantic_map import SemanticMap


def merge(maps: list[np.ndarray]) -> np.ndarray:
    """The team map: a cell holds what any agent's map holds there (maps share one frame)."""
    if not maps:
        raise ValueError("merge needs at least one map")
    shapes = {m.shape for m in maps}
    if len(shapes) != 1:
        raise ValueError(f"maps to merge must share one frame and channels, got shapes {shapes}")
    return np.maximum.reduce(maps)


def share_maps(maps: dict[str, SemanticMap], channel) -> np.ndarray:
    """Broadcast every agent's top-down map to the others through ``channel`` (which counts
    rows x cols x (K + 2) values per receiver) and return the merged team map."""
    names = list(maps)
    for name, m in maps.items():
        others = [n for n in names if n != name]
        if others:
            channel.send(name, others, m.top_down(), kind="map")
    return merge([m.top_down() for m in maps.values()])


class TeamMaps:
    """Every agent's map of the current house, fed from the env's per-agent observations."""

    def __init__(self, house: House, instances: dict, agents: list[str], config=None) -> None:
        self.maps = {a: SemanticMap(house, instances, config) for a in agents}

    def update(self, obs: dict) -> None:
        """Fuse each observation of ``obs`` (agent name -> observation) into its agent's map."""
        for name, o in obs.items():
            self.maps[name].update(o)

    def merged(self) -> np.ndarray:
        return merge([m.top_down() for m in self.maps.values()])

    def share(self, channel) -> np.ndarray:
        return share_maps(self.maps, channel)
