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
    bad.write_text("\n".join([lines[0], lines[1][:100]]) + "\n")
    with pytest.raises(ProcTHORImportError, match="line 2 is not valid JSON"):
        list(read_procthor_houses(bad))


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
