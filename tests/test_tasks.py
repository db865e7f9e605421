import gc
import gzip
import json
import shutil

import pytest

from maniskill_tidy.cli import main
from maniskill_tidy.common.files import sha256
from maniskill_tidy.common.memory import collector_paused
from maniskill_tidy.houses.generator import generate_house
from maniskill_tidy.knowledge import FLOOR, load_placement
from maniskill_tidy.tasks import dataset as tasks_dataset
from maniskill_tidy.tasks.dataset import (
    DatasetError,
    dumps_gz,
    generate_dataset,
    load_dataset,
    write_manifest,
)
from maniskill_tidy.tasks.metatask import (
    Location,
    Misplacement,
    generate_meta_tasks,
    label,
    single_schedule,
)
from maniskill_tidy.tasks.stats import dataset_stats
from maniskill_tidy.tasks.teams import SETTINGS, team
from maniskill_tidy.tasks.validate import check_task, validate_dataset


def _m(orig_room: str, new_room: str) -> Misplacement:
    loc = lambda room: Location("X", "top", room, [0, 0, 0], 0.0)  # noqa: E731
    return Misplacement("o", "Apple", loc(orig_room), loc(new_room), "floor", [])


def test_single_and_cross_labels_follow_the_paper():
    assert label([_m("a", "a"), _m("b", "b")]) == "Single"
    assert label([_m("a", "a"), _m("b", "c")]) == "Cross"
    assert label([_m("a", "c")]) == "Cross"


@pytest.fixture(scope="module")
def house_and_tasks():
    house = generate_house(4, 2)
    return house, generate_meta_tasks(house, 4, 2)


def test_meta_tasks_misplace_objects_unreasonably(house_and_tasks):
    house, tasks = house_and_tasks
    D = load_placement().D
    rooms = {r.id: r.type for r in house.rooms}
    furniture = house.furniture_by_id()
    assert len(tasks) == 10
    for task in tasks:
        assert check_task(house, task) == []
        assert 1 <= task.k <= 5 and len({m.object for m in task.misplaced}) == task.k
        for m in task.misplaced:
            loc = m.misplaced
            rtype = (
                FLOOR
                if loc.receptacle == FLOOR
                else furniture[loc.receptacle].surface(loc.surface).receptacle_type
            )
            assert not D(m.type, rtype, rooms[loc.room])
            orig = furniture[m.original.receptacle].surface(m.original.surface)
            assert D(m.type, orig.receptacle_type, rooms[m.original.room])
            assert [m.original.receptacle, m.original.surface] in m.reasonable
        for setting, members in SETTINGS.items():
            assert len(task.starts[setting]) == 5
            assert all(len(c) == len(members) for c in task.starts[setting])


def test_meta_tasks_are_deterministic(house_and_tasks):
    house, tasks = house_and_tasks
    again = generate_meta_tasks(generate_house(4, 2), 4, 2)
    assert [t.to_dict() for t in tasks] == [t.to_dict() for t in again]


def test_check_task_catches_a_reasonable_misplacement(house_and_tasks):
    house, tasks = house_and_tasks
    task = tasks[0]
    m = task.misplaced[0]
    m.misplaced = Location(
        m.original.receptacle,
        m.original.surface,
        m.original.room,
        m.original.position,
        m.original.yaw,
    )
    problems = check_task(house, task)
    assert any("where D is true" in p for p in problems)


def test_team_presets_and_custom_teams():
    assert team("I") == ((1, 0, 0), (1, 0, 1), (1, 1, 1))
    assert len(team("II")) == 4
    assert team([[1, 1, 0], (1, 0, 1)]) == ((1, 1, 0), (1, 0, 1))
    with pytest.raises(ValueError, match="unknown setting 'III'"):
        team("III")
    with pytest.raises(ValueError, match="not a \\(Nav, Mani, Hei\\) triple"):
        team([(1, 2, 0)])


def test_dataset_is_byte_identical_across_runs_and_workers(tmp_path):
    a = generate_dataset(tmp_path / "a", 8, seed=9, progress=False, workers=1)
    b = generate_dataset(tmp_path / "b", 8, seed=9, progress=False, workers=2)
    assert a["dataset_hash"] == b["dataset_hash"]
    for name in a["files"]:
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    assert (tmp_path / "a/manifest.json").read_bytes() == (
        tmp_path / "b/manifest.json"
    ).read_bytes()
    c = generate_dataset(tmp_path / "c", 8, seed=10, progress=False)
    assert c["dataset_hash"] != a["dataset_hash"]


def test_default_split_is_the_papers_4_1_1(small_dataset):
    manifest = json.loads((small_dataset / "manifest.json").read_text())
    assert manifest["splits"] == {"train": 8, "val": 2, "test": 2}
    test = load_dataset(small_dataset, "test")
    assert len(test.houses) == 2 and len(test.tasks) == 20
    assert len(list(test.episodes("I"))) == 100  # 10 meta-tasks x 5 starts per house


def test_loading_pauses_the_collector_and_leaves_it_as_it_was(small_dataset, monkeypatch):
    seen = []
    real = tasks_dataset.house_from_dict

    def spy(d):
        seen.append(gc.isenabled())
        return real(d)

    monkeypatch.setattr(tasks_dataset, "house_from_dict", spy)
    assert gc.isenabled()
    load_dataset(small_dataset, "test")
    assert seen and not any(seen) and gc.isenabled()  # paused while loading, on again after
    gc.disable()
    try:
        load_dataset(small_dataset, "test")
        assert not gc.isenabled()  # a caller who paused it keeps it paused
    finally:
        gc.enable()
    with pytest.raises(RuntimeError), collector_paused():
        raise RuntimeError("a shard fails to parse")
    assert gc.isenabled()


def test_generation_resumes_and_refuses_other_arguments(tmp_path, small_dataset):
    out = tmp_path / "resume"
    shutil.copytree(small_dataset, out)
    (out / "manifest.json").unlink()
    (out / "train/shard-0000.json.gz").unlink()
    again = generate_dataset(out, 12, seed=3, progress=False)
    assert (
        again["dataset_hash"]
        == json.loads((small_dataset / "manifest.json").read_text())["dataset_hash"]
    )
    with pytest.raises(DatasetError, match="other arguments"):
        generate_dataset(out, 12, seed=4, progress=False)


def test_validate_accepts_a_sound_dataset(small_dataset):
    assert validate_dataset(small_dataset, progress=False) == []


def test_validate_explains_a_truncated_shard(tmp_path, small_dataset):
    out = tmp_path / "cut"
    shutil.copytree(small_dataset, out)
    shard = out / "val/shard-0000.json.gz"
    shard.write_bytes(shard.read_bytes()[:500])
    problems = validate_dataset(out, progress=False)
    assert any("val/shard-0000.json.gz: sha256 differs" in p for p in problems)
    assert any("not a complete gzip file" in p for p in problems)
    assert main(["validate", str(out)]) == 1


def test_validate_explains_tampered_content_even_with_fixed_hashes(tmp_path, small_dataset):
    out = tmp_path / "tampered"
    shutil.copytree(small_dataset, out)
    shard = out / "test/shard-0000.json.gz"
    payload = json.loads(gzip.decompress(shard.read_bytes()))
    task = payload["tasks"][0]
    m = task["misplaced"][0]
    m["misplaced"] = dict(m["original"])  # "misplaced" back where it belongs
    crosses = any(x["original"]["room"] != x["misplaced"]["room"] for x in task["misplaced"])
    task["kind"] = "Single" if crosses else "Cross"  # the wrong label for what remains
    shard.write_bytes(dumps_gz(payload))
    manifest = json.loads((out / "manifest.json").read_text())
    params = {
        k: manifest[k] for k in ("houses", "seed", "splits", "generator_version", "schema_version")
    }
    write_manifest(out, params, list(manifest["files"]))  # hashes now match the tampering
    problems = validate_dataset(out, progress=False)
    assert any("where D is true: it is not misplaced" in p for p in problems)
    assert any("labelled" in p for p in problems)


def test_validate_without_manifest(tmp_path):
    assert "no manifest.json" in validate_dataset(tmp_path, progress=False)[0]


def test_dataset_stats_shares(small_dataset, tmp_path):
    stats = dataset_stats(small_dataset)
    total = stats["splits"]["all"]
    assert total["tasks"] == 120
    assert abs(sum(total["k_share"].values()) - 1) < 1e-3
    assert abs(sum(total["kind_share"].values()) - 1) < 1e-3
    assert set(total["k_share"]) <= {"1", "2", "3", "4", "5"}
    png = tmp_path / "stats.png"
    assert main(["dataset-stats", str(small_dataset), "--png", str(png)]) == 0
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_sha256_helper_matches_manifest(small_dataset):
    manifest = json.loads((small_dataset / "manifest.json").read_text())
    name, entry = next(iter(manifest["files"].items()))
    assert sha256((small_dataset / name).read_bytes()) == entry["sha256"]


def test_paper_sized_dataset_validates(tmp_path):
    """The paper's 120 houses (80/20/20): every house and task passes every check."""
    manifest = generate_dataset(tmp_path / "d120", 120, seed=0, progress=False, workers=2)
    assert manifest["tasks"] == {"train": 800, "val": 200, "test": 200}
    assert validate_dataset(tmp_path / "d120", progress=False) == []
    # the paper's test split has 565 Single episodes of 1000 (5 starts per meta-task)
    test = load_dataset(tmp_path / "d120", "test")
    single = 5 * sum(t.kind == "Single" for t in test.tasks)
    assert abs(single - 565) <= 30, single


def test_single_schedule_gives_the_fraction_whatever_the_one_room_houses():
    multi, one = generate_house(0, 3), generate_house(0, 3, spec=["Kitchen"])
    assert len(multi.rooms) > 1 and len(one.rooms) == 1
    for n_one in (0, 2, 5):
        houses = [one] * n_one + [multi] * (20 - n_one)
        schedule = single_schedule(houses, list(range(20)), seed=0, fraction=0.565)
        assert sum(len(v) for v in schedule.values()) == 113  # round(0.565 * 200)
        assert all(schedule[i] == set(range(10)) for i in range(n_one))
        counts = [len(schedule[i]) for i in range(n_one, 20)]
        assert max(counts) - min(counts) <= 1  # spread evenly over the multi-room houses
    assert single_schedule([multi], [7], 0) == single_schedule([multi], [7], 0)
    with pytest.raises(ValueError, match="Single fraction"):
        single_schedule([multi], [0], 0, fraction=1.5)


def test_a_cross_task_moves_an_object_to_another_room_and_a_single_one_does_not():
    house = generate_house(4, 2)
    assert len(house.rooms) > 1
    tasks = generate_meta_tasks(house, 4, 2, single={0, 1, 2, 3, 4})
    assert [t.kind for t in tasks[:5]] == ["Single"] * 5
    assert all(t.kind == "Cross" for t in tasks[5:])
