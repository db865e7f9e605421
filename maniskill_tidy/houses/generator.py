"""Seeded procedural multi-room houses, in the spirit of ProcTHOR.

``generate_house(seed, index)`` depends only on its arguments: house ``index`` of dataset
``seed`` is the same whatever else is generated, in whatever order or process.
"""

from __future__ import annotations

from dataclasses import asdict

import numpy as np

from maniskill_tidy.houses.floorplan import (
    LayoutError,
    build_walls,
    layout_rooms,
    place_doors,
    sample_room_spec,
)
from maniskill_tidy.houses.furnish import RoomFurnisher
from maniskill_tidy.houses.navgrid import GridFrame, components, compute_free, structural_free
from maniskill_tidy.houses.objects import MIN_OBJECTS, ObjectPlacer
from maniskill_tidy.houses.schema import House, Light


class GenerationError(RuntimeError):
    pass


def house_rng(seed: int, index: int, stream: int = 0) -> np.random.Generator:
    """Independent stream per (dataset seed, house index, purpose)."""
    return np.random.default_rng(np.random.SeedSequence([seed, index, stream]))


def room_lights(house: House) -> list[Light]:
    """Ceiling lights: one per room, two along the long side of rooms over 20 m^2."""
    lights = []
    height = min((w.height for w in house.walls), default=2.5) - 0.1
    for room in house.rooms:
        x0, y0, x1, y1 = room.bounds()
        n = 2 if room.area() > 20 else 1
        long_x = (x1 - x0) >= (y1 - y0)
        for k in range(n):
            t = (k + 1) / (n + 1)
            x = x0 + t * (x1 - x0) if long_x else (x0 + x1) / 2
            y = (y0 + y1) / 2 if long_x else y0 + t * (y1 - y0)
            lights.append(
                Light(
                    f"light_{len(lights)}",
                    room.id,
                    [x, y, height],
                    intensity=round(min(1.0, room.area() / (10.0 * n)), 3),
                )
            )
    return lights


def generate_house(
    seed: int, index: int = 0, spec: list[str] | None = None, max_attempts: int = 20
) -> House:
    """House ``index`` of the dataset with seed ``seed`` (room types from ``spec`` if given)."""
    rng = house_rng(seed, index)
    room_spec = list(spec) if spec else sample_room_spec(rng)
    last_error = "no attempt"
    for _ in range(max_attempts):
        try:
            rooms = layout_rooms(room_spec, rng)
            walls = build_walls(rooms)
            doors = place_doors(rooms, walls, rng)
        except LayoutError as e:
            last_error = str(e)
            continue
        house = House(
            id=f"house_{index:05d}",
            seed=seed,
            source="procedural",
            rooms=rooms,
            walls=walls,
            doors=doors,
            lights=[],
            furniture=[],
            objects=[],
            room_spec=room_spec,
        )
        frame = GridFrame.around(rooms)
        free = structural_free(house, frame)
        wall_axis = {w.id: "x" if abs(w.start[1] - w.end[1]) < 1e-9 else "y" for w in walls}
        furnisher = RoomFurnisher(
            frame, free, rooms, doors, {d.id: wall_axis[d.wall] for d in doors}, rng
        )
        for room in rooms:
            room_walls = {w.id for w in walls if room.id in w.rooms}
            furnisher.furnish(room, room_walls)
        # Compute the grid from the geometry as it will be saved (rounded), so that a reader
        # recomputing it from the file gets exactly the stored grid.
        house = House.from_dict(
            {**house.to_dict(), "furniture": [asdict(f) for f in furnisher.placed]}
        )
        frame, free = compute_free(house)
        if components(free)[1] != 1:
            last_error = "rounding disconnected the free cells"
            continue
        placer = ObjectPlacer(house, frame, free, rng)
        placer.populate()
        if len(house.objects) < MIN_OBJECTS:
            last_error = f"only {len(house.objects)} objects fit"
            continue
        house.lights = room_lights(house)
        house.navgrid = frame.to_navgrid(free)
        return house
    raise GenerationError(f"house {index} (seed {seed}, rooms {room_spec}): {last_error}")
