"""Check a dataset against everything it claims, and say in words what is wrong.

Nothing in a dataset is trusted: hashes are recomputed, the navigation grid is recomputed from
the geometry, D is re-evaluated for every placed and every misplaced object, labels and goals
are re-derived, and every start and goal is checked for reachability.
"""

from __future__ import annotations

from pathlib import Path

from tqdm import tqdm

from maniskill_tidy.common.files import sha256
from maniskill_tidy.houses.checks import check_house, slot_of
from maniskill_tidy.houses.navgrid import (
    REACH,
    frame_of,
    grid_array,
    main_component,
    reach_cells,
)
from maniskill_tidy.houses.schema import (
    CELL,
    House,
    HouseFormatError,
    house_from_dict,
    rotated_bounds,
)
from maniskill_tidy.knowledge import FLOOR, load_placement
from maniskill_tidy.tasks.dataset import (
    DatasetError,
    read_manifest,
    read_shard,
)
from maniskill_tidy.tasks.metatask import MetaTask, findable, label, reasonable_surfaces
from maniskill_tidy.tasks.starts import ROTATIONS
from maniskill_tidy.tasks.teams import SETTINGS


def check_task(house: House, task: MetaTask, from_floor: bool = False) -> list[str]:
    """Every problem of one meta-task in its house. ``from_floor``: heights as ProcTHOR
    datasets measure them (see ``findable``).

    One list of checks in the order a task is built (objects, their misplacements, labels,
    goals, starts), each a few lines that append to the same list of problems."""
    where = task.id
    problems = []
    if not 1 <= task.k <= 5 or task.k != len(task.misplaced):
        problems.append(
            f"{where}: k={task.k} with {len(task.misplaced)} misplaced objects; "
            "expected k in 1..5 equal to their number"
        )
    if task.kind != label(task.misplaced):
        problems.append(f"{where}: labelled {task.kind} but objects say {label(task.misplaced)}")
    knowledge = load_placement()
    rooms = {r.id: r.type for r in house.rooms}
    objects = house.object_by_id()
    frame, free = frame_of(house.navgrid), grid_array(house.navgrid)
    walkable = main_component(free)
    for m in task.misplaced:
        o = objects.get(m.object)
        if o is None or o.type != m.type:
            problems.append(f"{where}: {m.object} ({m.type}) is not an object of {house.id}")
            continue
        if (m.original.receptacle, m.original.surface) != (o.receptacle, o.surface):
            problems.append(f"{where}: {m.object} original location differs from the house")
        loc = m.misplaced
        if loc.room not in rooms:
            problems.append(f"{where}: {m.object} moved to unknown room {loc.room}")
            continue
        if loc.receptacle == FLOOR:
            rtype = FLOOR
            fp_reach = CELL * 1.5
        else:
            slot = slot_of(house, loc.receptacle, loc.surface)
            if slot is None:
                problems.append(
                    f"{where}: {m.object} moved to unknown {loc.receptacle}/{loc.surface}"
                )
                continue
            rtype, fp_reach = slot.surface.receptacle_type, REACH
            if not findable(slot.furniture, slot.surface, from_floor):
                problems.append(
                    f"{where}: {m.object} misplaced on {loc.receptacle}/{loc.surface}, where no "
                    "robot camera can see it (too high, a drawer or an open-top bin)"
                )
        if knowledge.D(m.type, rtype, rooms[loc.room]):
            problems.append(
                f"{where}: {m.object} 'misplaced' on {rtype} in {rooms[loc.room]}, "
                "where D is true: it is not misplaced"
            )
        moved = loc.room != m.original.room
        if (m.how == "other_room_receptacle") != moved:
            problems.append(f"{where}: {m.object} move '{m.how}' does not match its rooms")
        footprint = rotated_bounds(loc.position, o.size[0], o.size[1], loc.yaw)
        if not reach_cells(frame, walkable, footprint, fp_reach).any():
            problems.append(f"{where}: {m.object} at its misplaced location is out of reach")
        expected = reasonable_surfaces(house, m.type, o.size)
        if sorted(map(tuple, m.reasonable)) != sorted(map(tuple, expected)):
            problems.append(f"{where}: {m.object} goal set differs from what D gives in this house")
        if not m.reasonable:
            problems.append(f"{where}: {m.object} has no reasonable location in this house")
    for setting, team in SETTINGS.items():
        configs = task.starts.get(setting)
        if not configs:
            problems.append(f"{where}: no start configurations for setting {setting}")
            continue
        for j, config in enumerate(configs):
            cells = [tuple(a["cell"]) for a in config]
            if len(config) != len(team):
                problems.append(
                    f"{where}: setting {setting} start {j} has {len(config)} agents, "
                    f"the team has {len(team)}"
                )
            if len(set(cells)) != len(cells):
                problems.append(f"{where}: setting {setting} start {j}: agents share a cell")
            for a in config:
                r, c = a["cell"]
                inside = 0 <= r < walkable.shape[0] and 0 <= c < walkable.shape[1]
                if not inside or not walkable[r, c]:
                    problems.append(
                        f"{where}: setting {setting} start {j}: cell {(r, c)} is not "
                        "free and connected"
                    )
                if a["rotation"] not in ROTATIONS:
                    problems.append(f"{where}: rotation {a['rotation']} not in {ROTATIONS}")
    return problems


def validate_dataset(root: Path, progress: bool = True, deep: bool = True) -> list[str]:
    """All problems found in the dataset at ``root`` (empty when it is sound)."""
    root = Path(root)
    try:
        manifest = read_manifest(root)
    except DatasetError as e:
        return [str(e)]
    problems = []
    from_floor = "importer_version" in manifest  # made by generate --procthor
    listed = set(manifest.get("files", {}))
    if not listed or not any(f.get("houses") for f in manifest.get("files", {}).values()):
        problems.append("manifest.json: the dataset has no houses (generate with --houses >= 1)")
    on_disk = {str(p.relative_to(root)) for p in root.glob("*/shard-*.json.gz")}
    for name in sorted(on_disk - listed):
        problems.append(f"{name}: shard on disk but not in the manifest")
    recomputed = sha256(
        "".join(f"{n}:{f['sha256']}\n" for n, f in sorted(manifest["files"].items())).encode()
    )
    if recomputed != manifest.get("dataset_hash"):
        problems.append("manifest.json: dataset_hash does not match the listed file hashes")
    for name in tqdm(sorted(listed), desc="validate", unit="shard", disable=not progress):
        path = root / name
        if not path.is_file():
            problems.append(f"{name}: listed in the manifest but missing")
            continue
        data = path.read_bytes()
        entry = manifest["files"][name]
        if sha256(data) != entry["sha256"]:
            problems.append(f"{name}: sha256 differs from the manifest (file changed or truncated)")
        try:
            payload = read_shard(path)
        except DatasetError as e:
            problems.append(str(e))
            continue
        if len(payload["houses"]) != entry["houses"] or len(payload["tasks"]) != entry["tasks"]:
            problems.append(
                f"{name}: holds {len(payload['houses'])} houses and "
                f"{len(payload['tasks'])} tasks, the manifest says {entry['houses']} "
                f"and {entry['tasks']}"
            )
        houses = {}
        for i, h in enumerate(payload["houses"]):
            try:
                house = house_from_dict(h)
            except HouseFormatError as e:
                problems.append(f"{name}: houses[{i}]: {e}")
                continue
            houses[house.id] = house
            if deep:
                problems += [f"{name}: {p}" for p in check_house(house)]
        for i, t in enumerate(payload["tasks"]):
            try:
                task = MetaTask.from_dict(t)
            except (TypeError, KeyError) as e:
                problems.append(f"{name}: tasks[{i}] malformed: {e}")
                continue
            house = houses.get(task.house_id)
            if house is None:
                problems.append(f"{name}: task {task.id} refers to unknown house {task.house_id}")
                continue
            problems += [f"{name}: {p}" for p in check_task(house, task, from_floor)]
    return problems
