"""The pixels track's segmenter trains on a tiny render, writes its card, fp16 weights and the
int8 graph agents run, resumes after a kill to the same result, loads back as it was selected,
and runs the same through ONNX Runtime."""

from __future__ import annotations

import json

import numpy as np
import pytest

from maniskill_tidy.training.segmenter_data import SegDataConfig, build_segmenter_data


@pytest.fixture(scope="module")
def tiny_data(tmp_path_factory):
    root = tmp_path_factory.mktemp("segtrain")
    for split in ("train", "val", "test"):
        cfg = SegDataConfig(None, split, "HeteroTidy-v1", every=3, max_steps=7, houses=1)
        build_segmenter_data(cfg, root / split, progress=False)
    return root


def _cfg(data, out, **kw):
    from maniskill_tidy.training.segmenter_trainer import SegTrainConfig

    # a few steps: a high rate, so that the loss can fall in them
    kw = {"lr": 0.01, "epochs": 3, "widths": (8, 8, 16, 16, 16), **kw}
    return SegTrainConfig(str(data), str(out), batch=4, crop=64, **kw)


def test_a_tiny_segmenter_trains_resumes_and_loads(tiny_data, tmp_path, monkeypatch):
    from maniskill_tidy.models.checkpoints import load_segmenter
    from maniskill_tidy.models.segmenter import predict
    from maniskill_tidy.training import segmenter_trainer as st

    card = st.train_segmenter(_cfg(tiny_data, tmp_path / "a"), progress=False)
    assert card["look"] == "HeteroTidy-v1" and len(card["curve"]) == 3
    assert card["frames"] == {"train": 27, "val": 27, "test": 27}  # 3 teams x 3 steps x 3 agents
    for key in ("AP", "AP50", "AP_small", "pixel_accuracy_pickupable", "truth", "predicted"):
        assert key in card["test"], key
    assert set(card["agent_threshold"]) == {"threshold", "f1", "precision", "recall"}
    assert card["test"]["truth"] > 0 and card["train_seconds"] > 0
    assert card["curve"][-1]["train_loss"] < card["curve"][0]["train_loss"]
    saved = json.loads((tmp_path / "a" / "card.json").read_text())
    assert saved["weights_sha256"] == card["weights_sha256"]
    assert (tmp_path / "a" / "curve.png").is_file()
    assert not (tmp_path / "a" / "checkpoint.pt").exists()

    # killed during the second epoch's validation, then run again: the same card
    calls = {"n": 0}
    real = st.evaluate

    def dies_second(model, frames):
        calls["n"] += 1
        if calls["n"] == 2:
            raise KeyboardInterrupt
        return real(model, frames)

    monkeypatch.setattr(st, "evaluate", dies_second)
    with pytest.raises(KeyboardInterrupt):
        st.train_segmenter(_cfg(tiny_data, tmp_path / "b"), progress=False)
    assert (tmp_path / "b" / "checkpoint.pt").is_file()
    monkeypatch.setattr(st, "evaluate", real)
    with pytest.raises(ValueError, match="another configuration"):  # not resumed with other
        st.train_segmenter(_cfg(tiny_data, tmp_path / "b", lr=1e-3), progress=False)
    resumed = st.train_segmenter(_cfg(tiny_data, tmp_path / "b"), progress=False)
    assert resumed["curve"] == card["curve"] and resumed["test"] == card["test"]
    assert resumed["weights_sha256"] == card["weights_sha256"]
    assert resumed["int8"]["sha256"] == card["int8"]["sha256"]  # the same calibration, graph

    model, card_back = load_segmenter(tmp_path / "a")
    assert card_back["weights_sha256"] == card["weights_sha256"]  # the card comes with it
    with np.load(sorted((tiny_data / "test").glob("*.npz"))[0]) as z:
        labels, probs = predict(model, z["rgb"][:2], z["depth_mm"][:2] / 1000.0)
    assert labels.shape == (2, 112, 112) and labels.dtype == np.uint8  # the network's grid
    assert ((0.5 <= probs) & (probs <= 1)).all()  # the sigmoid of a non-negative margin
    # agents run the same weights through ONNX Runtime: the same labels, up to float rounding
    from maniskill_tidy.models.segmenter import Runtime

    with np.load(sorted((tiny_data / "test").glob("*.npz"))[0]) as z:
        z_rgb, z_depth = z["rgb"][:2], z["depth_mm"][:2] / 1000.0
    ort_labels, ort_probs = Runtime(model)(z_rgb, z_depth)
    assert ort_labels.shape == labels.shape and ort_labels.dtype == np.uint8
    assert (ort_labels == labels).mean() > 0.995
    assert np.abs(ort_probs - probs)[ort_labels == labels].max() < 1e-3
    # the agents' frames in one batch: each frame's labels are those it gets alone
    alone = [Runtime(model)(z_rgb[i : i + 1], z_depth[i : i + 1])[0][0] for i in range(2)]
    assert all((ort_labels[i] == alone[i]).all() for i in range(2))

    # agents run the int8 graph the card names, and the card scores it; the fp16 weights'
    # own scores stay beside
    from maniskill_tidy.common.files import file_sha256
    from maniskill_tidy.models.checkpoints import CheckpointError, served_segmenter, served_sha256

    graph = tmp_path / "a" / "model.int8.onnx"
    assert card["int8"]["sha256"] == file_sha256(graph) == served_sha256(tmp_path / "a")
    assert card["int8"]["fp16_torch"]["test"]["truth"] == card["test"]["truth"]
    runtime, sha, _ = served_segmenter(tmp_path / "a")
    int8_labels, int8_probs = runtime(z_rgb, z_depth)
    assert sha == card["int8"]["sha256"] and int8_labels.shape == labels.shape
    assert (int8_labels == labels).mean() > 0.9  # int8 rounding moves a few labels, not most
    assert (int8_labels != labels).any() or (int8_probs != probs).any()  # not the fp32 graph
    blob = graph.read_bytes()
    # which convolutions stay fp32 is a choice (the int8 probe compares them): every one in
    # int8 dequantizes more than the label head alone in fp32, which dequantizes more than the
    # shipped graph (the first convolution fp32 too); a name it does not know is refused
    import onnx

    from maniskill_tidy.models.segmenter import int8_graph

    def dequantized(graph: bytes) -> int:
        return sum(n.op_type == "DequantizeLinear" for n in onnx.load_from_string(graph).graph.node)

    every, head = (int8_graph(model, z_rgb, z_depth, fp32) for fp32 in ((), ("head",)))
    assert dequantized(every) > dequantized(head) > dequantized(blob)
    with pytest.raises(ValueError, match="'stem'.*expected 'first' and/or 'head'"):
        int8_graph(model, z_rgb, z_depth, ("stem",))
    graph.write_bytes(blob[:-1] + bytes([blob[-1] ^ 1]))  # a damaged or substituted graph
    with pytest.raises(CheckpointError, match="int8.sha256"):
        served_sha256(tmp_path / "a")
    graph.unlink()
    with pytest.raises(CheckpointError, match="missing.*quantize-segmenter"):
        served_segmenter(tmp_path / "a")
    graph.write_bytes(blob)
    # a card from before the int8 graph: its agents run the fp16 weights, its runs record them
    card_path = tmp_path / "a" / "card.json"
    plain = json.loads(card_path.read_text())
    plain.pop("int8")
    card_path.write_text(json.dumps(plain))
    assert served_sha256(tmp_path / "a") == card["weights_sha256"]
    from maniskill_tidy.cli import main

    assert main(["quantize-segmenter", "--segmenter", str(tmp_path / "a"), "--data",
                 str(tiny_data)]) == 0  # fmt: skip
    assert served_sha256(tmp_path / "a") == card["int8"]["sha256"]
    card_path.write_text(json.dumps(card))

    # scored again with unchanged code: the same figures, the earlier ones kept beside them
    again = st.rescore(tmp_path / "a", tiny_data)
    assert again["test"] == card["test"] and again["val"] == card["val"]
    assert again["scored_before"] == [{k: card[k] for k in ("val", "test", "agent_threshold")}]
    assert json.loads((tmp_path / "a" / "card.json").read_text())["scored_before"]
    other = tmp_path / "other"
    for split in ("val", "test"):  # other frames than it was scored on: refused
        (other / split).mkdir(parents=True)
        (other / split / "manifest.json").write_text(json.dumps({"data_hash": "0" * 64}))
    with pytest.raises(ValueError, match="data hashes differ"):
        st.rescore(tmp_path / "a", other)
    # the same views rendered with other bytes (another machine's llvmpipe): scored, and said
    import shutil

    shutil.rmtree(other)
    shutil.copytree(tiny_data, other)
    for split in ("val", "test"):
        m = json.loads((other / split / "manifest.json").read_text())
        (other / split / "manifest.json").write_text(json.dumps(dict(m, data_hash="1" * 64)))
    elsewhere = st.rescore(tmp_path / "a", other)
    assert elsewhere["scored_on"] == {"val": "1" * 64, "test": "1" * 64}
    assert elsewhere["test"] == card["test"]
    home = st.rescore(tmp_path / "a", tiny_data)
    assert "scored_on" not in home and home["scored_before"][-1]["scored_on"]["val"] == "1" * 64
    m = json.loads((other / "test" / "manifest.json").read_text())
    (other / "test" / "manifest.json").write_text(json.dumps(dict(m, frames=m["frames"] + 1)))
    with pytest.raises(ValueError, match="data hashes differ"):  # more test frames: other data
        st.rescore(tmp_path / "a", other)

    # trained again into the same folder (another seed): the old card does not refuse it
    retrained = st.train_segmenter(_cfg(tiny_data, tmp_path / "a", seed=1), progress=False)
    assert retrained["weights_sha256"] != card["weights_sha256"]
    assert load_segmenter(tmp_path / "a")[1]["weights_sha256"] == retrained["weights_sha256"]


def test_a_run_can_start_from_a_trained_segmenters_weights(tiny_data, tmp_path):
    """``--init``: its weights start the run (at a vanishing rate its parameters come out
    unchanged, batch norm's statistics aside; from scratch they do not), the card names them;
    another architecture is refused."""
    import torch

    from maniskill_tidy.models.checkpoints import load_segmenter
    from maniskill_tidy.training import segmenter_trainer as st

    def parameters(folder):
        return dict(load_segmenter(tmp_path / folder)[0].named_parameters())

    first = st.train_segmenter(_cfg(tiny_data, tmp_path / "a", epochs=1), progress=False)
    still = st.train_segmenter(_cfg(tiny_data, tmp_path / "b", epochs=1, lr=1e-12,
                                    init=str(tmp_path / "a")), progress=False)  # fmt: skip
    a = parameters("a")
    assert all(torch.equal(a[k], p) for k, p in parameters("b").items())
    assert still["init"]["weights_sha256"] == first["weights_sha256"]
    assert still["init"]["from"] == "a" and still["init"]["epochs"] == 1
    fresh = st.train_segmenter(_cfg(tiny_data, tmp_path / "c", epochs=1, lr=1e-12),
                               progress=False)  # fmt: skip
    assert not all(torch.equal(a[k], p) for k, p in parameters("c").items())
    assert "init" not in fresh
    with pytest.raises(ValueError, match="widths \\[8, 8, 16, 16, 16\\].*expected"):
        st.train_segmenter(_cfg(tiny_data, tmp_path / "d", init=str(tmp_path / "a"),
                                widths=(8, 8, 8, 16, 16)), progress=False)  # fmt: skip


def test_extra_train_frames_join_the_train_split_from_other_houses_only(tiny_data, tmp_path):
    """``--extra``: another dataset's frames join the train split (and the card names them);
    frames of the train split's own dataset or of another look are refused."""
    import shutil

    from maniskill_tidy.training import segmenter_trainer as st

    other = tmp_path / "other"
    shutil.copytree(tiny_data / "train", other)  # stands in for the houses of another seed
    manifest = json.loads((other / "manifest.json").read_text())
    with pytest.raises(ValueError, match="another seed"):
        st.train_segmenter(_cfg(tiny_data, tmp_path / "a", epochs=1, extra=(str(other),)),
                           progress=False)  # fmt: skip
    manifest["dataset_hash"] = "0" * 64
    (other / "manifest.json").write_text(json.dumps(dict(manifest, env="HeteroTidy-v2")))
    with pytest.raises(ValueError, match="expected HeteroTidy-v1"):
        st.train_segmenter(_cfg(tiny_data, tmp_path / "b", epochs=1, extra=(str(other),)),
                           progress=False)  # fmt: skip
    (other / "manifest.json").write_text(json.dumps(manifest))
    card = st.train_segmenter(_cfg(tiny_data, tmp_path / "c", epochs=1, extra=(str(other),)),
                              progress=False)  # fmt: skip
    assert card["frames"]["train"] == 2 * 27
    assert card["config"]["extra"] == [{"data_hash": manifest["data_hash"],
                                        "dataset_hash": "0" * 64, "frames": 27}]  # fmt: skip
    alone = st.train_segmenter(_cfg(tiny_data, tmp_path / "d", epochs=1), progress=False)
    assert alone["frames"]["train"] == 27 and "extra" not in alone["config"]


def test_a_segmenter_with_a_stem_a_hidden_head_and_relief_saves_and_loads(tmp_path):
    import torch

    from maniskill_tidy.models.checkpoints import load_segmenter, save_segmenter
    from maniskill_tidy.models.segmenter import Segmenter

    torch.manual_seed(0)
    model = Segmenter(7, (4, 4, 8, 8, 8), stem=3, head=6, relief=True).eval()
    save_segmenter(model, tmp_path)
    back, no_card = load_segmenter(tmp_path)
    assert no_card == {}
    assert back.config() == {"classes": 7, "widths": [4, 4, 8, 8, 8], "stem": 3, "head": 6,
                             "relief": True}  # fmt: skip
    rgb, depth = torch.rand(1, 3, 32, 32) * 255, torch.rand(1, 1, 32, 32) * 3
    with torch.inference_mode():
        assert (model(rgb, depth).argmax(1) == back(rgb, depth).argmax(1)).float().mean() > 0.99


def test_relief_reads_zero_on_a_slanted_plane_and_negative_on_a_box_standing_on_it():
    import torch

    from maniskill_tidy.models.segmenter import RELIEF_WINDOWS, relief

    # a floor seen at a slant: disparity linear in the row, depth from 1 m to 5 m
    rows = torch.arange(64, dtype=torch.float32)[:, None].expand(64, 64)
    depth = 1.0 / (1.0 - rows * (0.8 / 63))
    box = depth.clone()
    box[30:36, 30:36] -= 0.05  # a box 5 cm proud of it
    flat, proud = relief(depth[None, None]), relief(box[None, None])
    assert flat.shape == (1, len(RELIEF_WINDOWS), 64, 64)
    inner = (slice(None), slice(None), slice(12, 52), slice(12, 52))  # off the borders
    assert flat[inner].abs().max() < 1e-3  # a plane reads 0, not its curvature in depth
    assert (proud[0, :, 32, 32] < -0.2).all() and proud[0, -1, 32, 32] < -0.5  # widest window


def test_crops_without_zoom_are_drawn_as_the_shipped_segmenters_were_trained():
    """``zoom`` 1 keeps the shipped runs' random draws: rows, then columns, each one integer
    per crop, made even; a checkpoint resumed under this code crops as it did."""
    from maniskill_tidy.training.segmenter_trainer import _crops

    n, crop = 5, 64
    rgb = np.zeros((n, 224, 224, 3), np.uint8)
    rgb[..., 0] = np.arange(224)[None, :, None]  # each pixel says its row ...
    rgb[..., 1] = np.arange(224)[None, None, :]  # ... and its column
    frames = {"rgb": rgb, "depth_mm": np.full((n, 224, 224), 2000, np.uint16),
              "cls": np.zeros((n, 224, 224), np.uint8)}  # fmt: skip
    out, _, labels = _crops(frames, np.arange(n), crop, np.random.default_rng(7), zoom=1.0)
    draws = np.random.default_rng(7)
    ys, xs = draws.integers(0, 224 - crop + 1, n), draws.integers(0, 224 - crop + 1, n)
    assert out.shape == (n, 3, crop, crop) and labels.shape == (n, crop // 2, crop // 2)
    for k in range(n):  # a flip reverses the columns, not which ones
        assert int(out[k, 0].min()) == ys[k] // 2 * 2 and int(out[k, 1].min()) == xs[k] // 2 * 2


def test_zoomed_crops_show_objects_larger_and_nearer():
    """Crops blown up by up to ``zoom`` show an object over more label cells, its depth
    smaller by the same factor; without zoom, every crop shows it at its size."""
    from maniskill_tidy.perception.seg_classes import seg_classes
    from maniskill_tidy.training.segmenter_trainer import _crops

    mug = seg_classes().index["Mug"]
    frames = {"rgb": np.zeros((1, 224, 224, 3), np.uint8),
              "depth_mm": np.full((1, 224, 224), 2000, np.uint16),
              "cls": np.zeros((1, 224, 224), np.uint8)}  # fmt: skip
    frames["cls"][0, 100:110, 100:110] = mug
    index = np.zeros(64, dtype=int)
    rng = np.random.default_rng(0)
    _, depth, labels = _crops(frames, index, 64, rng, focus=1.0)
    cells = (labels == mug).sum((1, 2)).numpy()  # 10 x 10 px: 25 cells, fewer where cut
    assert labels.shape == (64, 32, 32) and cells.max() == 25 and (cells > 0).all()
    assert (depth == 2.0).all()
    _, depth, labels = _crops(frames, index, 64, rng, focus=1.0, zoom=2.0)
    cells = (labels == mug).sum((1, 2)).numpy()
    near = depth.amin((1, 2, 3)).numpy()
    assert labels.shape == (64, 32, 32) and cells.max() > 50 and (cells > 0).all()
    assert (near < 1.9).sum() > 10 and (near >= 0.99).all() and (near <= 2.0).all()
    assert (cells <= 25 * (2.0 / near) ** 2 + 12).all()  # blown up as much as it came nearer


def test_the_objectness_loss_scores_which_pixels_are_objects_not_their_type():
    import torch

    from maniskill_tidy.training.segmenter_trainer import objectness_dice

    first = 3  # classes 0-2 structure/furniture, 3-4 two pickupable types
    target = torch.zeros(1, 4, 4, dtype=torch.long)
    target[0, :2, :2] = 3  # one small object in a corner

    def logits_of(label: torch.Tensor) -> torch.Tensor:
        return torch.nn.functional.one_hot(label, 5).permute(0, 3, 1, 2).float() * 20

    right = objectness_dice(logits_of(target), target, first)
    other_type = objectness_dice(logits_of(torch.where(target == 3, 4, target)), target, first)
    missed = objectness_dice(logits_of(torch.zeros_like(target)), target, first)
    everywhere = objectness_dice(logits_of(torch.full_like(target, 4)), target, first)
    assert right < 0.01 and other_type < 0.01  # the type is the cross-entropy's business
    assert missed > 0.7  # a missed 4-pixel object costs most of the loss, beside 12 background
    assert 0.3 < everywhere < 0.9  # objects everywhere: all found, three quarters false


def test_the_cross_look_table_scores_each_segmenter_on_each_look(tiny_data, tmp_path):
    """Its diagonal is the card's test score; a look's folder without frames is refused."""
    import shutil

    from maniskill_tidy.training import segmenter_trainer as st
    from maniskill_tidy.training.segmenter_cross_look import cross_look, write_table

    card = st.train_segmenter(_cfg(tiny_data, tmp_path / "seg"), progress=False)
    data = tmp_path / "looks"
    shutil.copytree(tiny_data / "test", data / "HeteroTidy-v1" / "test")
    with pytest.raises(FileNotFoundError, match="no <look>/val/manifest.json"):
        cross_look([tmp_path / "seg"], data, "val", progress=False)
    rows = cross_look([tmp_path / "seg"], data, progress=False)
    assert [(r["trained_on"], r["tested_on"]) for r in rows] == [("HeteroTidy-v1",) * 2]
    assert all(rows[0][k] == card["test"][k] for k in ("AP50", "AP", "pixel_accuracy_pickupable"))
    assert rows[0]["served_sha256"] == card["int8"]["sha256"]  # what agents run
    js, md = write_table(rows, tmp_path / "table" / "cross")
    assert json.loads(js.read_text()) == rows
    assert "| HeteroTidy-v1 | HeteroTidy-v1 |" in md.read_text()
