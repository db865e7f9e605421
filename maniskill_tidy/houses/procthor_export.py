"""Write our houses in ProcTHOR's house format, so that they can be loaded where ProcTHOR
houses are (AI2-THOR's ``Controller(scene=house)``) and read back by ``generate --procthor``.

The inverse of :mod:`maniskill_tidy.houses.procthor`: our (x, y, z) is Unity's (x, z, y), a
yaw of ``a`` radians is a rotation of ``-degrees(a)`` about Unity's y, positions are
bounding-box centres. Each piece and object gets the asset of its type in ProcTHOR's asset
database whose size is nearest to ours (log-ratio distance over width, depth and height);
types with no asset there (our Bathtub and StoveBurner) are left out, with what stands on them,
and counted. Objects and stacked furniture become children of what they rest on, which is how
the importer finds their surface.
"""

from __future__ import annotations

import gzip
import json
import math
from collections import Counter
from functools import cache
from pathlib import Path

from maniskill_tidy.common.files import write_atomic
from maniskill_tidy.houses.schema import Furniture, House, PlacedObject
from maniskill_tidy.knowledge import FLOOR
from maniskill_tidy.knowledge.catalog import load_assets

ON_LEFT_OUT = "(on a piece left out)"


@cache
def _assets_by_type() -> dict[str, list[tuple[str, float, float, float]]]:
    out: dict[str, list] = {}
    for asset_id, (type_name, w, d, h) in sorted(load_assets().items()):
        out.setdefault(type_name, []).append((asset_id, w, d, h))
    return out


def nearest_asset(type_name: str, size: list[float]) -> tuple[str, float] | None:
    """(asset id, its height) of ``type_name`` nearest in size, or None if the type has none."""
    candidates = _assets_by_type().get(type_name)
    if not candidates:
        return None

    def distance(c: tuple[str, float, float, float]) -> float:
        return sum(
            abs(math.log(max(a, 1e-3) / max(b, 1e-3))) for a, b in zip(c[1:], size[:3], strict=True)
        )

    best = min(candidates, key=distance)
    return best[0], best[3]


def _pid(our_id: str) -> str:
    return our_id.replace("_", "|")  # the importer maps "|" back to "_"


def _point(x: float, y: float, z: float = 0.0) -> dict:
    return {"x": round(x, 4), "y": round(z, 4), "z": round(y, 4)}


def _placed(item: Furniture | PlacedObject, asset: tuple[str, float]) -> dict:
    asset_id, height = asset
    x, y, z = item.position
    return {
        "id": _pid(item.id),
        "assetId": asset_id,
        "position": _point(x, y, z + height / 2),
        "rotation": {"x": 0, "y": round(-math.degrees(item.yaw), 4) % 360, "z": 0},
        "kinematic": isinstance(item, Furniture),
        "children": [],
    }


def export_house(house: House, left_out: Counter | None = None) -> dict:
    """``house`` as a ProcTHOR house dict; counts in ``left_out`` what has no asset, by type,
    and what stood on such a piece, as "TYPE (on a piece left out)".

    Long on purpose: it writes ProcTHOR's schema field by field in the schema's order (rooms,
    walls, doors, objects and their children), so that it reads beside the importer."""
    left_out = left_out if left_out is not None else Counter()
    rooms = [
        {
            "id": _pid(r.id),
            "roomType": r.type,
            "children": [],
            "ceilings": [],
            "floorPolygon": [_point(x, y) for x, y in r.polygon],
            "floorMaterial": {"name": r.floor_material},
        }
        for r in house.rooms
    ]
    walls, wall_of_room = [], {}
    for w in house.walls:
        coords = "|".join(f"{v:.2f}" for v in (*w.start, *w.end))
        for room in w.rooms:
            wid = f"wall|{_pid(room).split('|')[-1]}|{coords}"
            wall_of_room[(w.id, room)] = wid
            walls.append(
                {
                    "id": wid,
                    "roomId": _pid(room),
                    "polygon": [
                        _point(*w.start),
                        _point(*w.end),
                        _point(*w.start, w.height),
                        _point(*w.end, w.height),
                    ],
                    "material": {"name": w.material},
                }
            )
    walls_by_id = {w.id: w for w in house.walls}
    first = {wall: wid for (wall, _), wid in reversed(list(wall_of_room.items()))}
    doors = []
    for i, d in enumerate(house.doors):
        wall = walls_by_id[d.wall]
        room0, room1 = d.rooms[0], d.rooms[-1]
        along = math.dist(wall.start, d.center)
        asset = nearest_asset("Doorway", [d.width, wall.thickness, d.height])
        doors.append(
            {
                "id": f"door|{i}",
                "room0": _pid(room0),
                "room1": _pid(room1),
                "wall0": wall_of_room.get((wall.id, room0), first[wall.id]),
                "wall1": wall_of_room.get((wall.id, room1), first[wall.id]),
                "assetId": asset[0] if asset else "Doorway_1",
                "holePolygon": [
                    {"x": round(along - d.width / 2, 4), "y": 0, "z": 0},
                    {"x": round(along + d.width / 2, 4), "y": round(d.height, 4), "z": 0},
                ],
                "openable": False,
                "openness": 0,
            }
        )

    nodes: dict[str, dict] = {}
    top: list[dict] = []
    for f in house.furniture:  # parents come before the pieces stacked on them
        asset = nearest_asset(f.type, f.size)
        parent = nodes.get(f.parent) if f.parent else None
        if asset is None:
            left_out[f.type] += 1
            continue
        if f.parent and parent is None:
            left_out[f"{f.type} {ON_LEFT_OUT}"] += 1
            continue
        nodes[f.id] = _placed(f, asset)
        (parent["children"] if parent else top).append(nodes[f.id])
    for o in house.objects:
        asset = nearest_asset(o.type, o.size)
        holder = nodes.get(o.receptacle) if o.receptacle != FLOOR else None
        if asset is None:
            left_out[o.type] += 1
            continue
        if o.receptacle != FLOOR and holder is None:
            left_out[f"{o.type} {ON_LEFT_OUT}"] += 1
            continue
        (holder["children"] if holder else top).append(_placed(o, asset))
    height = max((w.height for w in house.walls), default=2.5)
    return {
        "rooms": rooms,
        "walls": walls,
        "doors": doors,
        "windows": [],
        "objects": top,
        "proceduralParameters": {
            "floorColliderThickness": 1.0,
            "receptacleHeight": 0.7,
            "lights": [
                {
                    "id": light.id,
                    "type": "point",
                    "position": _point(*light.position),
                    "intensity": light.intensity,
                    "range": 15,
                    "rgb": {"r": 1.0, "g": 1.0, "b": 1.0},
                }
                for light in house.lights
            ],
            "reflections": [],
            "ceilingMaterial": {"name": "PureWhite"},
            "skyboxId": "SkySFGarden",
        },
        "metadata": {
            "schema": "1.0.0",
            "source": f"maniskill-tidy {house.source} house {house.id}",
            "roomSpecId": "+".join(house.room_spec),
            "wallHeight": height,
            "warnings": {},
        },
    }


def export_houses(houses: list[House], out: Path) -> Counter:
    """Write ``houses`` to ``out`` (.jsonl or .jsonl.gz, one house per line), atomically;
    returns what was left out for want of an asset, by type."""
    out = Path(out)
    left_out: Counter = Counter()
    lines = "".join(json.dumps(export_house(h, left_out)) + "\n" for h in houses)
    data = lines.encode()
    write_atomic(out, gzip.compress(data, mtime=0) if out.suffix == ".gz" else data)
    return left_out
