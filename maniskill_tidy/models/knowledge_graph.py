"""The commonsense graph: object, receptacle and room types, linked by what the train houses show.

Stand-in: the paper filters Visual Genome relations; here the edges are placements counted in
the *train* houses of the dataset (an object on a receptacle type, a receptacle in a room type,
an object in a room type), never the ``D`` table itself, so that the learned modules must
generalise from what the houses show. Edge weights are log(1 + count). Node features are the
types' GloVe vectors (``knowledge/word_vectors.py``).
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass

import numpy as np
import torch

from maniskill_tidy.houses.schema import House
from maniskill_tidy.knowledge import ROOM_TYPES, load_catalog
from maniskill_tidy.knowledge.word_vectors import load_word_vectors


@dataclass
class KnowledgeGraph:
    nodes: tuple[str, ...]  # the catalog's categories, then the room types
    edge_index: torch.Tensor  # (2, E), both directions
    edge_weight: torch.Tensor  # (E,)
    features: torch.Tensor  # (nodes, word dim)

    def node(self, name: str) -> int:
        return self.nodes.index(name)


def count_placements(houses: list[House]) -> Counter:
    """(type a, type b) -> how often a rests on / stands in b over ``houses``."""
    counts: Counter = Counter()
    for house in houses:
        rooms = {r.id: r.type for r in house.rooms}
        furniture = house.furniture_by_id()
        for f in house.furniture:
            counts[(f.type, rooms[f.room])] += 1
            for s in f.surfaces:
                if s.receptacle_type != f.type:
                    counts[(s.receptacle_type, rooms[f.room])] += 1
        for o in house.objects:
            counts[(o.type, rooms[o.room])] += 1
            if o.receptacle in furniture and o.surface:
                rtype = furniture[o.receptacle].surface(o.surface).receptacle_type
                counts[(o.type, rtype)] += 1
    return counts


def build_graph(houses: list[House]) -> KnowledgeGraph:
    nodes = tuple(load_catalog().categories) + ROOM_TYPES
    index = {n: i for i, n in enumerate(nodes)}
    src, dst, weight = [], [], []
    for (a, b), n in sorted(count_placements(houses).items()):
        if a in index and b in index and a != b:
            w = math.log1p(n)
            src += [index[a], index[b]]
            dst += [index[b], index[a]]
            weight += [w, w]
    vectors = load_word_vectors()
    features = np.stack([vectors[n] for n in nodes])
    return KnowledgeGraph(
        nodes,
        torch.tensor([src, dst], dtype=torch.long),
        torch.tensor(weight, dtype=torch.float32),
        torch.from_numpy(features),
    )
