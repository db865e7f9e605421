"""Regenerate the shipped knowledge tables from ProcTHOR's databases.

Run once by a maintainer (``maniskill-tidy derive-knowledge --reference DIR``); the package
only ever reads the derived files in ``knowledge/data``. Source: the ``procthor`` package's
``databases/`` folder (allenai/procthor, Apache License 2.0).

The rule behind ``D`` is ``RULE`` below; it is copied into ``placement.json``.
"""

from __future__ import annotations

import gzip
import json
from collections import Counter, defaultdict
from pathlib import Path
from statistics import median

ROOM_TYPES = ("Kitchen", "LivingRoom", "Bedroom", "Bathroom")
METADATA_ROOMS = {
    "kitchens": "Kitchen",
    "living_rooms": "LivingRoom",
    "bedrooms": "Bedroom",
    "bathrooms": "Bathroom",
}
ANNOTATION_ROOMS = {
    "inKitchens": "Kitchen",
    "inLivingRooms": "LivingRoom",
    "inBedrooms": "Bedroom",
    "inBathrooms": "Bathroom",
}
# Architecture, not objects: excluded from the category list an agent's map channels use.
ARCHITECTURE = ("Floor", "Doorframe", "Doorway", "Window")
MIN_RECEPTACLE_P = 0.02
FLOOR = "Floor"
RULE = (
    "D(o, p, r) is true iff (1) o is pickupable, p is a receptacle type other than Floor "
    "(nothing is tidy on the floor) and r is one of the four room types; and (2) either "
    "(a) some AI2-THOR room of type r has an o whose parentReceptacles include a p (the paper's "
    "rule: AI2-THOR's placements are the reasonable ones), or (b) receptacles.json gives "
    "P(o on p) >= min_receptacle_p over AI2-THOR scenes and both o and p occur in room type r "
    "(placement-annotation weight >= 1, or seen there in the metadata). (b) fills gaps of the "
    "120-room metadata without admitting pairs that no room type supports."
)
SOURCE = "ProcTHOR databases (allenai/procthor, Apache License 2.0), procthor==0.0.1.dev2"


def _load(reference: Path) -> tuple[dict, dict, dict, dict]:
    needed = [
        "asset-database.json",
        "placement-annotations.json",
        "receptacles.json",
        "ai2thor-object-metadata.json.gz",
    ]
    missing = [n for n in needed if not (reference / n).is_file()]
    if missing:
        raise FileNotFoundError(
            f"{reference} lacks {', '.join(missing)}; expected ProcTHOR's databases/ folder"
        )
    assets = json.loads((reference / "asset-database.json").read_text())
    annotations = json.loads((reference / "placement-annotations.json").read_text())
    receptacles = json.loads((reference / "receptacles.json").read_text())
    with gzip.open(reference / "ai2thor-object-metadata.json.gz", "rt") as f:
        metadata = json.load(f)
    return assets, annotations, receptacles, metadata


def derive(reference: Path) -> tuple[dict, dict, dict]:
    """Return the (catalog, placement, assets) tables derived from ``reference``.

    A maintainers' derivation (``derive-knowledge``), kept as one pass: each table is built
    from the ones before it in the order the paper describes them, and the intermediate sets
    are not meaningful on their own."""
    assets, annotations, receptacles, metadata = _load(reference)

    pickupable: set[str] = set()
    receptacle: set[str] = set()
    openable: set[str] = set()
    sizes: dict[str, list[tuple[float, float, float]]] = defaultdict(list)
    for obj_type, variants in assets.items():
        for v in variants:
            if v.get("primaryProperty") == "CanPickup":
                pickupable.add(obj_type)
            if "Receptacle" in v.get("secondaryProperties", []):
                receptacle.add(obj_type)
            if "CanOpen" in v.get("secondaryProperties", []):
                openable.add(obj_type)
            bb = v["boundingBox"]
            # Unity is y-up; we store (width x, depth y, height z), z-up.
            sizes[obj_type].append((bb["x"], bb["z"], bb["y"]))

    metadata_receptacle: set[str] = set()
    seen_triples: Counter[tuple[str, str, str]] = Counter()
    seen_in_room: dict[str, set[str]] = defaultdict(set)
    all_types = set(assets)
    for room_key, scenes in metadata.items():
        room = METADATA_ROOMS.get(room_key)  # RoboTHOR apartments have no single room type
        for scene in scenes:
            for obj in scene:
                t = obj["objectType"]
                all_types.add(t)
                if obj.get("pickupable"):
                    pickupable.add(t)
                if obj.get("receptacle"):
                    receptacle.add(t)
                    metadata_receptacle.add(t)
                if obj.get("openable"):
                    openable.add(t)
                if room is None:
                    continue
                seen_in_room[t].add(room)
                if obj.get("pickupable"):
                    for parent in obj.get("parentReceptacles") or []:
                        seen_triples[(t, parent.split("|")[0], room)] += 1

    def rooms_of(t: str) -> set[str]:
        rooms = set(seen_in_room.get(t, ()))
        for key, room in ANNOTATION_ROOMS.items():
            if (annotations[key].get(t) or 0) >= 1:
                rooms.add(room)
        return rooms

    reasonable: dict[str, dict[str, dict]] = {}
    for o in sorted(pickupable):
        entries: dict[str, dict] = {}
        for p in sorted(receptacle - {FLOOR}):
            for r in ROOM_TYPES:
                count = seen_triples.get((o, p, r), 0)
                prob = receptacles.get(p, {}).get(o, {}).get("p", 0.0)
                by_prior = prob >= MIN_RECEPTACLE_P and r in rooms_of(o) and r in rooms_of(p)
                if count or by_prior:
                    entries[f"{p}|{r}"] = {
                        "receptacle": p,
                        "room": r,
                        "ai2thor_count": count,
                        "receptacle_p": round(prob, 4),
                    }
        reasonable[o] = entries

    def typical_size(t: str) -> list[float] | None:
        if not sizes.get(t):
            return None
        return [round(median(s[i] for s in sizes[t]), 3) for i in range(3)]

    def room_weights(t: str) -> dict[str, int]:
        return {room: int(annotations[key].get(t) or 0) for key, room in ANNOTATION_ROOMS.items()}

    def stance(t: str) -> dict[str, bool | None]:
        keys = ("onFloor", "onEdge", "inCorner", "inMiddle", "onWall", "multiplePerRoom")
        return {k: annotations[k].get(t) for k in keys}

    categories = sorted(all_types - set(ARCHITECTURE))
    catalog = {
        "source": SOURCE,
        "room_types": list(ROOM_TYPES),
        "categories": categories,
        "pickupable": sorted(pickupable),
        "receptacles": sorted(receptacle),
        "ai2thor_receptacles": sorted(metadata_receptacle),
        "tidyable": sorted(o for o, e in reasonable.items() if e),
        "types": {
            t: {
                "pickupable": t in pickupable,
                "receptacle": t in receptacle,
                "openable": t in openable,
                "size": typical_size(t),
                "room_weights": room_weights(t),
                "seen_in_rooms": sorted(seen_in_room.get(t, ())),
                "stance": stance(t),
            }
            for t in categories
        },
    }
    placement = {
        "source": SOURCE,
        "rule": RULE,
        "min_receptacle_p": MIN_RECEPTACLE_P,
        "reasonable": reasonable,
    }
    assets_table = {
        "source": SOURCE,
        "columns": ["objectType", "width_x", "depth_y", "height_z"],
        "assets": {
            v["assetId"]: [
                t,
                round(v["boundingBox"]["x"], 3),
                round(v["boundingBox"]["z"], 3),
                round(v["boundingBox"]["y"], 3),
            ]
            for t, variants in assets.items()
            for v in variants
        },
    }
    return catalog, placement, assets_table


def write(tables: tuple[dict, dict, dict], out_dir: Path) -> None:
    """Write the tables atomically (write to a temp file, then rename)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    names = ("catalog.json", "placement.json", "assets.json")
    for name, data in zip(names, tables, strict=True):
        tmp = out_dir / f".{name}.tmp"
        tmp.write_text(
            json.dumps(data, indent=None if name == "assets.json" else 1, sort_keys=True) + "\n"
        )
        tmp.replace(out_dir / name)
