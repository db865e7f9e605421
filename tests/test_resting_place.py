"""Where a detected object rests (``perception/detections.py: resting_place``): the surface
whose height its lowest point is near, over the surface's rectangle (a little beyond its edge
too), the floor below ON_FLOOR, nothing when it is between."""

from __future__ import annotations

import numpy as np
from test_object_space import room_with_a_table

from maniskill_tidy.knowledge import FLOOR
from maniskill_tidy.perception.detections import (
    EDGE,
    ON_FLOOR,
    ON_SURFACE,
    Detection,
    resting_place,
    surface_table,
    surfaces_under,
)


def _detection(x: float, y: float, bottom: float) -> Detection:
    return Detection(1, "Apple_0", "Apple", np.array([x, y, bottom + 0.04]), bottom, 400, 1.0)


def test_an_object_rests_on_the_surface_its_lowest_point_is_near_or_on_the_floor():
    house = room_with_a_table()
    surfaces = surface_table(house)
    (top,) = surfaces
    assert (top.furniture, top.surface) == ("DiningTable_0", "top")
    assert np.isclose(top.height, 0.75)
    # the table is turned 90 degrees: its top spans x 1.7-2.3, y 1.5-2.5
    assert np.allclose(top.bounds, (1.7, 1.5, 2.3, 2.5))
    on_top = resting_place(house, _detection(2.0, 1.8, 0.75 + ON_SURFACE / 2), surfaces)
    assert on_top == ("DiningTable_0", "top", "room_0")
    assert resting_place(house, _detection(2.0, 1.8, 0.75 - ON_SURFACE / 2), surfaces)[0]
    # a hand's width above the top, or below it: carried, or on nothing the plan knows
    assert resting_place(house, _detection(2.0, 1.8, 0.75 + ON_SURFACE * 1.5), surfaces) == (
        "", None, None)  # fmt: skip
    assert resting_place(house, _detection(2.0, 1.8, 0.5), surfaces) == ("", None, None)
    # low enough is the floor, wherever it is
    assert resting_place(house, _detection(3.5, 3.5, ON_FLOOR / 2), surfaces) == (
        FLOOR, None, "room_0")  # fmt: skip
    assert resting_place(house, _detection(3.5, 3.5, 0.75), surfaces) == ("", None, None)


def test_a_position_just_past_a_surfaces_edge_still_counts_as_over_it():
    surfaces = surface_table(room_with_a_table())
    assert surfaces_under(2.3 + EDGE * 0.8, 2.0, surfaces) == surfaces
    assert surfaces_under(2.0, 1.5 - EDGE * 0.8, surfaces) == surfaces
    assert surfaces_under(2.3 + EDGE * 1.2, 2.0, surfaces) == []
    assert surfaces_under(2.0, 2.5 + EDGE * 1.2, surfaces) == []
