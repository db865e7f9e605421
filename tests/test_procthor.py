import gzip

import pytest

from maniskill_tidy.houses.procthor import ProcTHORImportError, import_house, read_procthor_houses
from maniskill_tidy.knowledge import load_catalog
from tests.conftest import DATA, REFERENCE

SAMPLE = DATA / "procthor-sample-20.jsonl.gz"
FULL = REFERENCE / "procthor-houses" / "procthor-single-room-train.jsonl.gz"


def _check(houses):
    catalog = load_catalog()
    for h in houses:
        assert h.source == "procthor" and len(h.rooms) >= 1
        assert all(r.area() > 4 for r in h.rooms)
        assert h.furniture and h.walls
        for o in h.objects:
            assert catalog.info(o.type).pickupable
            assert o.receptacle == "Floor" or o.receptacle in h.furniture_by_id()
        assert sum(row.count(".") for row in h.navgrid.rows) >= 5  # room to stand in
    return houses


def test_imports_sample_houses():
    houses = _check(list(read_procthor_houses(SAMPLE)))
    assert len(houses) == 20
    # Objects on furniture land on a surface of that furniture.
    on_furniture = 0
    for h in houses:
        furniture = h.furniture_by_id()
        for o in h.objects:
            if o.receptacle != "Floor" and furniture[o.receptacle].surfaces:
                on_furniture += 1
                assert furniture[o.receptacle].surface(o.surface)
    assert on_furniture > 50


@pytest.mark.skipif(not FULL.is_file(), reason="reference houses not present")
def test_imports_all_500_reference_houses():
    assert len(_check(list(read_procthor_houses(FULL)))) == 500


def test_truncated_file_is_a_clear_error(tmp_path):
    data = SAMPLE.read_bytes()
    bad = tmp_path / "cut.jsonl.gz"
    bad.write_bytes(data[: len(data) // 2])
    with pytest.raises(ProcTHORImportError, match="truncated"):
        list(read_procthor_houses(bad))


def test_bad_line_names_its_number(tmp_path):
    lines = gzip.decompress(SAMPLE.read_bytes()).decode().splitlines()
    bad = tmp_path / "bad.jsonl"
    bad.write_text("\n".join([lines[0], lines[1][:100], lines[2]]) + "\n")
    with pytest.raises(ProcTHORImportError, match="line 2 is not valid JSON"):
        list(read_procthor_houses(bad, strict=True))
    problems: list[str] = []
    kept = list(read_procthor_houses(bad, problems))
    assert [h.id for h in kept] == ["procthor_00000", "procthor_00002"]  # the rest is kept
    assert len(problems) == 1 and problems[0].startswith("house 1 (line 2)")


def _breakages():
    """(what is broken, how, the words its report must contain)."""

    def no_rooms(h):
        h["rooms"] = []

    def null_rotation(h):
        h["objects"][0]["rotation"] = None

    def null_yaw(h):
        h["objects"][0]["rotation"] = {"x": 0, "y": None, "z": 0}

    def door_without_x(h):
        del h["doors"][0]["holePolygon"][0]["x"]

    def far_object(h):
        h["objects"][0]["position"]["x"] = 50.0

    return [
        (no_rooms, ["rooms is empty"]),
        (null_rotation, ["objects[0].rotation", "None"]),
        (null_yaw, ["objects[0].rotation.y", "None"]),
        (door_without_x, ["doors[0].holePolygon[0]", "'x'"]),
        (far_object, ["objects[0].position", "outside every room"]),
    ]


def test_each_bad_house_is_reported_with_its_index_and_field_and_the_rest_kept(tmp_path):
    import json

    lines = gzip.decompress(SAMPLE.read_bytes()).decode().splitlines()
    houses = [json.loads(x) for x in lines[:6]]
    broken = _breakages()
    for i, (breakage, _) in enumerate(broken):
        breakage(houses[i])
    path = tmp_path / "mixed.jsonl"
    path.write_text("".join(json.dumps(h) + "\n" for h in houses))
    problems: list[str] = []
    kept = list(read_procthor_houses(path, problems))
    assert [h.id for h in kept] == [f"procthor_{len(broken):05d}"]
    assert len(problems) == len(broken)
    for i, (problem, (_, words)) in enumerate(zip(problems, broken, strict=True)):
        assert problem.startswith(f"house {i} (line {i + 1}): procthor_{i:05d}"), problem
        for w in words:
            assert w in problem, (w, problem)
        assert "Error" not in problem.split(":", 2)[-1][:20], problem  # no bare exception name


def test_missing_field_is_named():
    import json

    house = json.loads(gzip.decompress(SAMPLE.read_bytes()).decode().splitlines()[0])
    del house["rooms"][0]["floorPolygon"]
    with pytest.raises(ProcTHORImportError, match=r"rooms\[0\]: missing 'floorPolygon'"):
        import_house(house, "h")
    house = json.loads(gzip.decompress(SAMPLE.read_bytes()).decode().splitlines()[0])
    house["objects"][0]["assetId"] = "NoSuchAsset_1"
    with pytest.raises(ProcTHORImportError, match="unknown assetId 'NoSuchAsset_1'"):
        import_house(house, "h")
