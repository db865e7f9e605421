"""Frames for the pixels track's segmenter: the renderer's labels as classes and instances,
one shard per house, resumable, the same data from the same dataset."""

from __future__ import annotations

import json

import numpy as np
import pytest

from maniskill_tidy.perception.seg_classes import STRUCTURE, seg_classes
from maniskill_tidy.training.segmenter_data import TEAMS, SegDataConfig, build_segmenter_data


def test_the_class_table_covers_structure_furniture_and_every_pickupable_type():
    from maniskill_tidy.houses.furniture import TEMPLATES
    from maniskill_tidy.knowledge import load_catalog

    c = seg_classes()
    assert c.names[0] == "background" and c.names[1 : 1 + len(STRUCTURE)] == STRUCTURE
    assert set(c.pickupable) == set(load_catalog().pickupable)
    assert {f"furniture:{t}" for t in TEMPLATES} <= set(c.names)
    assert len(set(c.names)) == len(c.names) <= 255
    apple = c.of_instance("object", "Apple")
    assert c.is_pickupable(apple) and not c.is_pickupable(c.of_instance("furniture", "Sofa"))
    assert c.of_instance("ceiling", "Kitchen") == c.index["ceiling"]
    with pytest.raises(ValueError, match="instance kind 'lamp'"):
        c.of_instance("lamp", "x")


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    out = tmp_path_factory.mktemp("segdata") / "test"
    cfg = SegDataConfig(None, "test", "HeteroTidy-v1", every=6, max_steps=7, houses=1)
    return cfg, out, build_segmenter_data(cfg, out, progress=False)


def test_a_house_shard_holds_frames_with_consistent_labels(tiny):
    _, out, manifest = tiny
    shards = sorted(out.glob("house_*.npz"))
    assert len(shards) == 1 and manifest["houses_done"] == 1
    c = seg_classes()
    with np.load(shards[0]) as z:
        n = len(z["agent"])
        assert n == manifest["frames"] == len(TEAMS) * 2 * 3  # 2 kept steps, 3 agents
        assert z["rgb"].shape == (n, 224, 224, 3) and z["rgb"].dtype == np.uint8
        assert z["depth_mm"].dtype == np.uint16 and z["depth_mm"].max() > 500
        assert sorted(set(z["team"].tolist())) == [0, 1, 2]
        cls, inst = z["cls"], z["instance"]
        assert ((cls == 0) == (inst == 0)).all()  # background exactly where nothing is drawn
        owner: dict[int, set[int]] = {}
        for i in np.unique(inst[inst > 0]):
            owner[int(i)] = set(np.unique(cls[inst == i]).tolist())
        assert all(len(v) == 1 for v in owner.values())  # one class per instance
        seen = {next(iter(v)) for v in owner.values()}
        assert {c.index["floor"], c.index["wall"]} <= seen
        assert any(c.is_pickupable(k) for k in seen)  # some object is in some frame
        meta = json.loads(str(z["meta"]))
        assert set(meta["episodes"]) == set(TEAMS)
        assert len(meta["instance_ids"]) == len(owner)


def test_a_rerun_resumes_and_names_the_same_data(tiny, tmp_path):
    cfg, out, manifest = tiny
    again = build_segmenter_data(cfg, out, progress=False)  # nothing left to render
    assert again["data_hash"] == manifest["data_hash"]
    assert again["seconds"] == manifest["seconds"]
    with pytest.raises(ValueError):  # another config into the same folder is refused
        build_segmenter_data(SegDataConfig(None, "test", "HeteroTidy-v1", every=3, max_steps=7,
                                           houses=1), out, progress=False)  # fmt: skip


@pytest.mark.slow
def test_the_same_dataset_renders_the_same_frames(tiny, tmp_path):
    cfg, _, manifest = tiny
    assert build_segmenter_data(cfg, tmp_path / "b", progress=False)["data_hash"] == (
        manifest["data_hash"]
    )
