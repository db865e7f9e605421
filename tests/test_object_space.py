"""Objects as what the floor plan does not explain (``perception/object_space.py``): which world
points it leaves unexplained in a small house, the pixels of a frame it flags, and the masks
typed by the segmenter's votes."""

from __future__ import annotations

import numpy as np

from maniskill_tidy.houses.schema import Furniture, House, Room, Surface, Wall
from maniskill_tidy.perception.object_space import (
    OPEN_ABOVE,
    RISE,
    ObjectSpace,
    frame_objects,
    object_masks,
    unexplained,
)
from maniskill_tidy.perception.seg_classes import seg_classes


def room_with_a_table() -> House:
    """A 4 x 4 m room, a wall along x = 0, a 1 x 0.6 m table (top at 0.75 m) at (2, 2) turned
    90 degrees, and a 0.4 m box standing on the table's top at its +y end."""
    table = Furniture("DiningTable_0", "DiningTable", "room_0", [2.0, 2.0, 0.0], np.pi / 2,
                      [1.0, 0.6, 0.75], [Surface("top", "DiningTable", [0.0, 0.0, 0.75],
                                                 [1.0, 0.6])])  # fmt: skip
    box = Furniture("Microwave_0", "Microwave", "room_0", [2.0, 2.35, 0.75], 0.0,
                    [0.3, 0.3, 0.4], parent="DiningTable_0")  # fmt: skip
    return House("house", None, "procedural", [Room("room_0", "Kitchen", [[0, 0], [4, 0], [4, 4],
                 [0, 4]])], [Wall("wall_0", [0, 0], [0, 4], ["room_0"])], [], [],
                 [table, box], [])  # fmt: skip


def test_points_resting_on_a_surface_or_the_floor_are_unexplained_and_the_plan_is_not():
    space = ObjectSpace(room_with_a_table())
    points = {
        "on the table": (2.0, 1.8, 0.78),
        "on the table, under the rise": (2.0, 1.8, 0.75 + RISE / 2),
        "the table's top itself": (2.0, 1.8, 0.749),
        "on the table, too high": (2.0, 1.8, 0.75 + OPEN_ABOVE + 0.05),
        "in the box on the table": (2.0, 2.35, 0.9),
        "above the box": (2.0, 2.35, 1.2),
        "beside the table, on the floor": (1.0, 1.0, 0.05),
        "the table's leg": (2.25, 2.45, 0.3),
        "in the wall": (0.02, 2.0, 0.1),
        "on the floor outside the room": (5.0, 2.0, 0.05),
        "on the floor, flat": (1.0, 1.0, RISE / 2),
    }
    got = dict(zip(points, space.contains(np.array(list(points.values()))), strict=True))
    assert got == {
        "on the table": True,
        "on the table, under the rise": False,
        "the table's top itself": False,
        "on the table, too high": False,
        "in the box on the table": False,  # the box is a piece of the plan
        "above the box": True,  # an object could stand on it... within the table's open space
        "beside the table, on the floor": True,
        "the table's leg": False,
        "in the wall": False,
        "on the floor outside the room": False,
        "on the floor, flat": False,
    }


def camera_looking_down(height: float, at=(1.0, 1.0)):
    """A 40 x 40 px camera ``height`` metres above ``at``, looking straight down (+y of the
    image towards -y of the world): intrinsics and world-to-camera extrinsics."""
    K = np.array([[40.0, 0, 20], [0, 40.0, 20], [0, 0, 1]], np.float32)
    R = np.array([[1, 0, 0], [0, -1, 0], [0, 0, -1]], float)  # camera axes in the world
    E = np.eye(4)
    E[:3, :3] = R
    E[:3, 3] = -R @ np.array([at[0], at[1], height])
    return K, E.astype(np.float32)


def test_a_frame_of_the_floor_flags_the_pixels_of_what_stands_on_it():
    space = ObjectSpace(room_with_a_table())
    K, E = camera_looking_down(2.0)
    depth = np.full((40, 40), 2.0, np.float32)  # the floor
    depth[10:16, 20:30] = 1.9  # something 10 cm tall
    depth[30:34, 5:9] = 1.999  # a sheet of paper, 1 mm thick: under the rise
    free = unexplained(space, depth, K, E)
    expected = np.zeros((40, 40), bool)
    expected[10:16, 20:30] = True
    assert np.array_equal(free, expected)


def test_an_unexplained_part_is_typed_by_the_votes_its_pixels_carry():
    c = seg_classes()
    mug, cup, floor = c.index["Mug"], c.index["Cup"], c.index["floor"]
    pickupable = np.array([c.is_pickupable(i) and i > 0 for i in range(256)])
    depth = np.full((40, 40), 2.0, np.float32)
    free = np.zeros((40, 40), bool)
    free[10:16, 20:30] = True  # one part: 60 px, 15 cells of the 20 x 20 grid
    labels = np.full((20, 20), floor, np.uint8)
    margins = np.full((20, 20), 0.9, np.float32)
    labels[5:8, 10:13] = mug  # 9 of its 15 cells: mug
    labels[5:8, 13:15] = cup  # 6: cup, surer
    margins[5:8, 13:15] = 1.0
    (m,) = object_masks(free, depth, labels, margins, pickupable, min_pixels=20)
    assert m.cls == mug and np.array_equal(m.mask, free)
    assert np.isclose(m.score, 1.0 * (9 * 0.9) / (9 * 0.9 + 6 * 1.0))
    labels[5:8, 10:15] = floor  # no pickupable vote: not an object mask
    assert object_masks(free, depth, labels, margins, pickupable, min_pixels=20) == []


def test_a_flat_object_the_plan_explains_keeps_the_segmenters_mask_and_no_two_overlap():
    from maniskill_tidy.perception.instances import Mask2D

    c = seg_classes()
    cd, mug = c.index["CD"], c.index["Mug"]
    pickupable = np.array([c.is_pickupable(i) and i > 0 for i in range(256)])
    depth = np.full((40, 40), 2.0, np.float32)
    free = np.zeros((40, 40), bool)
    free[10:16, 20:30] = True
    labels = np.zeros((20, 20), np.uint8)
    labels[5:8, 10:15] = mug
    margins = np.full((20, 20), 0.9, np.float32)

    def grid_mask(cls, rows, cols, score):
        m = np.zeros((20, 20), bool)
        m[rows, cols] = True
        return Mask2D(cls, m, score, (rows, cols))

    # the CD's mask lies on explained pixels; the mug's is the unexplained part's own
    masks = [grid_mask(cd, slice(15, 19), slice(2, 6), 0.85),
             grid_mask(mug, slice(5, 8), slice(10, 15), 0.9)]  # fmt: skip
    found, starts = frame_objects(masks, free, depth, labels, margins, pickupable, keep=0.6,
                                  start=0.8, plan_keep=0.3, plan_start=0.45, covered=0.5,
                                  min_pixels=20)  # fmt: skip
    assert [(m.cls, s) for m, s in zip(found, starts, strict=True)] == [(mug, 0.45), (cd, 0.8)]
    assert not (found[0].mask & found[1].mask).any()
    assert found[1].mask[30:38, 4:12].all() and found[1].mask.sum() == 64
