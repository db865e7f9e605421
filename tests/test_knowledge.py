import json

import pytest

from maniskill_tidy.knowledge import FLOOR, ROOM_TYPES, load_catalog, load_placement
from tests.conftest import REFERENCE


@pytest.fixture(scope="module")
def D():
    return load_placement().D


def test_type_counts_match_the_reference_data():
    c = load_catalog()
    assert len(c.pickupable) == 62
    assert len(c.categories) == 119  # the paper reports 118; see docs/task.md for the difference
    assert FLOOR in c.receptacles and "Fridge" in c.receptacles
    assert set(c.tidyable) < set(c.pickupable)
    assert "Plunger" not in c.tidyable  # AI2-THOR only ever has plungers on the floor


@pytest.mark.parametrize(
    "obj,rec,room",
    [
        ("Egg", "Fridge", "Kitchen"),
        ("Pillow", "Bed", "Bedroom"),
        ("Pillow", "Sofa", "LivingRoom"),
        ("Towel", "TowelHolder", "Bathroom"),
        ("Laptop", "Desk", "Bedroom"),
        ("Apple", "CounterTop", "Kitchen"),
        ("SoapBottle", "CounterTop", "Bathroom"),
    ],
)
def test_commonsense_placements_are_reasonable(D, obj, rec, room):
    assert D(obj, rec, room)


@pytest.mark.parametrize(
    "obj,rec,room",
    [
        ("Pillow", "Sink", "Bathroom"),
        ("Egg", "Bed", "Bedroom"),
        ("Laptop", "Fridge", "Kitchen"),
        ("Towel", "CounterTop", "Kitchen"),
        ("Pillow", "Bed", "Kitchen"),  # right receptacle type, wrong room
        ("Egg", "Fridge", "Bathroom"),
    ],
)
def test_commonsense_misplacements_are_not(D, obj, rec, room):
    assert not D(obj, rec, room)


def test_nothing_is_reasonable_on_the_floor(D):
    for obj in load_catalog().pickupable:
        for room in ROOM_TYPES:
            assert not D(obj, FLOOR, room)


def test_unknown_room_is_an_error(D):
    with pytest.raises(ValueError, match="unknown room type 'Garage'"):
        D("Egg", "Fridge", "Garage")


def test_every_tidyable_type_has_reasonable_locations():
    k = load_placement()
    for obj in load_catalog().tidyable:
        assert k.locations(obj), obj


@pytest.mark.skipif(not (REFERENCE / "procthor-databases").is_dir(), reason="no reference data")
def test_shipped_tables_regenerate_from_the_reference(tmp_path):
    from maniskill_tidy.knowledge.derive import derive, write

    write(derive(REFERENCE / "procthor-databases"), tmp_path)
    from importlib import resources

    data = resources.files("maniskill_tidy.knowledge").joinpath("data")
    for name in ("catalog.json", "placement.json", "assets.json"):
        regenerated = json.loads((tmp_path / name).read_text())
        assert regenerated == json.loads(data.joinpath(name).read_text()), name


def test_derive_names_missing_reference_files(tmp_path):
    from maniskill_tidy.knowledge.derive import derive

    with pytest.raises(FileNotFoundError, match="asset-database.json"):
        derive(tmp_path)


def test_the_maintainers_commands_write_the_shipped_tables_by_default():
    """derive-knowledge and derive-word-vectors without --out replace the package's tables
    (a default that pointed elsewhere would leave the shipped ones silently stale)."""
    from pathlib import Path

    import maniskill_tidy.knowledge
    from maniskill_tidy.cli.maintenance import KNOWLEDGE_DATA

    shipped = Path(maniskill_tidy.knowledge.__file__).resolve().parent / "data"
    assert KNOWLEDGE_DATA == shipped and (shipped / "word_vectors.json").is_file()
