import math

import pytest

from maniskill_tidy.cli import main
from maniskill_tidy.houses.generator import generate_house
from maniskill_tidy.houses.navgrid import components, grid_array
from maniskill_tidy.houses.schema import HouseFormatError, house_from_dict
from maniskill_tidy.knowledge import ROOM_TYPES
from maniskill_tidy.tasks.validate import check_house

SEEDS = [(s, i) for s in (0, 11) for i in range(20)]


@pytest.fixture(scope="module")
def houses():
    return [generate_house(s, i) for s, i in SEEDS]


def test_houses_are_valid_over_many_seeds(houses):
    """Reachability, no overlaps, grid consistent with geometry, every object reasonable."""
    for house in houses:
        assert check_house(house) == [], house.id


def test_house_sizes_and_rooms(houses):
    sizes = set()
    for house in houses:
        assert 1 <= len(house.rooms) <= 8
        assert {r.type for r in house.rooms} <= set(ROOM_TYPES)
        assert 15 <= len(house.objects) <= 40
        assert len(house.lights) >= len(house.rooms)
        free = grid_array(house.navgrid)
        assert components(free)[1] == 1
        for room in house.rooms:  # every room has floor an agent can stand on
            x0, y0, x1, y1 = room.bounds()
            r0, c0 = house.navgrid.cell_of(x0, y0)
            r1, c1 = house.navgrid.cell_of(x1 - 1e-6, y1 - 1e-6)
            assert free[r0 : r1 + 1, c0 : c1 + 1].any(), (house.id, room.id)
        sizes.add(len(house.rooms))
    assert len(sizes) >= 4  # the specs really vary


def test_multi_room_houses_have_doors_connecting_all_rooms(houses):
    for house in houses:
        if len(house.rooms) > 1:
            assert len(house.doors) >= len(house.rooms) - 1


def test_articulated_furniture_is_specified(houses):
    seen = {}
    for house in houses:
        for f in house.furniture:
            seen.setdefault(f.type, f)
    fridge, counter, dresser, microwave = (
        seen[t] for t in ("Fridge", "CounterTop", "Dresser", "Microwave")
    )
    for f in (fridge, counter, microwave):
        assert f.joints and all(
            j.type == "revolute" and j.axis == [0.0, 0.0, 1.0] for j in f.joints
        )
        assert all(0 < j.limits[1] <= math.pi for j in f.joints)
        assert any(s.inside for s in f.surfaces)
    assert {s.receptacle_type for s in counter.surfaces} == {"CounterTop", "Cabinet"}
    drawers = [j for j in dresser.joints if j.type == "prismatic"]
    assert len(drawers) >= 2 and all(j.axis == [0.0, 1.0, 0.0] for j in drawers)
    assert all(0 < j.limits[1] < dresser.size[1] for j in drawers)
    assert {s.link for s in dresser.surfaces if s.receptacle_type == "Drawer"} == {
        j.name for j in drawers
    }
    assert microwave.parent is not None  # stands on a counter


def test_same_seed_same_house_and_different_index_differs():
    a, b = generate_house(5, 3).to_dict(), generate_house(5, 3).to_dict()
    assert a == b
    assert generate_house(5, 4).to_dict() != a
    assert generate_house(6, 3).to_dict() != a


def test_schema_round_trip_and_clear_errors():
    d = generate_house(2, 0).to_dict()
    assert house_from_dict(d).to_dict() == d
    with pytest.raises(HouseFormatError, match="schema_version '0.1', expected '1.0'"):
        house_from_dict({**d, "schema_version": "0.1"})
    broken = {k: v for k, v in d.items() if k != "walls"}
    with pytest.raises(HouseFormatError, match="missing walls"):
        house_from_dict(broken)
    bad_furniture = {**d, "furniture": [{"id": "x"}]}
    with pytest.raises(HouseFormatError, match=r"furniture\[0\]"):
        house_from_dict(bad_furniture)


def test_check_house_catches_overlap_and_bad_grid():
    house = generate_house(0, 1)
    pieces = [f for f in house.furniture if f.parent is None and f.position[2] == 0.0]
    pieces[1].position = list(pieces[0].position)
    problems = check_house(house)
    assert any("overlap" in p for p in problems)
    assert any("navigation grid differs" in p for p in problems)


def test_show_house_draws_a_png(tmp_path):
    out = tmp_path / "house.png"
    assert main(["show-house", "--seed", "1", "--index", "2", "--out", str(out)]) == 0
    data = out.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000


def test_generation_makes_at_least_10_houses_per_second_on_2_cores():
    """The spec is 10 houses/s on 2 cores, i.e. 5 per core. Measured in this process's CPU
    time: wall time fails whenever other jobs share the cores (``make bench`` reports the
    wall-clock rate with 1 and 2 workers)."""
    import time

    generate_house(99, 0)  # imports and caches out of the measurement
    start = time.process_time()
    for i in range(1, 21):
        generate_house(99, i)
    per_core = 20 / (time.process_time() - start)
    assert 2 * per_core > 10, f"{2 * per_core:.1f} houses per second on 2 cores"
