"""Import ProcTHOR house JSON (the ProcTHOR-10K format) into the project's house schema.

ProcTHOR is y-up and left-handed (Unity): a point (x, y, z) maps to our (x, z, y), and a
rotation of ``r`` degrees about Unity's y maps to a yaw of ``-r`` degrees about our z.
Asset sizes come from ProcTHOR's asset database (``knowledge/data/assets.json``); object
positions in ProcTHOR are bounding-box centres, ours are bottom centres. Children of a piece
of furniture that are pickupable become objects on its nearest surface; other children (a
television on a stand) become furniture standing on it.
"""

from __future__ import annotations

import gzip
import json
import math
import zlib
from collections.abc import Iterator
from pathlib import Path

from maniskill_tidy.houses.furniture import parts_for, top
from maniskill_tidy.houses.generator import room_lights
from maniskill_tidy.houses.navgrid import compute_free
from maniskill_tidy.houses.schema import Door, Furniture, House, PlacedObject, Room, Wall
from maniskill_tidy.knowledge import FLOOR, ROOM_TYPES, load_catalog
from maniskill_tidy.knowledge.catalog import load_assets


class ProcTHORImportError(ValueError):
    """A ProcTHOR house is malformed; the message names the house and the field."""


def _xz(p: dict, where: str) -> list[float]:
    try:
        return [float(p["x"]), float(p["z"])]
    except (KeyError, TypeError, ValueError):
        raise ProcTHORImportError(
            f"{where}: expected a point with numeric x and z, got {p!r}"
        ) from None


def _sid(s: str) -> str:
    return s.replace("|", "_")


def _need(d: dict, key: str, where: str):
    if not isinstance(d, dict) or key not in d:
        raise ProcTHORImportError(f"{where}: missing {key!r}")
    return d[key]


def _wall_key(wall_id: str) -> tuple[float, float, float, float] | None:
    parts = wall_id.split("|")
    try:
        return tuple(round(float(v), 2) for v in parts[-4:])  # type: ignore[return-value]
    except ValueError:
        return None


def import_house(d: dict, house_id: str) -> House:
    """Convert one ProcTHOR house dict; raises ProcTHORImportError naming what is wrong."""
    where = house_id
    rooms = []
    for i, r in enumerate(_need(d, "rooms", where)):
        rw = f"{where}: rooms[{i}]"
        poly = [_xz(p, f"{rw}.floorPolygon") for p in _need(r, "floorPolygon", rw)]
        if len(poly) < 3:
            raise ProcTHORImportError(f"{rw}: floorPolygon needs at least 3 points")
        area2 = sum(
            poly[k][0] * poly[k - 1][1] - poly[k - 1][0] * poly[k][1] for k in range(len(poly))
        )
        if area2 < 0:
            poly = poly[::-1]
        room_type = _need(r, "roomType", rw)
        if room_type not in ROOM_TYPES:
            raise ProcTHORImportError(f"{rw}: roomType {room_type!r} not in {ROOM_TYPES}")
        rooms.append(
            Room(
                id=_sid(_need(r, "id", rw)),
                type=room_type,
                polygon=poly,
                floor_material=str((r.get("floorMaterial") or {}).get("name", "wood")),
            )
        )
    room_ids = {r.id for r in rooms}

    walls: dict[tuple, Wall] = {}
    wall_alias: dict[str, str] = {}
    for i, w in enumerate(_need(d, "walls", where)):
        ww = f"{where}: walls[{i}]"
        wid = _need(w, "id", ww)
        key = _wall_key(wid)
        if key is None:
            raise ProcTHORImportError(f"{ww}: id {wid!r} does not end in x0|z0|x1|z1")
        pts = _need(w, "polygon", ww)
        height = max(float(p.get("y", 0)) for p in pts) if pts else 2.5
        canon = tuple(sorted([key[:2], key[2:]]))
        room = _sid(w.get("roomId", ""))
        if canon not in walls:
            walls[canon] = Wall(
                id=f"wall_{len(walls)}",
                start=list(key[:2]),
                end=list(key[2:]),
                rooms=[],
                height=round(height, 3),
                material=str((w.get("material") or {}).get("name", "plaster")),
            )
        if room in room_ids and room not in walls[canon].rooms:
            walls[canon].rooms.append(room)
        wall_alias[wid] = walls[canon].id
    wall_list = list(walls.values())
    by_id = {w.id: w for w in wall_list}

    doors = []
    for i, dd in enumerate(d.get("doors", [])):
        dw = f"{where}: doors[{i}]"
        wall = by_id.get(wall_alias.get(_need(dd, "wall0", dw), ""))
        if wall is None:
            raise ProcTHORImportError(f"{dw}: wall0 {dd['wall0']!r} is not among the walls")
        hole = _need(dd, "holePolygon", dw)
        if len(hole) < 2:
            raise ProcTHORImportError(f"{dw}: holePolygon needs two corners")
        key = _wall_key(dd["wall0"])
        start, end = list(key[:2]), list(key[2:])
        length = math.dist(start, end) or 1.0
        t = (float(hole[0]["x"]) + float(hole[1]["x"])) / 2 / length
        center = [start[0] + t * (end[0] - start[0]), start[1] + t * (end[1] - start[1])]
        door_rooms = sorted({_sid(dd.get("room0", "")), _sid(dd.get("room1", ""))} & room_ids)
        doors.append(
            Door(
                id=f"door_{i}",
                wall=wall.id,
                rooms=door_rooms,
                center=center,
                width=abs(float(hole[1]["x"]) - float(hole[0]["x"])),
                height=float(hole[1].get("y", 2.1)),
            )
        )

    house = House(
        id=house_id,
        seed=None,
        source="procthor",
        rooms=rooms,
        walls=wall_list,
        doors=doors,
        lights=[],
        furniture=[],
        objects=[],
        room_spec=[r.type for r in rooms],
    )
    for i, o in enumerate(d.get("objects", [])):
        _import_object(house, o, f"{where}: objects[{i}]", parent=None)
    house.lights = room_lights(house)
    frame, free = compute_free(house)
    house.navgrid = frame.to_navgrid(free)
    return house


def _room_of(house: House, x: float, y: float) -> str:
    return house.room_at(x, y) or house.rooms[0].id


def _import_object(house: House, o: dict, where: str, parent: Furniture | None) -> None:
    asset_id = _need(o, "assetId", where)
    asset = load_assets().get(asset_id)
    if asset is None:
        raise ProcTHORImportError(
            f"{where}: unknown assetId {asset_id!r} (not in ProcTHOR's asset database)"
        )
    type_name, w, dpt, h = asset
    pos = _need(o, "position", where)
    x, y = _xz(pos, f"{where}.position")
    z = float(pos.get("y", h / 2)) - h / 2
    yaw = -math.radians(float((o.get("rotation") or {}).get("y", 0.0)))
    room = _room_of(house, x, y)
    info = load_catalog().types.get(type_name)
    if info is not None and info.pickupable:
        receptacle, surface = FLOOR, None
        if parent is not None:
            receptacle = parent.id
            if parent.surfaces:
                surface = min(
                    parent.surfaces, key=lambda s: abs(parent.position[2] + s.center[2] - z)
                ).name
        house.objects.append(
            PlacedObject(
                id=_sid(_need(o, "id", where)),
                type=type_name,
                room=room,
                receptacle=receptacle,
                surface=surface,
                position=[x, y, max(z, 0.0)],
                yaw=yaw,
                size=[w, dpt, h],
            )
        )
        return
    size = [w, dpt, h]
    surfaces, joints = parts_for(type_name, size)
    if not surfaces and info is not None and info.receptacle:
        surfaces = [top(type_name, w, dpt, h)]
    f = Furniture(
        id=_sid(_need(o, "id", where)),
        type=type_name,
        room=room,
        position=[x, y, max(z, 0.0)],
        yaw=yaw,
        size=size,
        surfaces=surfaces,
        joints=joints,
        parent=parent.id if parent else None,
        asset=asset_id,
    )
    house.furniture.append(f)
    for j, child in enumerate(o.get("children") or []):
        _import_object(house, child, f"{where}.children[{j}]", parent=f)


def read_procthor_houses(path: Path) -> Iterator[House]:
    """Houses of a ProcTHOR ``.jsonl``/``.jsonl.gz`` file (one house per line), in order."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such ProcTHOR house file")
    opener = gzip.open if path.suffix == ".gz" else open
    try:
        with opener(path, "rt") as f:
            for n, line in enumerate(f):
                if not line.strip():
                    continue
                try:
                    d = json.loads(line)
                except json.JSONDecodeError as e:
                    raise ProcTHORImportError(
                        f"{path}: line {n + 1} is not valid JSON ({e}); is the file truncated?"
                    ) from None
                yield import_house(d, f"procthor_{n:05d}")
    except (EOFError, gzip.BadGzipFile, zlib.error) as e:
        raise ProcTHORImportError(
            f"{path}: the gzip stream is damaged or truncated ({e})"
        ) from None
