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

MAX_OUTSIDE = 1.0  # metres an object's centre may lie outside every room (wall-mounted items)


class ProcTHORImportError(ValueError):
    """A ProcTHOR house is malformed; the message names the house and the field."""


def _num(d: dict, key: str, where: str, default: float | None = None) -> float:
    """A numeric field; ``default`` when it is absent (never when it is null or not a number)."""
    if not isinstance(d, dict):
        raise ProcTHORImportError(f"{where}: expected an object, got {d!r}")
    if key not in d and default is not None:
        return default
    try:
        return float(d[key])
    except KeyError:
        raise ProcTHORImportError(f"{where}: missing {key!r}") from None
    except (TypeError, ValueError):
        raise ProcTHORImportError(f"{where}.{key}: expected a number, got {d[key]!r}") from None


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
    try:
        return _import_house(d, house_id)
    except ProcTHORImportError:
        raise
    except (KeyError, TypeError, IndexError, ValueError, AttributeError) as e:
        # A shape this importer does not check field by field: still name the house.
        raise ProcTHORImportError(
            f"{house_id}: malformed house ({type(e).__name__}: {e})"
        ) from None


def _list(d: dict, key: str, where: str, required: bool = True) -> list:
    value = _need(d, key, where) if required else (d.get(key) or [])
    if not isinstance(value, list):
        raise ProcTHORImportError(f"{where}: {key!r} must be a list, got {type(value).__name__}")
    return value


def _import_house(d: dict, house_id: str) -> House:
    """One ProcTHOR house dict as a House, every field checked with the path of what is wrong.

    Long on purpose: it reads ProcTHOR's schema field by field in the schema's order (rooms,
    doors, objects and their children), so that it reads beside the exporter."""
    where = house_id
    if not isinstance(d, dict):
        raise ProcTHORImportError(f"{where}: expected a house object, got {type(d).__name__}")
    if not _list(d, "rooms", where):
        raise ProcTHORImportError(f"{where}: rooms is empty; a house needs at least one room")
    rooms = []
    for i, r in enumerate(_list(d, "rooms", where)):
        rw = f"{where}: rooms[{i}]"
        poly = [_xz(p, f"{rw}.floorPolygon") for p in _list(r, "floorPolygon", rw)]
        if len(poly) < 3:
            raise ProcTHORImportError(f"{rw}: floorPolygon needs at least 3 points")
        signed2 = sum(  # twice the signed area: positive when counter-clockwise
            poly[k - 1][0] * poly[k][1] - poly[k][0] * poly[k - 1][1] for k in range(len(poly))
        )
        if signed2 < 0:
            poly = poly[::-1]  # the schema's rooms are counter-clockwise
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
    for i, w in enumerate(_list(d, "walls", where)):
        ww = f"{where}: walls[{i}]"
        wid = _need(w, "id", ww)
        key = _wall_key(wid)
        if key is None:
            raise ProcTHORImportError(f"{ww}: id {wid!r} does not end in x0|z0|x1|z1")
        pts = _list(w, "polygon", ww)
        height = max(_num(p, "y", f"{ww}.polygon", 0.0) for p in pts) if pts else 2.5
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
    for i, dd in enumerate(_list(d, "doors", where, required=False)):
        dw = f"{where}: doors[{i}]"
        wall = by_id.get(wall_alias.get(_need(dd, "wall0", dw), ""))
        if wall is None:
            raise ProcTHORImportError(f"{dw}: wall0 {dd['wall0']!r} is not among the walls")
        hole = _list(dd, "holePolygon", dw)
        if len(hole) < 2:
            raise ProcTHORImportError(f"{dw}: holePolygon needs two corners")
        x0, x1 = (_num(hole[k], "x", f"{dw}.holePolygon[{k}]") for k in (0, 1))
        key = _wall_key(dd["wall0"])
        start, end = list(key[:2]), list(key[2:])
        length = math.dist(start, end) or 1.0
        t = (x0 + x1) / 2 / length
        center = [start[0] + t * (end[0] - start[0]), start[1] + t * (end[1] - start[1])]
        door_rooms = sorted({_sid(dd.get("room0", "")), _sid(dd.get("room1", ""))} & room_ids)
        doors.append(
            Door(
                id=f"door_{i}",
                wall=wall.id,
                rooms=door_rooms,
                center=center,
                width=abs(x1 - x0),
                height=_num(hole[1], "y", f"{dw}.holePolygon[1]", 2.1),
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
    for i, o in enumerate(_list(d, "objects", where, required=False)):
        _import_object(house, o, f"{where}: objects[{i}]", parent=None)
    house.lights = room_lights(house)
    frame, free = compute_free(house)
    house.navgrid = frame.to_navgrid(free)
    return house


def _box_distance(bounds: tuple[float, float, float, float], x: float, y: float) -> float:
    """Metres from (x, y) to the box ``bounds`` (x0, y0, x1, y1); 0 inside it."""
    x0, y0, x1, y1 = bounds
    return math.hypot(max(x0 - x, 0, x - x1), max(y0 - y, 0, y - y1))


def _outside(house: House, x: float, y: float) -> float:
    """Metres from (x, y) to the nearest room's bounding box (0 inside one)."""
    return min(_box_distance(r.bounds(), x, y) for r in house.rooms)


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
    z = _num(pos, "y", f"{where}.position", h / 2) - h / 2
    rotation = o.get("rotation", {})
    if rotation is None:
        raise ProcTHORImportError(f"{where}.rotation: expected an object with y, got None")
    yaw = -math.radians(_num(rotation, "y", f"{where}.rotation", 0.0))
    if house.room_at(x, y) is None and _outside(house, x, y) > MAX_OUTSIDE:
        raise ProcTHORImportError(
            f"{where}.position: ({x:.2f}, {y:.2f}) lies {_outside(house, x, y):.1f} m outside "
            "every room"
        )
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
        _need(o, "id", where)
        same_type = sum(1 for q in house.objects if q.type == type_name)
        house.objects.append(
            PlacedObject(  # named as the generator names them: ProcTHOR's ids name a room
                id=f"{type_name}_{same_type}",
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
    if asset_id.startswith(("Countertop_L_", "Countertop_C_")):
        _import_shaped_counter(house, o, where, asset_id, (x, y, max(z, 0.0)), yaw, (w, dpt, h))
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
    for j, child in enumerate(_list(o, "children", where, required=False)):
        _import_object(house, child, f"{where}.children[{j}]", parent=f)


ARM = 0.61  # metres: the depth of a ProcTHOR counter (2 ft), L- and C-shaped ones included


def _edge_to_wall(house: House, a: tuple[float, float], b: tuple[float, float]) -> float:
    """Distance from the middle of segment ab to the nearest wall."""
    mx, my = (a[0] + b[0]) / 2, (a[1] + b[1]) / 2
    best = math.inf
    for wall in house.walls:
        (x0, y0), (x1, y1) = wall.start, wall.end
        dx, dy = x1 - x0, y1 - y0
        t = max(0.0, min(1.0, ((mx - x0) * dx + (my - y0) * dy) / max(dx * dx + dy * dy, 1e-12)))
        best = min(best, math.hypot(mx - x0 - t * dx, my - y0 - t * dy))
    return best


def _import_shaped_counter(house, o, where, asset_id, position, yaw, size) -> None:
    """An L- or C-shaped counter as two or three straight ones along the walls it stands
    against: as one box it was up to 3 m deep, with a top whose middle no robot reaches and
    a cabinet under floor a robot could have stood on. Which edges carry the arms is not in
    the asset's metadata; they are the ones nearest the walls."""
    w, d, h = size
    turn = round(yaw / (math.pi / 2)) % 4
    if turn % 2:
        w, d = d, w
    x0, y0, x1, y1 = (
        position[0] - w / 2,
        position[1] - d / 2,
        position[0] + w / 2,
        position[1] + d / 2,
    )
    # edge name -> (its segment, the yaw that makes a strip along it face the inside)
    edges = {
        "south": (((x0, y0), (x1, y0)), 0.0),
        "north": (((x0, y1), (x1, y1)), math.pi),
        "west": (((x0, y0), (x0, y1)), -math.pi / 2),
        "east": (((x1, y0), (x1, y1)), math.pi / 2),
    }
    near = {e: _edge_to_wall(house, *seg) for e, (seg, _) in edges.items()}
    if asset_id.startswith("Countertop_L_"):
        pairs = [(a, b) for a in ("south", "north") for b in ("west", "east")]
        chosen = list(min(pairs, key=lambda p: near[p[0]] + near[p[1]]))
    else:  # C: the three edges nearest the walls, the middle one of the U first
        away = max(near, key=near.get)
        opposite = {"south": "north", "north": "south", "west": "east", "east": "west"}
        chosen = [opposite[away]] + [e for e in edges if e not in (away, opposite[away])]
    back = chosen[0]
    strips = []
    for k, edge in enumerate(chosen):
        (a, b), strip_yaw = edges[edge]
        horizontal = edge in ("south", "north")
        lo, hi = (a[0], b[0]) if horizontal else (a[1], b[1])
        if k > 0:  # an arm starts where the back strip ends
            if back in ("south", "west"):
                lo += ARM
            else:
                hi -= ARM
        inward = ARM / 2 if edge in ("south", "west") else -ARM / 2
        if horizontal:
            centre = [(lo + hi) / 2, a[1] + inward]
        else:
            centre = [a[0] + inward, (lo + hi) / 2]
        strip_size = [hi - lo, ARM, h]
        surfaces, joints = parts_for("CounterTop", strip_size)
        if k == 0:  # the back: its cabinet ends behind the arms are blind corners
            arms = chosen[1:]
            ends = ("west", "east") if horizontal else ("south", "north")
            blind = [end in arms for end in ends]  # world low end, world high end
            if edge in ("north", "west"):  # local +x runs towards the world's low end
                blind.reverse()
            for surface in surfaces:
                if surface.name == "cabinet":
                    cut_lo, cut_hi = (ARM if b else 0.0 for b in blind)
                    surface.size[0] -= cut_lo + cut_hi
                    surface.center[0] += (cut_lo - cut_hi) / 2
        f = Furniture(
            id=f"{_sid(_need(o, 'id', where))}_{edge}",
            type="CounterTop",
            room=_room_of(house, *centre),
            position=[*centre, position[2]],
            yaw=strip_yaw,
            size=strip_size,
            surfaces=surfaces,
            joints=joints,
            asset=asset_id,
        )
        house.furniture.append(f)
        strips.append(f)
    for j, child in enumerate(_list(o, "children", where, required=False)):
        cx, cy = _xz(_need(child, "position", f"{where}.children[{j}]"), where)
        holder = min(strips, key=lambda f: _box_distance(f.footprint(), cx, cy))
        _import_object(house, child, f"{where}.children[{j}]", parent=holder)


def read_procthor_houses(
    path: Path, problems: list[str] | None = None, strict: bool = False, limit: int | None = None
) -> Iterator[House]:
    """Houses of a ProcTHOR ``.jsonl``/``.jsonl.gz`` file (one house per line), in order.

    House ``n`` (line n + 1) gets the id ``procthor_NNNNN``. A line that is not JSON or a house
    that does not import is skipped and reported in ``problems`` (one line naming the house and
    the field), or raised with ``strict``; a damaged gzip stream always raises. ``limit``: read
    only the first ``limit`` lines."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such ProcTHOR house file")
    opener = gzip.open if path.suffix == ".gz" else open
    try:
        with opener(path, "rt") as f:
            for n, line in enumerate(f):
                if limit is not None and n >= limit:
                    break
                if not line.strip():
                    continue
                try:
                    try:
                        d = json.loads(line)
                    except json.JSONDecodeError as e:
                        raise ProcTHORImportError(
                            f"{path}: line {n + 1} is not valid JSON ({e}); is the file truncated?"
                        ) from None
                    house = import_house(d, f"procthor_{n:05d}")
                except ProcTHORImportError as e:
                    if strict:
                        raise
                    if problems is not None:
                        problems.append(f"house {n} (line {n + 1}): {e}")
                    continue
                yield house
    except (EOFError, gzip.BadGzipFile, zlib.error) as e:
        raise ProcTHORImportError(
            f"{path}: the gzip stream is damaged or truncated ({e})"
        ) from None
