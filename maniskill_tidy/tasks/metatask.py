"""Tidy-up meta-tasks: misplace k objects of a tidy house, as in the paper's Section 4.

Each misplaced object goes to an unreasonable place (D false) by one of three moves:
- ``same_room_receptacle``: another receptacle in the room it was in;
- ``other_room_receptacle``: a receptacle in another room;
- ``floor``: dropped on the floor of its room.
A meta-task is *Single* when every misplaced object stays in its original room and *Cross*
when at least one changes room (the paper's definition). Which kind a meta-task is meant to be
is decided first, per dataset shard (:func:`single_schedule`), so that a split has the paper's mix:
``SINGLE_FRACTION`` of the tasks are Single (565 of the 1000 test episodes in the paper);
a Cross task moves its first object to another room, a Single task moves none there. A house
with one room, or a Cross task whose objects fit nowhere in another room, gives Single tasks.
The goal is checkable from the spec alone: each misplaced object lists its original location
and every surface of this house where it would be reasonable (the original one included, so a
goal always exists).

Misplaced objects only go where a robot can find and take them (:func:`findable`): on surfaces
at most ``MAX_MISPLACED_HEIGHT`` above the floor (no robot camera is higher than 1.0 m, and a flat
object on a higher shelf shows no pixels to any of them), not into drawers (they stack, so an
open drawer hides the one below) or open-top bins (their walls hide the bottom), and with the
object's centre within PickUp's reach of a free cell.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field, replace

import numpy as np

from maniskill_tidy.houses.generator import house_rng
from maniskill_tidy.houses.navgrid import GridFrame, compute_free, frame_of, grid_array
from maniskill_tidy.houses.objects import ObjectPlacer, fits
from maniskill_tidy.houses.schema import House
from maniskill_tidy.knowledge import FLOOR, load_placement
from maniskill_tidy.tasks.starts import sample_starts
from maniskill_tidy.tasks.teams import SETTINGS

META_TASKS_PER_HOUSE = 10
STARTS_PER_TASK = 5
MOVES = ("same_room_receptacle", "other_room_receptacle", "floor")
MAX_MISPLACED_HEIGHT = 1.0  # metres: the manipulator's camera height
PICK_REACH = 1.45  # metres: PickUp's 1.5 m reach from the robot's centre, with a margin
MOVE_P = (0.4, 0.35, 0.25)
SINGLE_FRACTION = 0.565  # the paper's test split: 565 Single and 435 Cross episodes of 1000
SCHEDULE_STREAM = 100  # house_rng stream that orders a house's Single and Cross tasks


@dataclass
class Location:
    receptacle: str  # furniture id or "Floor"
    surface: str | None
    room: str
    position: list[float]
    yaw: float


@dataclass
class Misplacement:
    object: str
    type: str
    original: Location
    misplaced: Location
    how: str
    reasonable: list[list[str]]  # [[furniture id, surface name], ...] where D is true here


@dataclass
class MetaTask:
    id: str
    house_id: str
    index: int
    k: int
    kind: str  # "Single" or "Cross"
    misplaced: list[Misplacement]
    starts: dict[str, list[list[dict]]] = field(default_factory=dict)  # setting -> 5 configs

    def to_dict(self) -> dict:
        from maniskill_tidy.houses.schema import _rounded

        return _rounded(self)

    @classmethod
    def from_dict(cls, d: dict) -> MetaTask:
        d = dict(d)
        d["misplaced"] = [
            Misplacement(
                **{
                    **m,
                    "original": Location(**m["original"]),
                    "misplaced": Location(**m["misplaced"]),
                }
            )
            for m in d["misplaced"]
        ]
        return cls(**d)


def label(misplaced: list[Misplacement]) -> str:
    return "Cross" if any(m.original.room != m.misplaced.room for m in misplaced) else "Single"


def reasonable_surfaces(house: House, object_type: str, size: list[float]) -> list[list[str]]:
    knowledge = load_placement()
    rooms = {r.id: r.type for r in house.rooms}
    out = []
    for f in house.furniture:
        for s in f.surfaces:
            if knowledge.D(object_type, s.receptacle_type, rooms[f.room]):
                slot_ok = s.clearance is None or size[2] <= s.clearance
                if slot_ok:
                    out.append([f.id, s.name])
    return out


def findable(furniture, surface, from_floor: bool = False) -> bool:
    """Whether an object misplaced on ``surface`` can be seen by some robot (see the top).

    ``from_floor``: measure the height from the floor. Generator version 3 measures it from the
    piece's own base, so the inside of a microwave standing on a counter counts as 0.05 m high;
    ProcTHOR datasets (a safe on a dresser, its inside at 1.03 m) measure from the floor."""
    height = surface.center[2] + (furniture.position[2] if from_floor else 0.0)
    if height > MAX_MISPLACED_HEIGHT:
        return False
    if not surface.inside:
        return True
    if surface.link == "body":
        return bool(furniture.joints)  # behind a door that the env opens; an open-top bin hides
    joint = next(j for j in furniture.joints if j.name == surface.link)
    return joint.type != "prismatic"


def _try_move(
    placer: ObjectPlacer,
    house: House,
    obj,
    how: str,
    rng,
    free_xy: np.ndarray,
    from_floor: bool = False,
) -> Location | None:
    knowledge = load_placement()
    rooms = {r.id: r.type for r in house.rooms}
    if how == "floor":
        spot = placer.floor_spot(obj.room, obj.size, ignore=obj.id)
        if spot is None:
            return None
        return Location(FLOOR, None, obj.room, spot[0], spot[1])
    same = how == "same_room_receptacle"
    slots = [
        s
        for s in placer.slots
        if (s.furniture.room == obj.room) == same
        and not (s.furniture.id == obj.receptacle and s.surface.name == obj.surface)
        and not knowledge.D(obj.type, s.surface.receptacle_type, rooms[s.furniture.room])
        and fits(s, obj.size)
        and findable(s.furniture, s.surface, from_floor)
    ]
    for i in rng.permutation(len(slots))[:8]:
        slot = slots[int(i)]
        spot = placer.spot_on(slot, obj.size, ignore=obj.id)
        if spot is not None and _within_reach(spot[0], free_xy):
            return Location(slot.furniture.id, slot.surface.name, slot.furniture.room, *spot)
    return None


def _within_reach(position: list[float], free_xy: np.ndarray) -> bool:
    return bool(np.min(np.hypot(*(free_xy - np.asarray(position[:2])).T)) <= PICK_REACH)


def single_schedule(
    houses: list[House], indices: list[int], seed: int, fraction: float = SINGLE_FRACTION
) -> dict[int, set[int]]:
    """Which meta-tasks of a batch of houses (a dataset shard) are meant to be Single.

    The batch gets ``round(fraction * tasks)`` Single tasks. One-room houses can only have
    Single tasks; the rest are spread over the multi-room houses as evenly as counts allow
    (``floor((j + 1) r) - floor(j r)`` for the j-th of them), and within a house a seeded
    permutation picks which tasks. So a split has the fraction to within a task or two
    whatever share of its houses has one room, and the batch alone decides it."""
    if not 0.0 <= fraction <= 1.0:
        raise ValueError(f"the Single fraction must lie in [0, 1], got {fraction}")
    n = META_TASKS_PER_HOUSE
    multi = [i for h, i in zip(houses, indices, strict=True) if len(h.rooms) > 1]
    total = int(round(fraction * n * len(houses)))
    rate = min(max(total - n * (len(houses) - len(multi)), 0) / max(len(multi), 1), n)
    out = {}
    for h, i in zip(houses, indices, strict=True):
        if len(h.rooms) == 1:
            out[i] = set(range(n))
            continue
        j = multi.index(i)
        count = int(np.floor((j + 1) * rate + 1e-9)) - int(np.floor(j * rate + 1e-9))
        order = house_rng(seed, i, stream=SCHEDULE_STREAM).permutation(n)
        out[i] = {int(t) for t in order[:count]}
    return out


def generate_meta_task(
    house: House,
    seed: int,
    house_index: int,
    task_index: int,
    single: bool = False,
    from_floor: bool = False,
) -> MetaTask:
    """Meta-task ``task_index`` of a house, meant to be Single or Cross (``single``); its
    randomness depends only on the arguments. ``from_floor``: see :func:`findable`."""
    rng = house_rng(seed, house_index, stream=1 + task_index)
    # Only objects move: copy them and share the rest (a deep copy of the house per task
    # took as long as generating the house).
    work = replace(house, objects=[replace(o) for o in house.objects])
    frame, free = house_grid(work)
    placer = ObjectPlacer(work, frame, free, rng)
    free_xy = np.stack([frame.X[free], frame.Y[free]], axis=1)
    k = int(rng.integers(1, 6))
    cross_wanted = not single and len(house.rooms) > 1
    candidates = [o for o in work.objects]
    order = rng.permutation(len(candidates))
    moved: list[Misplacement] = []
    for i in order:
        if len(moved) == k:
            break
        obj = candidates[int(i)]
        crossed = any(m.how == "other_room_receptacle" for m in moved)
        if cross_wanted and not crossed:
            moves = ["other_room_receptacle"]  # a Cross task's first object changes room
        else:
            allowed = [m for m in MOVES if cross_wanted or m != "other_room_receptacle"]
            p = np.array([MOVE_P[MOVES.index(m)] for m in allowed])
            first = allowed[int(rng.choice(len(allowed), p=p / p.sum()))]
            moves = [first] + [m for m in allowed if m != first]
        for how in moves:
            target = _try_move(placer, work, obj, how, rng, free_xy, from_floor)
            if target is None:
                continue
            original = Location(obj.receptacle, obj.surface, obj.room, list(obj.position), obj.yaw)
            obj.receptacle, obj.surface, obj.room = target.receptacle, target.surface, target.room
            obj.position, obj.yaw = list(target.position), target.yaw
            moved.append(
                Misplacement(
                    obj.id,
                    obj.type,
                    original,
                    target,
                    how,
                    reasonable_surfaces(house, obj.type, obj.size),
                )
            )
            break
    task = MetaTask(
        id=f"{house.id}/task_{task_index}",
        house_id=house.id,
        index=task_index,
        k=len(moved),
        kind=label(moved),
        misplaced=moved,
    )
    walkable = placer.walkable
    for name, team in SETTINGS.items():
        task.starts[name] = [
            sample_starts(frame, walkable, len(team), rng) for _ in range(STARTS_PER_TASK)
        ]
    return task


def house_grid(house: House) -> tuple[GridFrame, np.ndarray]:
    """The house's stored navigation grid, or a freshly computed one."""
    if house.navgrid is not None:
        return frame_of(house.navgrid), grid_array(house.navgrid)
    return compute_free(house)


def generate_meta_tasks(
    house: House,
    seed: int,
    house_index: int,
    single: set[int] | None = None,
    from_floor: bool = False,
) -> list[MetaTask]:
    """A house's meta-tasks; ``single``: which are meant to be Single (default: the share of
    ``single_schedule`` for this house alone)."""
    if single is None:
        single = single_schedule([house], [house_index], seed)[house_index]
    return [
        generate_meta_task(house, seed, house_index, t, t in single, from_floor)
        for t in range(META_TASKS_PER_HOUSE)
    ]


def apply_task(house: House, task: MetaTask) -> House:
    """The house as the agents find it: misplaced objects moved to their task locations."""
    messy = copy.deepcopy(house)
    by_id = messy.object_by_id()
    for m in task.misplaced:
        o = by_id[m.object]
        loc = m.misplaced
        o.receptacle, o.surface, o.room = loc.receptacle, loc.surface, loc.room
        o.position, o.yaw = list(loc.position), loc.yaw
    return messy
