"""Make an imported house sound, or say why it cannot be: the same checks `validate` applies.

ProcTHOR places things its own way: chairs tucked under tables (furniture footprints overlap),
objects straddling the edge of a counter, floating a few centimetres above it or on the floor,
objects where our placement knowledge D says they do not belong. The benchmark needs every
object resting on a surface where D is true and within reach, furniture that does not overlap,
and one connected walkable floor. :func:`make_sound` applies these rules in order:

1. furniture turns to the nearest quarter turn, and stacked furniture stands on its parent's top;
2. of two floor pieces that overlap, the smaller is dropped (with what stands on it);
3. while the walkable floor is split, the floor piece whose removal joins most of it is dropped;
4. a piece with a surface no free cell can reach, or whose middle is out of PickUp's reach, is
   dropped;
5. each object keeps its place, slid onto the surface if it sticks out and set down on it, when
   D holds there, it fits and touches no other object; otherwise it moves to a free spot on a
   surface where D holds (its own piece of furniture first, then its room, then the house);
   otherwise it is dropped.

What cannot be repaired rejects the house with one line naming what is wrong
(:class:`HouseRejected`). Relocations draw from ``rng``, so a seed gives the same house.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field, replace

import numpy as np

from maniskill_tidy.houses.furnish import overlaps
from maniskill_tidy.houses.navgrid import (
    ARM_REACH,
    blocks_navigation,
    components,
    compute_free,
    main_component,
    reach_cells,
)
from maniskill_tidy.houses.objects import (
    ObjectPlacer,
    SurfaceSlot,
    fits,
    is_hanging,
    surface_slots,
)
from maniskill_tidy.houses.schema import Furniture, House, PlacedObject
from maniskill_tidy.knowledge import load_placement

MIN_OBJECTS = 5  # a meta-task misplaces up to 5 objects
TOL = 1e-3  # the tolerance `validate` allows
MAX_DROPS_FOR_CONNECTION = 3
VIEW_REACH = ARM_REACH - 0.05  # a surface's middle must have a viewpoint (policies.viewpoints)


class HouseRejected(ValueError):
    """A house that no repair rule makes sound; the message says what is wrong."""


@dataclass
class RepairLog:
    """What :func:`make_sound` changed, for the dataset manifest."""

    furniture_dropped: list[str] = field(default_factory=list)
    objects_moved: list[str] = field(default_factory=list)
    objects_relocated: list[str] = field(default_factory=list)
    objects_dropped: list[str] = field(default_factory=list)

    def counts(self) -> dict[str, int]:
        return {k: len(v) for k, v in vars(self).items()}


def _area(f: Furniture) -> float:
    return f.size[0] * f.size[1]


def _drop_furniture(house: House, ids: set[str], log: RepairLog) -> None:
    """Drop ``ids`` and every piece stacked on them (their objects are re-homed later)."""
    while True:
        more = {f.id for f in house.furniture if f.parent in ids} - ids
        if not more:
            break
        ids |= more
    log.furniture_dropped += [f.id for f in house.furniture if f.id in ids]
    house.furniture = [f for f in house.furniture if f.id not in ids]


def _square_up(house: House) -> None:
    """Turn furniture to the nearest quarter turn (an angled armchair's seat is not the
    axis-aligned rectangle that surface checks use) and stand stacked pieces on their parent."""
    by_id = house.furniture_by_id()
    for f in house.furniture:
        f.yaw = round(f.yaw / (math.pi / 2)) % 4 * (math.pi / 2)
        parent = by_id.get(f.parent) if f.parent else None
        tops = [s for s in parent.surfaces if s.name == "top"] if parent else []
        if tops:
            f.position[2] = parent.position[2] + tops[0].center[2]


def _drop_overlaps(house: House, log: RepairLog) -> None:
    while True:
        pieces = [f for f in house.furniture if blocks_navigation(f)]
        pair = next(
            (
                (a, b)
                for a, b in itertools.combinations(pieces, 2)
                if overlaps(a.footprint(), b.footprint(), -TOL)
            ),
            None,
        )
        if pair is None:
            return
        smaller = min(pair, key=lambda f: (_area(f), f.id))
        _drop_furniture(house, {smaller.id}, log)


def _connect(house: House, log: RepairLog) -> None:
    for _ in range(MAX_DROPS_FOR_CONNECTION):
        _, n = components(compute_free(house)[1])
        if n <= 1:
            return
        best, best_n = None, n
        for f in sorted((f for f in house.furniture if blocks_navigation(f)), key=_area):
            trial = replace(house, furniture=[g for g in house.furniture if g is not f])
            _, m = components(compute_free(trial)[1])
            if m < best_n:
                best, best_n = f, m
        if best is None:
            break
        _drop_furniture(house, {best.id}, log)
    _, n = components(compute_free(house)[1])
    if n != 1:
        raise HouseRejected(
            f"the free floor is split into {n} areas that dropping up to "
            f"{MAX_DROPS_FOR_CONNECTION} pieces of furniture does not join"
        )


def _drop_unreachable(house: House, log: RepairLog) -> None:
    """Drop pieces with a surface no free cell reaches, or whose middle no robot can reach:
    PickUp and PutDown aim at a point from a cell within their reach (a piece imported as one
    deep block, as L-shaped counters were before the importer split them, fails this)."""
    while True:
        frame, free = compute_free(house)
        walkable = main_component(free)
        out = {
            slot.furniture.id
            for slot in surface_slots(house)
            if not reach_cells(frame, walkable, slot.bounds).any()
            or not reach_cells(frame, walkable, _middle(slot), VIEW_REACH).any()
        }
        if not out:
            return
        _drop_furniture(house, out, log)


def _middle(slot: SurfaceSlot) -> tuple[float, float, float, float]:
    x, y = slot.center[:2]
    return x, y, x, y


def _set_down(o: PlacedObject, slot: SurfaceSlot) -> PlacedObject | None:
    """``o`` slid inside ``slot``'s bounds and resting on it, or None if it is too big."""
    x0, y0, x1, y1 = slot.bounds
    fx0, fy0, fx1, fy1 = o.footprint()
    hw, hd = (fx1 - fx0) / 2, (fy1 - fy0) / 2
    if 2 * hw > x1 - x0 + TOL or 2 * hd > y1 - y0 + TOL:
        return None
    x = min(max(o.position[0], x0 + hw), x1 - hw)
    y = min(max(o.position[1], y0 + hd), y1 - hd)
    z = slot.center[2] - o.size[2] if is_hanging(slot.surface) else slot.center[2]
    return replace(o, position=[x, y, z], room=slot.furniture.room)


def _rehome_objects(house: House, rng: np.random.Generator, log: RepairLog) -> None:
    knowledge = load_placement()
    frame, free = compute_free(house)
    originals, house.objects = house.objects, []
    placer = ObjectPlacer(house, frame, free, rng)
    slots = {(s.furniture.id, s.surface.name): s for s in placer.slots}

    def reasonable(o: PlacedObject, slot: SurfaceSlot) -> bool:
        return bool(knowledge.D(o.type, slot.surface.receptacle_type, slot.room_type))

    # Objects that can stay stay first, so that a relocated one never takes their place.
    homeless = []
    for o in originals:
        slot = slots.get((o.receptacle, o.surface))
        placed = _keep(o, slot, placer, frame) if slot and reasonable(o, slot) else None
        if placed is None:
            homeless.append(o)
            continue
        if math.dist(placed.position, o.position) > 0.01:
            log.objects_moved.append(o.id)
        house.objects.append(placed)
    for o in homeless:
        slot = slots.get((o.receptacle, o.surface))
        home = o.receptacle, (slot.furniture.room if slot else o.room)
        candidates = [s for s in placer.slots if reasonable(o, s) and fits(s, o.size)]
        candidates.sort(
            key=lambda s: (s.furniture.id != home[0], s.furniture.room != home[1])
        )  # stable: its own furniture, then its room, then the rest in house order
        for s in candidates:
            spot = placer.spot_on(s, o.size, ignore=o.id)
            if spot is not None:
                position, yaw = spot
                house.objects.append(
                    replace(
                        o,
                        receptacle=s.furniture.id,
                        surface=s.surface.name,
                        room=s.furniture.room,
                        position=position,
                        yaw=yaw,
                    )
                )
                log.objects_relocated.append(o.id)
                break
        else:
            log.objects_dropped.append(o.id)
    order = {o.id: i for i, o in enumerate(originals)}
    house.objects.sort(key=lambda o: order[o.id])


def _keep(o: PlacedObject, slot: SurfaceSlot, placer: ObjectPlacer, frame) -> PlacedObject | None:
    """``o`` set down where it is, if it fits there, touches no placed object and is in reach."""
    if not fits(slot, o.size):
        return None
    placed = _set_down(o, slot)
    if placed is None:
        return None
    fp = placed.footprint()
    if any(overlaps(fp, other, -TOL) for other in placer.obstacles(o.receptacle, o.surface)):
        return None
    return placed if reach_cells(frame, placer.walkable, fp).any() else None


def make_sound(house: House, rng: np.random.Generator) -> tuple[House, RepairLog]:
    """A repaired copy of ``house`` with its navigation grid, and what changed.

    Raises :class:`HouseRejected` when the floor cannot be joined or too few objects remain."""
    from maniskill_tidy.houses.checks import check_house

    log = RepairLog()
    house = House.from_dict(house.to_dict())  # a copy, at the precision it will be saved with
    house.navgrid = None
    _square_up(house)
    _drop_overlaps(house, log)
    _connect(house, log)
    _drop_unreachable(house, log)
    n_source = len(house.objects)
    _rehome_objects(house, rng, log)
    if len(house.objects) < MIN_OBJECTS:
        raise HouseRejected(
            f"too few objects: {len(house.objects)} of its {n_source} have a sound place where "
            f"D holds; a meta-task misplaces up to {MIN_OBJECTS}, so a house needs {MIN_OBJECTS}"
        )
    # The grid is computed from the house as it will be read back (rounded), as for
    # generated houses, so that `validate` recomputes exactly the stored grid.
    house = House.from_dict(house.to_dict())
    frame, free = compute_free(house)
    house.navgrid = frame.to_navgrid(free)
    problems = check_house(house)
    if problems:
        first = problems[0].split(": ", 1)[-1]
        more = f" (and {len(problems) - 1} more problems)" if len(problems) > 1 else ""
        raise HouseRejected(f"no repair rule fixes: {first}{more}")
    return house, log
