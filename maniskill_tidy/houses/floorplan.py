"""Room plans: which rooms a house has, where they lie, its walls and the doors between rooms.

Rooms are rectangles that tile a rectangular footprint (a squarified split on a 0.5 m grid,
as ProcTHOR's floor plans are on a grid too). Doors follow a random spanning tree of the
room-adjacency graph (plus an occasional extra door), so every room is reachable; bathrooms
prefer to hang off living rooms and bedrooms rather than kitchens.
"""

from __future__ import annotations

import math

import networkx as nx
import numpy as np

from maniskill_tidy.houses.schema import Door, Room, Wall

SNAP = 0.5  # room corners lie on this grid
MIN_SIDE = 2.5  # no room narrower than this
DOOR_WIDTH = 1.0
AREA = {  # square metres, uniform ranges
    "Kitchen": (9.0, 18.0),
    "LivingRoom": (14.0, 28.0),
    "Bedroom": (9.0, 18.0),
    "Bathroom": (6.0, 9.0),
}
# ProcTHOR-style room specs with sampling weights (1 to 8 rooms).
ROOM_SPECS: list[tuple[tuple[str, ...], float]] = [
    (("Kitchen",), 0.4),
    (("LivingRoom",), 0.4),
    (("Bedroom",), 0.4),
    (("Kitchen", "LivingRoom"), 1.0),
    (("Bedroom", "Bathroom"), 0.8),
    (("Kitchen", "LivingRoom", "Bathroom"), 1.0),
    (("LivingRoom", "Bedroom", "Bathroom"), 1.0),
    (("Kitchen", "LivingRoom", "Bedroom", "Bathroom"), 2.0),
    (("Kitchen", "LivingRoom", "Bedroom", "Bedroom", "Bathroom"), 1.5),
    (("Kitchen", "LivingRoom", "Bedroom", "Bedroom", "Bathroom", "Bathroom"), 1.0),
    (("Kitchen", "LivingRoom", "Bedroom", "Bedroom", "Bedroom", "Bathroom", "Bathroom"), 0.5),
    (
        (
            "Kitchen",
            "LivingRoom",
            "LivingRoom",
            "Bedroom",
            "Bedroom",
            "Bedroom",
            "Bathroom",
            "Bathroom",
        ),
        0.3,
    ),
]
FLOORS = {"Kitchen": "tile", "LivingRoom": "wood", "Bedroom": "carpet", "Bathroom": "marble"}
WALLS = ("plaster", "paint_cream", "paint_blue", "paint_green", "brick")
EDGE_COST = {
    frozenset(("Bathroom", "Kitchen")): 3.0,
    frozenset(("Bathroom",)): 4.0,
    frozenset(("Bedroom", "Kitchen")): 2.0,
    frozenset(("Bedroom",)): 1.5,
}


class LayoutError(RuntimeError):
    """This draw of sizes cannot be split into rooms of at least MIN_SIDE; draw again."""


def sample_room_spec(rng: np.random.Generator) -> list[str]:
    weights = np.array([w for _, w in ROOM_SPECS])
    spec = ROOM_SPECS[int(rng.choice(len(ROOM_SPECS), p=weights / weights.sum()))][0]
    return list(spec)


def _snap(v: float) -> float:
    return round(v / SNAP) * SNAP


def _split(rect, rooms, rng) -> list[tuple[tuple[float, float, float, float], int]]:
    """Split ``rect`` among ``rooms`` [(index, area)] proportionally to area, recursively."""
    x0, y0, x1, y1 = rect
    if len(rooms) == 1:
        if min(x1 - x0, y1 - y0) < MIN_SIDE - 1e-9:
            raise LayoutError("room too narrow")
        return [(rect, rooms[0][0])]
    total = sum(a for _, a in rooms)
    cuts = sorted(range(1, len(rooms)), key=lambda k: abs(sum(a for _, a in rooms[:k]) - total / 2))
    horizontal = (x1 - x0) >= (y1 - y0)
    for k in cuts:
        frac = sum(a for _, a in rooms[:k]) / total
        if horizontal:
            cut = _snap(x0 + frac * (x1 - x0))
            parts = ((x0, y0, cut, y1), (cut, y0, x1, y1))
        else:
            cut = _snap(y0 + frac * (y1 - y0))
            parts = ((x0, y0, x1, cut), (x0, cut, x1, y1))
        try:
            return _split(parts[0], rooms[:k], rng) + _split(parts[1], rooms[k:], rng)
        except LayoutError:
            continue
    raise LayoutError("no split keeps every room wide enough")


def layout_rooms(spec: list[str], rng: np.random.Generator) -> list[Room]:
    """Rectangular rooms of the given types tiling a footprint with its corner at (0, 0)."""
    for _ in range(50):
        areas = [float(rng.uniform(*AREA[t])) for t in spec]
        order = list(rng.permutation(len(spec)))
        total = sum(areas)
        aspect = float(rng.uniform(1.0, 1.6))
        w = max(_snap(math.sqrt(total * aspect)), MIN_SIDE)
        h = max(_snap(total / w), MIN_SIDE)
        try:
            cells = _split((0.0, 0.0, w, h), [(i, areas[i]) for i in order], rng)
        except LayoutError:
            continue
        wall_material = str(rng.choice(WALLS))
        rooms: list[Room] = [None] * len(spec)  # type: ignore[list-item]
        for (x0, y0, x1, y1), i in cells:
            rooms[i] = Room(
                id=f"room_{i}",
                type=spec[i],
                polygon=[[x0, y0], [x1, y0], [x1, y1], [x0, y1]],
                floor_material=FLOORS[spec[i]],
                wall_material=wall_material,
            )
        return rooms
    raise LayoutError(f"could not lay out rooms {spec}")


def _edges(room: Room) -> list[tuple[str, float, float, float]]:
    """Room edges as (axis, fixed coordinate, lo, hi): axis 'x' means the edge runs along x."""
    x0, y0, x1, y1 = room.bounds()
    return [("x", y0, x0, x1), ("x", y1, x0, x1), ("y", x0, y0, y1), ("y", x1, y0, y1)]


def _segment(axis: str, fixed: float, lo: float, hi: float) -> tuple[list[float], list[float]]:
    if axis == "x":
        return [lo, fixed], [hi, fixed]
    return [fixed, lo], [fixed, hi]


def build_walls(rooms: list[Room]) -> list[Wall]:
    """Interior walls (shared by two rooms, once) and exterior walls (the rest of each edge)."""
    walls: list[Wall] = []
    for a, ra in enumerate(rooms):
        for axis, fixed, lo, hi in _edges(ra):
            covered: list[tuple[float, float]] = []
            for b, rb in enumerate(rooms):
                if a == b:
                    continue
                for axis2, fixed2, lo2, hi2 in _edges(rb):
                    if axis2 != axis or abs(fixed2 - fixed) > 1e-6:
                        continue
                    s, e = max(lo, lo2), min(hi, hi2)
                    if e - s > 1e-6:
                        covered.append((s, e))
                        if a < b:
                            start, end = _segment(axis, fixed, s, e)
                            walls.append(
                                Wall(
                                    f"wall_{len(walls)}",
                                    start,
                                    end,
                                    [ra.id, rb.id],
                                    material=ra.wall_material,
                                )
                            )
            cursor = lo
            for s, e in sorted(covered) + [(hi, hi)]:
                if s - cursor > 1e-6:
                    start, end = _segment(axis, fixed, cursor, s)
                    walls.append(
                        Wall(f"wall_{len(walls)}", start, end, [ra.id], material=ra.wall_material)
                    )
                cursor = max(cursor, e)
    return walls


def place_doors(rooms: list[Room], walls: list[Wall], rng: np.random.Generator) -> list[Door]:
    """Doors on interior walls along a spanning tree of room adjacency, plus a few extras."""
    types = {r.id: r.type for r in rooms}
    graph = nx.Graph()
    graph.add_nodes_from(types)
    for w in walls:
        length = math.dist(w.start, w.end)
        if len(w.rooms) == 2 and length >= DOOR_WIDTH + 0.5:
            a, b = w.rooms
            pair = frozenset((types[a], types[b]))
            cost = EDGE_COST.get(pair, 1.0) + float(rng.uniform(0, 1))
            cost += 2.0 if "Bathroom" in pair else 0.0  # bathrooms are leaves, not hallways
            if not graph.has_edge(a, b) or graph[a][b]["weight"] > cost:
                graph.add_edge(a, b, weight=cost, wall=w.id)
    if not nx.is_connected(graph):
        raise LayoutError("rooms do not all touch along a wall long enough for a door")
    tree = nx.minimum_spanning_tree(graph)
    chosen = sorted(tree.edges(data=True), key=lambda e: e[2]["wall"])
    extras = [
        e
        for e in sorted(graph.edges(data=True), key=lambda e: e[2]["wall"])
        if not tree.has_edge(e[0], e[1]) and "Bathroom" not in (types[e[0]], types[e[1]])
    ]
    chosen += [e for e in extras if rng.uniform() < 0.25]
    by_id = {w.id: w for w in walls}
    doors = []
    for a, b, data in chosen:
        w = by_id[data["wall"]]
        length = math.dist(w.start, w.end)
        # Door edges on the 0.25 m grid so that whole navigation cells pass through.
        slots = int(round((length - DOOR_WIDTH - 0.5) / 0.25))
        offset = 0.25 + DOOR_WIDTH / 2 + 0.25 * int(rng.integers(0, slots + 1))
        t = offset / length
        center = [
            w.start[0] + t * (w.end[0] - w.start[0]),
            w.start[1] + t * (w.end[1] - w.start[1]),
        ]
        doors.append(Door(f"door_{len(doors)}", w.id, sorted([a, b]), center, width=DOOR_WIDTH))
    return doors
