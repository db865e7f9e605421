"""How a pixels agent turns a segmenter's object masks into what its team sees, on synthetic
frames: an object is shown once seen twice with confidence, kept by less confident sightings,
a PickUp of one out of view aims at the same object seen as another track, and a PickUp whose
pixel showed no object (or that failed twice at a pixel of the frame, not for the distance), or
a spot in clear view within reach where it was missed more often than seen, hides that track
from then on; targets are pixels the labels were made at (a PutDown's, where its surface
projects), and furniture of one type side by side keeps its own pixels."""

from __future__ import annotations

from types import SimpleNamespace as NS

import numpy as np
import pytest

from maniskill_tidy.envs.actions import NOTHING_DRAWN, Action, Targeted
from maniskill_tidy.perception.seg_classes import seg_classes
from maniskill_tidy.policies.base import AgentView, PublicInfo
from maniskill_tidy.policies.pixels import (
    CONFIRM,
    KEEP_THRESHOLD,
    MISSES,
    OBJECT_BASE,
    VERIFY_RANGE,
    PixelsAgent,
)

H = 40  # frame size; the fake segmenter's labels are on a 20 x 20 grid


class FakeSegmenter:
    """Gives the labels and confidences a test sets, as the shared segmenter would."""

    threshold = 0.8

    def __init__(self) -> None:
        self.seconds = {"segmenter": 0.0, "instances": 0.0, "labels": 0.0}
        self.labels = np.zeros((H // 2, H // 2), dtype=np.uint8)
        self.probs = np.ones((H // 2, H // 2), dtype=np.float32)
        self.depth = np.full((H, H), 2.0, np.float32)  # what the frames show: objects nearer

    def show(self, cls: int, rows: slice, cols: slice, score: float, depth: float = 1.8) -> None:
        self.labels[rows, cols], self.probs[rows, cols] = cls, score
        self.depth[rows.start * 2 : rows.stop * 2, cols.start * 2 : cols.stop * 2] = depth

    def clear(self) -> None:
        self.labels[:] = 0

    def __call__(self, name, rgb, depth):
        return self.labels.copy(), self.probs.copy()


class Inner:
    """A team's agent that remembers what it was shown and does what the test says."""

    decide_every = 1

    def __init__(self, name, public, outbox) -> None:
        self.public, self.action, self.seen = public, Action.RotateLeft, None

    def observe(self, view) -> None:
        self.seen = view.obs["segmentation"]

    def act(self, inbox):
        return self.action

    def forget(self, object_id: str) -> None:  # as HeuristicAgent.forget
        self.forgotten = [*getattr(self, "forgotten", []), object_id]


@pytest.fixture
def agent():
    house = NS(furniture=[], rooms=[], walls=[], furniture_by_id=lambda: {})
    public = PublicInfo(house, ["agent_0"], [], "episode", 0)
    return PixelsAgent(Inner, "agent_0", public, None, FakeSegmenter())


def view(agent, step: int, failed: str = "") -> AgentView:
    K = np.array([[40.0, 0, 20], [0, 40.0, 20], [0, 0, 1]], dtype=np.float32)
    obs = {"rgb": np.zeros((H, H, 3), np.uint8), "depth": agent.segmenter.depth.copy(),
           "intrinsics": K, "extrinsics": np.eye(4, dtype=np.float32),
           "held": np.int32(0)}  # fmt: skip
    return AgentView("agent_0", step, obs, failed)


def shown(agent) -> set[int]:
    return {int(i) for i in np.unique(agent.inner.seen) if i >= OBJECT_BASE}


def depth_of(agent, sid: int) -> float:
    """How far in front of the camera (the world's +z here) the track shown as ``sid`` lies."""
    (track,) = agent.table.tracks_of(sid)
    return float(agent.tracker.tracks[track].position[2])


def confirmed_mug(agent) -> tuple[int, int]:
    """A mug drawn sure in two frames (steps 0 and 1): its class and the slot it is shown as."""
    mug = seg_classes().index["Mug"]
    agent.segmenter.show(mug, slice(8, 12), slice(8, 12), 0.9)
    agent.observe(view(agent, 0))
    agent.observe(view(agent, 1))
    (slot,) = shown(agent)
    return mug, slot


def test_an_object_is_shown_once_confirmed_and_kept_by_weaker_sightings(agent):
    mug, seg = seg_classes().index["Mug"], agent.segmenter
    seg.show(mug, slice(8, 12), slice(8, 12), 0.9)
    agent.observe(view(agent, 0))
    assert CONFIRM == 2 and shown(agent) == set()  # one sighting: not yet
    agent.observe(view(agent, 1))
    (slot,) = shown(agent)
    seg.show(mug, slice(8, 12), slice(8, 12), KEEP_THRESHOLD + 0.05)  # less sure: still kept
    seg.show(mug, slice(2, 5), slice(14, 18), KEEP_THRESHOLD + 0.05)  # a new one that unsure: no
    agent.observe(view(agent, 2))
    agent.observe(view(agent, 3))
    assert shown(agent) == {slot} and len(agent.tracker.tracks) == 1
    seg.show(mug, slice(8, 12), slice(8, 12), KEEP_THRESHOLD - 0.05)  # too unsure to keep it
    agent.observe(view(agent, 4))
    assert slot not in shown(agent)


def test_a_pickup_aims_at_the_object_its_team_named_and_a_refuted_one_is_hidden(agent):
    _, slot = confirmed_mug(agent)
    name = agent.table.instances[slot].id
    agent.inner.action = Targeted(Action.PickUp, name)
    action = agent.act([])
    x, y = action.target
    assert action.action == Action.PickUp and 16 <= x < 24 and 16 <= y < 24
    # a pixel of its mask refined to the frame's pixels, off the rim (a rim pixel may show what
    # lies beside the object), nearest its middle
    inside = [agent.seg[y + dy, x + dx] == slot for dy, dx in ((0, 0), (0, 1), (1, 0), (0, -1),
                                                               (-1, 0))]  # fmt: skip
    assert all(inside) and 18 <= x <= 21 and 18 <= y <= 21
    # the env found no object at that pixel: a false detection, hidden from now on
    agent.observe(view(agent, 2, f"PickUp at pixel {(x, y)}: no object {NOTHING_DRAWN}"))
    assert slot not in shown(agent)
    assert agent.inner.forgotten == [name]  # its team is told once: it stops fetching it
    agent.observe(view(agent, 3))
    assert shown(agent) == set() and agent.tracker.tracks  # still tracked, never shown
    assert agent.inner.forgotten == [name]


def test_a_pickup_out_of_view_takes_the_same_object_seen_as_another_track(agent):
    _, slot = confirmed_mug(agent)
    agent.tracker.tracks[1].position = agent.tracker.tracks[1].position + [0.0, 0.0, 0.4]
    agent.tracker.radius = 0.1  # so that this frame's sightings start another track ...
    for step in (2, 3):
        agent.observe(view(agent, step))
    (other,) = shown(agent)
    assert other != slot  # ... shown under another slot, 0.4 m from where the first one lies
    agent.inner.action = Targeted(Action.PickUp, agent.table.instances[slot].id)
    action = agent.act([])
    assert action.target != (-1, -1) and agent.aimed == other
    # failing at a pixel of the frame twice refutes the track it aimed at; failing for the
    # distance, or with no pixel to aim at (the object out of view), says nothing of it
    agent.segmenter.clear()  # from here the segmenter misses it (too far to verify)
    agent.observe(view(agent, 4, f"PickUp at pixel {action.target}: an object is out of reach "
                                 "(2.10 m > 1.50 m)"))  # fmt: skip
    assert agent.refuted == set()
    agent.inner.action = Targeted(Action.PickUp, agent.table.instances[other].id)
    out_of_view = "PickUp at pixel (-1, -1): outside the 40 x 40 frame"
    for step in (5, 6):
        assert agent.act([]).target == (-1, -1) and agent.aimed == other
        agent.observe(view(agent, step, out_of_view))
    assert agent.refuted == set()
    agent.segmenter.show(seg_classes().index["Mug"], slice(8, 12), slice(8, 12), 0.9)
    agent.observe(view(agent, 7))
    assert shown(agent) == {other}
    for step in (8, 9):
        pixel = agent.act([]).target
        assert pixel != (-1, -1)
        agent.observe(view(agent, step, f"PickUp at pixel {pixel}: an object is not visible"))
    assert agent.refuted == {2}


def test_a_track_missed_in_clear_view_within_reach_more_often_than_seen_is_hidden(agent):
    mug, seg = seg_classes().index["Mug"], agent.segmenter
    seg.show(mug, slice(8, 12), slice(8, 12), 0.9, depth=1.0)  # within reach
    seg.show(mug, slice(2, 5), slice(14, 18), 0.9, depth=1.8)  # beyond it
    assert 1.0 < VERIFY_RANGE < 1.8 and MISSES == 2
    for step in (0, 1):
        agent.observe(view(agent, step))
    near, far = sorted(shown(agent), key=lambda sid: depth_of(agent, sid))
    seg.clear()  # the segmenter no longer sees either, though the depth shows both still
    for step in (2, 3):  # missed twice where it was seen twice: not yet
        agent.observe(view(agent, step))
    assert agent.refuted == set()
    agent.observe(view(agent, 4))
    (ghost,) = agent.refuted
    seg.show(mug, slice(8, 12), slice(8, 12), 0.9, depth=1.0)
    seg.show(mug, slice(2, 5), slice(14, 18), 0.9, depth=1.8)
    agent.observe(view(agent, 5))
    assert shown(agent) == {far}  # the one out of reach was never looked at closely enough
    assert agent.table.tracks_of(near) == [ghost]


def test_a_pickup_of_an_object_missed_this_frame_aims_where_its_track_lies_within_reach(agent):
    mug, seg = seg_classes().index["Mug"], agent.segmenter
    seg.show(mug, slice(8, 12), slice(8, 12), 0.9, depth=1.0)
    for step in (0, 1):
        agent.observe(view(agent, step))
    (slot,) = shown(agent)
    seg.clear()  # missed once: still believed, not shown this frame
    agent.observe(view(agent, 2))
    assert shown(agent) == set() and agent.refuted == set()
    agent.inner.action = Targeted(Action.PickUp, agent.table.instances[slot].id)
    x, y = agent.act([]).target
    assert 16 <= x < 24 and 16 <= y < 24  # the spot the depth still shows
    agent.observe(view(agent, 3, f"PickUp at pixel {(x, y)}: no object {NOTHING_DRAWN}"))
    assert agent.refuted == {1}
    assert agent.act([]).target == (-1, -1)  # refuted: no longer recalled


def test_two_pieces_of_one_type_side_by_side_keep_their_own_pixels():
    """One furniture mask over two counters: each cell is named by the piece under its point,
    so that a PutDown on either finds it in view."""

    class Piece(NS):
        def footprint(self):
            return self.box

    left = Piece(id="CounterTop_0", type="CounterTop", box=(-3.0, -3.0, 0.0, 3.0))
    right = Piece(id="CounterTop_1", type="CounterTop", box=(0.0, -3.0, 3.0, 3.0))
    house = NS(furniture=[left, right], rooms=[], walls=[], furniture_by_id=lambda: {})
    agent = PixelsAgent(Inner, "agent_0", PublicInfo(house, ["agent_0"], [], "episode", 0),
                        None, FakeSegmenter())  # fmt: skip
    counter = seg_classes().index["furniture:CounterTop"]
    agent.segmenter.show(counter, slice(4, 16), slice(2, 18), 0.9, depth=2.0)
    agent.observe(view(agent, 0))
    seen = agent.inner.seen  # camera at the origin: world x is the image's columns' way
    ids = {p.id: agent.table.furniture[p.id] for p in (left, right)}
    assert set(np.unique(seen[8:32, 4:18])) == {ids["CounterTop_0"]}
    assert set(np.unique(seen[8:32, 22:36])) == {ids["CounterTop_1"]}


def test_a_putdown_aims_where_the_named_surface_of_the_piece_projects():
    """The env tries a piece's surfaces whose centre projects nearest the pixel first: a
    PutDown on one surface aims at the piece's mask pixel nearest where that surface's world
    centre (the floor plan's, not its piece-local one) projects."""

    class Piece(NS):
        def footprint(self):
            return (-3.0, -3.0, 3.0, 3.0)

        def surface(self, name):
            return next(s for s in self.surfaces if s.name == name)

        def surface_world(self, s):  # yaw 0: the piece's position plus the local centre
            return [p + c for p, c in zip(self.position, s.center, strict=True)], None

    shelves = Piece(id="Shelf_0", type="ShelvingUnit", position=(0.3, 0.3, 0.0),
                    surfaces=[NS(name="top", center=(-0.8, -0.8, 2.0)),
                              NS(name="shelf_0", center=(0.2, 0.2, 2.0))])  # fmt: skip
    house = NS(furniture=[shelves], rooms=[], walls=[],
               furniture_by_id=lambda: {"Shelf_0": shelves})  # fmt: skip
    agent = PixelsAgent(Inner, "agent_0", PublicInfo(house, ["agent_0"], [], "episode", 0),
                        None, FakeSegmenter())  # fmt: skip
    unit = seg_classes().index["furniture:ShelvingUnit"]
    agent.segmenter.show(unit, slice(2, 18), slice(2, 18), 0.9, depth=2.0)
    agent.observe(view(agent, 0))
    # camera at the origin looking along +z: world (-0.5, -0.5, 2) projects to about (10, 10),
    # (0.5, 0.5, 2) to about (30, 30); the local centres would give the mask's corner
    for surface, want in (("top", 10), ("shelf_0", 30)):
        agent.inner.action = Targeted(Action.PutDown, f"Shelf_0/{surface}")
        x, y = agent.act([]).target
        assert abs(x - want) <= 2 and abs(y - want) <= 2, (surface, x, y)
