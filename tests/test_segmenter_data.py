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
    """On one machine, in this process as in a worker process: the same bytes (frames made on
    another machine may differ; rescoring reads them with a warning)."""
    cfg, _, manifest = tiny
    again = build_segmenter_data(cfg, tmp_path / "b", workers=2, progress=False)
    assert again["data_hash"] == manifest["data_hash"]


def test_instances_are_the_components_of_a_pixel_graph():
    """The one-pass labelling against scipy's graph components: 4-neighbours of one asked-for
    class joined unless the depth jumps, on random labels and depths; scores are mean
    probabilities, instances come ordered by class."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from maniskill_tidy.perception.instances import DEPTH_JUMP, split_instances

    rng = np.random.default_rng(3)
    for _ in range(5):
        labels = rng.integers(0, 4, (30, 40)).astype(np.uint8)
        labels[rng.random(labels.shape) < 0.5] = 2  # large parts of class 2
        depth = rng.choice([1.0, 1.02, 2.0, 3.5], labels.shape).astype(np.float32)
        prob = rng.random(labels.shape).astype(np.float32)
        asked = [1, 2]
        h, w = labels.shape
        idx = np.arange(h * w).reshape(h, w)
        a, b = [], []
        for x, y in ((idx[:, :-1], idx[:, 1:]), (idx[:-1], idx[1:])):
            la, lb = labels.ravel()[x], labels.ravel()[y]
            da, db = depth.ravel()[x], depth.ravel()[y]
            ok = (la == lb) & np.isin(la, asked)
            ok &= np.abs(da - db) <= DEPTH_JUMP + 0.05 * np.minimum(da, db)
            a.append(x[ok]), b.append(y[ok])
        graph = coo_matrix((np.ones(sum(len(v) for v in a)), (np.concatenate(a),
                            np.concatenate(b))), shape=(h * w, h * w))  # fmt: skip
        _, comp = connected_components(graph, directed=False)
        comp = comp.reshape(h, w)
        want = set()
        for c in np.unique(comp[np.isin(labels, asked)]):
            m = (comp == c) & np.isin(labels, asked)
            if m.sum() >= 3:
                want.add((int(labels[m][0]), m.tobytes(), round(float(prob[m].mean()), 5)))
        got = split_instances(labels, depth, asked, prob, min_pixels=3)
        assert {(g.cls, g.mask.tobytes(), round(g.score, 5)) for g in got} == want
        assert [g.cls for g in got] == sorted(g.cls for g in got) and len(got) == len(want)
        assert all(g.mask[g.window].sum() == g.mask.sum() for g in got)


def test_a_mask_in_front_of_its_surroundings_keeps_its_score_a_flat_patch_loses_half():
    from maniskill_tidy.perception.instances import Mask2D, depth_contrast, scored_by_relief

    depth = np.full((30, 30), 2.0, dtype=np.float32)
    depth[5:10, 5:10] = 1.9  # a box standing 10 cm proud of the floor behind it
    depth[14:17, 5:12] = 1.996  # a credit card, 4 mm thick
    box, card = np.zeros((30, 30), dtype=bool), np.zeros((30, 30), dtype=bool)
    box[5:10, 5:10] = card[14:17, 5:12] = True
    patch = np.zeros((30, 30), dtype=bool)
    patch[20:25, 20:25] = True  # floor texture taken for an object
    assert depth_contrast(Mask2D(7, box, 0.9), depth) == pytest.approx(0.1)
    assert depth_contrast(Mask2D(7, patch, 0.9, (slice(20, 25), slice(20, 25))), depth) == 0
    a, b, c, d = scored_by_relief([Mask2D(7, box, 0.9), Mask2D(7, patch, 0.9),
                                   Mask2D(3, patch, 0.9), Mask2D(7, card, 0.9)],
                                  depth, [7])  # fmt: skip
    assert a.score == pytest.approx(0.9, abs=1e-3) and b.score == pytest.approx(0.45)
    assert c.score == 0.9  # not an object class: untouched
    assert d.score > 0.78  # a thin one above the agents' threshold (the 1 cm contrast: 0.54)
    whole = Mask2D(7, np.ones((30, 30), dtype=bool), 0.9)  # no ring, no plane: no contrast
    assert scored_by_relief([whole], depth, [7])[0].score == pytest.approx(0.45)


def test_depth_contrast_rings_a_mask_as_a_scipy_dilation_does_at_the_frame_borders_too():
    from scipy import ndimage

    from maniskill_tidy.perception.instances import Mask2D, depth_contrast

    rng = np.random.default_rng(3)
    for _ in range(200):
        h, w = rng.integers(4, 30, 2)
        mask = np.zeros((h, w), dtype=bool)
        r0, c0 = rng.integers(0, h), rng.integers(0, w)
        r1, c1 = rng.integers(r0, h + 1), rng.integers(c0, w + 1)
        mask[r0:r1, c0:c1] = rng.random((r1 - r0, c1 - c0)) < 0.7
        depth = (rng.random((h, w)) * 3).astype(np.float32)
        around = ndimage.binary_dilation(mask, iterations=2) & ~mask
        want = (
            np.median(depth[around]) - np.median(depth[mask]) if around.any() and mask.any() else 0
        )
        box = (slice(r0, r1), slice(c0, c1))
        for m in (Mask2D(1, mask, 1.0), Mask2D(1, mask, 1.0, box)):
            assert depth_contrast(m, depth) == pytest.approx(float(want), abs=1e-6)


def test_refined_masks_follow_the_depth_silhouette_not_the_grid():
    """Labels on a grid of 2 x 2 pixel cells (each cell's depth read at its first pixel) miss
    an object's first row and column and spill one past its last; with depth's guidance its
    mask at full resolution is the object's own pixels, and a mask on a flat background keeps
    its cells."""
    from maniskill_tidy.perception.instances import Mask2D, coarse, refined

    depth = np.full((24, 24), 2.0, np.float32)
    depth[5:13, 7:15] = 1.0  # the object: rows 5..12, columns 7..14
    cells = coarse(depth, 2) < 1.5  # what a right segmenter labels: cell rows 3..6, cols 4..7
    other = np.zeros((12, 12), bool)
    other[9:11, 1:3] = True
    masks = [Mask2D(70, cells, 0.9, (slice(3, 7), slice(4, 8))), Mask2D(71, other, 0.8)]
    silhouette = depth < 1.5
    assert (masks[0].upscaled(2).mask != silhouette).sum() == 30  # rows 5, 13; columns 7, 15
    obj, flat = refined(masks, depth, 2)
    assert np.array_equal(obj.mask, silhouette) and (obj.cls, obj.score) == (70, 0.9)
    assert obj.mask[obj.window].sum() == obj.mask.sum()  # its box holds it
    assert np.array_equal(coarse(obj.mask, 2), cells)  # each cell's own pixel stays its own
    with pytest.raises(ValueError, match="expected the grid of a"):
        refined(masks, depth[:20], 2)
    assert np.array_equal(flat.mask, other.repeat(2, axis=0).repeat(2, axis=1))
    kept = refined(masks, depth, 2, min_pixels=20)  # the 16-pixel one left out
    assert len(kept) == 1 and np.array_equal(kept[0].mask, silhouette)


def test_plane_relief_reads_a_cards_thickness_on_a_slanted_table_and_a_texture_as_none():
    from maniskill_tidy.perception.instances import Mask2D, depth_contrast, plane_relief

    # a table seen at a slant through a pinhole camera: its inverse depth is affine in the
    # pixel's row and column
    rows, cols = np.mgrid[0:40, 0:40]
    table = (1.0 / (0.25 + 0.012 * rows + 0.003 * cols)).astype(np.float32)
    edge = np.zeros((40, 40), dtype=bool)
    edge[34:, 8:16] = True  # at the frame's bottom: a ring above it only, farther off
    assert depth_contrast(Mask2D(7, edge, 1.0), table) > 0.01  # a texture in relief
    assert plane_relief(Mask2D(7, edge, 1.0), table) == pytest.approx(0, abs=1e-5)
    patch = np.zeros((40, 40), dtype=bool)
    patch[12:30, 8:16] = True
    texture = Mask2D(7, patch, 1.0)
    assert plane_relief(texture, table) == pytest.approx(0, abs=1e-5)
    card = table.copy()
    card[patch] -= 0.004  # 4 mm proud of the table along the optical axis
    assert plane_relief(texture, card) == pytest.approx(0.004, abs=1e-4)
    # the floor 70 cm below the table's edge in a sixth of the ring: trimmed off the plane
    floor = card.copy()
    floor[30:, :] += 0.7
    assert plane_relief(texture, floor) == pytest.approx(0.004, abs=1e-4)
    # a kettle between a counter (below) and the wall behind (above): the ring lies on two
    # surfaces, no plane fits most of it; its relief is then the median contrast, positive
    from maniskill_tidy.perception.instances import relief

    kitchen = np.where(rows < 21, 2.0, 1.5 + 0.01 * rows).astype(np.float32)
    kettle = np.zeros((40, 40), dtype=bool)
    kettle[12:30, 15:25] = True
    kitchen[kettle] = 1.35
    assert np.isnan(plane_relief(Mask2D(7, kettle, 1.0), kitchen))
    assert relief(Mask2D(7, kettle, 1.0), kitchen) > 0.1
    # under three ring pixels: no plane
    whole = Mask2D(7, np.ones((40, 40), dtype=bool), 1.0)
    assert np.isnan(plane_relief(whole, table))


def test_instances_split_at_depth_jumps_and_score_a_perfect_prediction_at_ap_one(tiny):
    from maniskill_tidy.eval.mask_ap import mask_ap
    from maniskill_tidy.perception.instances import Mask2D, split_instances

    # two boxes of one class side by side, one 1 m behind the other: two instances
    labels = np.zeros((40, 40), dtype=np.uint8)
    labels[10:20, 5:20] = labels[10:20, 20:35] = 7
    depth = np.full((40, 40), 3.0, dtype=np.float32)
    depth[10:20, 5:20], depth[10:20, 20:35] = 1.0, 2.0
    parts = split_instances(labels, depth, [7])
    assert sorted(p.area for p in parts) == [150, 150] and {p.cls for p in parts} == {7}
    # below min_pixels: left out; a class not asked for: no instance
    assert split_instances(labels, depth, [7], min_pixels=151) == []
    assert split_instances(labels, depth, [3]) == []
    assert all(p.mask[p.window].any() and not p.mask[:, :5].any() for p in parts)
    depth[10:20, 20:35] = 1.02  # the same surface: one instance
    assert [p.area for p in split_instances(labels, depth, [7])] == [300]

    _, out, _ = tiny
    c = seg_classes()
    pickupable = [i for i in range(len(c.names)) if c.is_pickupable(i)]
    with np.load(sorted(out.glob("house_*.npz"))[0]) as z:
        truth = []
        for inst, cls in zip(z["instance"], z["cls"], strict=True):
            truth.append([Mask2D(int(cls[inst == i][0]), inst == i, 1.0)
                          for i in np.unique(inst[inst > 0])])  # fmt: skip
    frames = [(t, t) for t in truth]
    perfect = mask_ap(frames, pickupable, (224, 224))
    assert perfect["truth"] > 0 and perfect["AP"] == perfect["AP50"] == 1.0
    # every prediction given the wrong class: nothing matches
    wrong = [(t, [Mask2D(pickupable[(pickupable.index(m.cls) + 1) % len(pickupable)]
                         if m.cls in pickupable else m.cls, m.mask, 1.0) for m in t])
             for t in truth]  # fmt: skip
    assert mask_ap(wrong, pickupable, (224, 224))["AP50"] == 0.0
    # half of the instances missed: recall, and so AP, falls
    half = [(t, t[::2]) for t in truth]
    assert 0.0 < mask_ap(half, pickupable, (224, 224))["AP50"] < 1.0
    # objects under 20 pixels missed: ignored when asked (an agent could not act on them)
    big = [(t, [m for m in t if m.area >= 20]) for t in truth]
    missed = mask_ap(big, pickupable, (224, 224))
    tiny_ones = sum(m.area < 20 for t in truth for m in t if m.cls in pickupable)
    assert tiny_ones > 0 and missed["AP50"] < 1.0
    ignored = mask_ap(big, pickupable, (224, 224), ignore_below=20)
    assert ignored["AP50"] == 1.0 and ignored["ignored"] == tiny_ones
    assert ignored["truth"] == missed["truth"] - tiny_ones
    # where agents draw the line: wrong-type copies at a low score fall under it
    from maniskill_tidy.eval.mask_ap import score_threshold

    noisy = [(t, [Mask2D(m.cls, m.mask, 0.9) for m in t] + [Mask2D(w.cls, w.mask, 0.2)
                                                            for w in wt])
             for t, (_, wt) in zip(truth, wrong, strict=True)]  # fmt: skip
    line = score_threshold(noisy, pickupable, (224, 224), ignore_below=20)
    assert line["threshold"] == 0.9 and line["f1"] == 1.0 and line["precision"] == 1.0
    assert 0.0 < mask_ap(noisy, pickupable, (224, 224), ignore_below=20)["AP50"] <= 1.0


def test_the_best_f1_threshold_keeps_masks_of_one_score_together():
    """A threshold cannot keep one of two masks with the same score: the F1 is of all of them,
    whichever order they come in."""
    from maniskill_tidy.eval.mask_ap import best_f1

    scores, hits = np.array([0.5, 0.5, 0.5, 0.5, 0.2]), np.array([True, False, False, False, False])
    line = best_f1(scores, hits, 2)
    assert line["threshold"] == 0.5 and line["precision"] == 0.25 and line["recall"] == 0.5
    assert best_f1(scores, hits[[3, 1, 2, 0, 4]], 2) == line
    assert best_f1(np.array([0.9, 0.5]), np.array([True, False]), 1)["f1"] == 1.0


def test_the_segmenter_gives_class_logits_at_half_resolution_and_learns():
    import torch

    from maniskill_tidy.models.segmenter import Segmenter

    torch.manual_seed(0)
    model = Segmenter(5, widths=(8, 8, 16, 16, 16))
    rgb, depth = torch.rand(2, 3, 64, 64) * 255, torch.rand(2, 1, 64, 64) * 4
    assert model(rgb, depth).shape == (2, 5, 32, 32)
    target = (depth[:, 0, ::2, ::2] > 2).long()  # near vs far: learnable from depth alone
    opt = torch.optim.Adam(model.parameters(), 1e-2)
    losses = []
    for _ in range(30):
        loss = torch.nn.functional.cross_entropy(model(rgb, depth), target)
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(loss.item())
    assert losses[-1] < 0.5 * losses[0]
