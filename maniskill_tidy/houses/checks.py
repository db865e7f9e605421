"""A house's own soundness: its grid matches its geometry, every room connects, nothing
overlaps, every surface and object is within reach, and every object starts reasonable by D.

``validate`` runs these for each house of a dataset; ``houses/repair.py`` runs them after
repairing an imported house.
"""

from __future__ import annotations

import itertools

from maniskill_tidy.houses.furnish import overlaps
from maniskill_tidy.houses.navgrid import (
    blocks_navigation,
    components,
    compute_free,
    grid_array,
    main_component,
    reach_cells,
)
from maniskill_tidy.houses.objects import stacked_footprints, surface_slots
from maniskill_tidy.houses.schema import House
from maniskill_tidy.knowledge import load_placement

TOL = 1e-3


def slot_of(house: House, receptacle: str, surface: str | None):
    for slot in surface_slots(house):
        if slot.furniture.id == receptacle and slot.surface.name == surface:
            return slot
    return None


def check_house(house: House) -> list[str]:
    problems = []
    where = house.id
    frame, free = compute_free(house)
    if house.navgrid is None:
        problems.append(f"{where}: no navigation grid")
    else:
        stored = grid_array(house.navgrid)
        if stored.shape != free.shape:
            problems.append(
                f"{where}: navigation grid shape {stored.shape}, geometry implies {free.shape}"
            )
        elif (stored != free).any():
            problems.append(
                f"{where}: navigation grid differs from the geometry at "
                f"{int((stored != free).sum())} cells"
            )
    _, n = components(free)
    if n != 1:
        problems.append(f"{where}: free cells form {n} separate areas; every room must connect")
    walkable = main_component(free)
    floor_pieces = [f for f in house.furniture if blocks_navigation(f)]
    for a, b in itertools.combinations(floor_pieces, 2):
        if overlaps(a.footprint(), b.footprint(), -TOL):
            problems.append(f"{where}: furniture {a.id} and {b.id} overlap")
    knowledge = load_placement()
    rooms = {r.id: r.type for r in house.rooms}
    for slot in surface_slots(house):
        if not reach_cells(frame, walkable, slot.bounds).any():
            problems.append(
                f"{where}: {slot.furniture.id}/{slot.surface.name} is out of reach "
                f"of every free cell"
            )
    by_surface: dict[tuple, list] = {}
    stacked = stacked_footprints(house)
    for o in house.objects:
        slot = slot_of(house, o.receptacle, o.surface)
        if slot is None:
            problems.append(f"{where}: object {o.id} rests on unknown {o.receptacle}/{o.surface}")
            continue
        if not knowledge.D(o.type, slot.surface.receptacle_type, rooms[o.room]):
            problems.append(
                f"{where}: object {o.id} starts unreasonable: "
                f"{slot.surface.receptacle_type} in {rooms[o.room]}"
            )
        fp = o.footprint()
        b = slot.bounds
        if fp[0] < b[0] - TOL or fp[1] < b[1] - TOL or fp[2] > b[2] + TOL or fp[3] > b[3] + TOL:
            problems.append(f"{where}: object {o.id} sticks out of {o.receptacle}/{o.surface}")
        for other in by_surface.get((o.receptacle, o.surface), []):
            if overlaps(fp, other.footprint(), -TOL):
                problems.append(f"{where}: objects {o.id} and {other.id} interpenetrate")
        if o.surface == "top" and any(
            overlaps(fp, piece, -TOL) for piece in stacked.get(o.receptacle, [])
        ):
            problems.append(f"{where}: object {o.id} is inside a piece standing on {o.receptacle}")
        by_surface.setdefault((o.receptacle, o.surface), []).append(o)
        if not reach_cells(frame, walkable, fp).any():
            problems.append(f"{where}: object {o.id} is out of reach")
    return problems
