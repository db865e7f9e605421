"""The learned perception modules: shapes, data, a short run that learns, checkpoints, seeds."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

from maniskill_tidy.envs.episodes import default_dataset
from maniskill_tidy.knowledge import ROOM_TYPES, load_catalog, load_placement
from maniskill_tidy.knowledge.word_vectors import derive_word_vectors, load_word_vectors, words_of
from maniskill_tidy.models.checkpoints import load_perception, save_perception
from maniskill_tidy.models.knowledge_graph import build_graph
from maniskill_tidy.tasks.dataset import load_dataset
from maniskill_tidy.training.perception_data import (
    REGIONS,
    ViewsConfig,
    build_views,
    load_views,
    region_answers,
)
from maniskill_tidy.training.perception_report import compute_priors, perception_metrics
from maniskill_tidy.training.perception_trainer import (
    TrainConfig,
    Views,
    embed_frames,
    fit_stage,
    new_model,
)

K = len(load_catalog().categories)
P = len(load_catalog().receptacles)


@pytest.fixture(scope="module")
def houses():
    return list(load_dataset(default_dataset(), "train").houses.values())


VIEWS = ViewsConfig("train", tasks_per_house=2, every=2, houses=1)


@pytest.fixture(scope="module")
def views_dir(tmp_path_factory) -> Path:
    """Views of one house of the shipped dataset (two expert episodes, every 2nd step)."""
    out = tmp_path_factory.mktemp("views")
    manifest = build_views(out, None, VIEWS, workers=1, progress=False)
    assert manifest["houses"] == 1 and manifest["frames"] > 50 and manifest["detections"] > 20
    return out


@pytest.fixture(scope="module")
def views(views_dir) -> Views:
    return Views(load_views(views_dir / "train"))


def test_word_vectors_cover_the_catalog_and_rooms():
    vectors = load_word_vectors()
    for name in (*load_catalog().categories, *ROOM_TYPES):
        assert vectors[name].shape == (100,) and np.isfinite(vectors[name]).all()
    assert words_of("TVStand") == ["tv", "stand"]
    assert words_of("HandTowelHolder") == ["hand", "towel", "holder"]

    def cos(a, b):
        x, y = vectors[a], vectors[b]
        return float(x @ y / np.linalg.norm(x) / np.linalg.norm(y))

    # GloVe, not noise: related types are closer than unrelated ones.
    assert cos("Pillow", "Bed") > cos("Pillow", "Sink")
    assert cos("Toilet", "Bathroom") > cos("Toilet", "Kitchen")


def test_derive_word_vectors_averages_words_and_names_a_missing_one(tmp_path):
    words = {w for n in (*load_catalog().categories, *ROOM_TYPES) for w in words_of(n)}
    rng = np.random.default_rng(0)
    vectors = {w: rng.normal(size=3).round(3).tolist() + [1.0, 0] for w in sorted(words)}
    src = tmp_path / "wink.json"
    src.write_text(json.dumps({"dimensions": 3, "vectors": vectors}))
    table = derive_word_vectors(src)
    want = (np.array(vectors["coffee"][:3]) + np.array(vectors["table"][:3])) / 2
    assert np.allclose(table["vectors"]["CoffeeTable"], want, atol=1e-4)
    del vectors["fridge"]
    src.write_text(json.dumps({"dimensions": 3, "vectors": vectors}))
    with pytest.raises(ValueError, match="fridge"):
        derive_word_vectors(src)


def test_knowledge_graph_counts_train_placements(houses):
    g = build_graph(houses)
    src, dst = g.edge_index.numpy()
    pairs = set(zip(src.tolist(), dst.tolist(), strict=True))
    assert all((b, a) in pairs for a, b in pairs)  # undirected
    o = houses[0].objects[0]
    f = houses[0].furniture_by_id()[o.receptacle]
    rtype = f.surface(o.surface).receptacle_type
    assert (g.node(o.type), g.node(rtype)) in pairs
    room = {r.id: r.type for r in houses[0].rooms}[o.room]
    assert (g.node(o.type), g.node(room)) in pairs
    assert g.features.shape == (K + 4, 100)


def test_region_answers_follow_the_crop_convention():
    k = load_catalog().category_index("Apple")
    pose = (0.0, 0.0, 0.0)  # facing +x: ahead is +x, left is +y
    ahead_left = region_answers([("Apple", 1.0, 1.0)], pose, 20, 0.25)
    assert ahead_left[:, k].tolist() == [True, False, False, False]
    behind_right = region_answers([("Apple", -1.0, -1.0)], pose, 20, 0.25)
    assert behind_right[:, k].tolist() == [False, False, False, True]
    far = region_answers([("Apple", 3.0, 0.0)], pose, 20, 0.25)  # beyond 2.5 m
    assert not far.any()
    turned = region_answers([("Apple", 1.0, 1.0)], (0.0, 0.0, 90.0), 20, 0.25)
    assert turned[:, k].tolist() == [False, True, False, False]  # now ahead and to the right


def test_views_hold_what_an_agent_saw_with_answers(views):
    raw = views.raw
    assert raw["rgb"].shape[1:] == (64, 64, 3) and raw["rgb"].dtype == np.uint8
    assert raw["crop"].shape[1:] == (20, 20, K + 2)
    assert raw["answers"].shape[1:] == (REGIONS**2, K)
    assert set(np.unique(raw["room"])) <= set(range(4))
    catalog, knowledge = load_catalog(), load_placement()
    for t, rec, rec_d in zip(
        raw["det_type"], raw["det_receptacles"], raw["det_receptacles_d"], strict=True
    ):
        assert catalog.categories[t] in catalog.pickupable
        assert not (rec & ~rec_d).any()  # in the house implies reasonable
        reasonable = {p for p, _ in knowledge.locations(catalog.categories[t])}
        assert {catalog.receptacles[i] for i in np.nonzero(rec_d)[0]} == reasonable
    assert 0 < raw["det_misplaced"].mean() < 1  # both kinds were seen
    # the agents' maps show what they saw: some answered query is visible in its crop
    assert raw["crop"][..., 2:].any()


def test_model_shapes(houses):
    for knowledge in (True, False):
        model = new_model(houses, knowledge)
        b = 3
        sv = model.sv(torch.zeros(b, 64, 64, 3, dtype=torch.uint8))
        assert sv.shape == (b, 256)
        sm = model.sm(torch.zeros(b, 20, 20, K + 2, dtype=torch.uint8))
        assert sm.shape == (b, 256) and model.queries(sm).shape == (b, REGIONS**2, K)
        seen = torch.zeros(b, K)
        assert model.room_classifier(seen, sv).shape == (b, 4)
        sr = model.sr(seen, sv)
        r = model.reason(
            sv, sr, torch.tensor([0, 1, 2]), torch.tensor([0, P, 3]), torch.zeros(b, 7)
        )
        assert r.det.shape == (b, 2) and r.receptacle.shape == (b, P) and r.room.shape == (b, 4)
        assert r.fd.shape == (b, 256) and r.fp.shape == (b, 256)
        assert (r.attention is not None) == knowledge
        if knowledge:
            assert torch.allclose(r.attention.sum(1), torch.ones(b))


def test_frozen_model_reuses_sq_until_a_weight_changes(houses):
    model = new_model(houses, True).eval()
    with torch.no_grad():
        first = model.knowledge_nodes()
        assert model.knowledge_nodes() is first  # computed once
        assert torch.equal(first, model.gcn())  # and exactly what the GCN gives
        state = {k: v + 0.01 for k, v in model.gcn.state_dict().items()}
        model.gcn.load_state_dict(state)
        again = model.knowledge_nodes()
        assert again is not first and torch.equal(again, model.gcn())
    model.train()
    assert model.knowledge_nodes().requires_grad  # training: recomputed, with gradients


def test_frozen_attention_keys_give_the_bits_of_the_full_attention(houses):
    """reason() reuses the nodes' keys and values while frozen; its outputs must be the
    attention computed from scratch, and a changed attention weight must be seen."""
    model = new_model(houses, True).eval()
    rng = torch.Generator().manual_seed(0)
    sl, sr = (
        torch.randn(5, model.cfg.dim, generator=rng),
        torch.randn(5, model.cfg.dim, generator=rng),
    )
    with torch.no_grad():
        for _ in range(2):  # the first call fills the cache, the second reads it
            attl, weights = model._commonsense("object_attention", sl)
            attr, _ = model._commonsense("room_attention", sr)
            full_l, full_w = model.object_attention(sl, model.gcn())
            assert torch.equal(attl, full_l) and torch.equal(weights, full_w)
            assert torch.equal(attr, model.room_attention(sr, model.gcn())[0])
        model.object_attention.v.weight.add_(0.01)
        assert torch.equal(
            model._commonsense("object_attention", sl)[0],
            model.object_attention(sl, model.gcn())[0],
        )
        assert not torch.equal(model._commonsense("object_attention", sl)[0], attl)


def _train_quick(houses, views, tmp: Path, knowledge=True, epochs=None, seed=0):
    cfg = TrainConfig(
        seed=seed, batch=32, epochs=epochs or {"visual": 1, "scene": 1, "room": 25, "reasoning": 25}
    )
    torch.manual_seed(seed)
    model = new_model(houses, knowledge)
    curves = {}
    for stage in ("visual", "scene"):
        curves[stage] = fit_stage(model, stage, views, views, cfg, tmp / f"{stage}.pt", False)
    embed_frames(model, views)
    for stage in ("room", "reasoning"):
        curves[stage] = fit_stage(model, stage, views, views, cfg, tmp / f"{stage}.pt", False)
    return model, curves


def test_short_training_learns(houses, views, tmp_path):
    model, curves = _train_quick(houses, views, tmp_path)
    for stage in ("room", "reasoning"):
        curve = curves[stage]["curve"]
        assert curve[-1]["train"] < 0.7 * curve[0]["train"], (stage, curve)
    m = perception_metrics(model, views, compute_priors(views))
    assert m["room"]["accuracy"] > m["room"]["majority"] + 0.1
    assert m["detector"]["f1"] > m["detector"]["always_misplaced"]["f1"]
    assert m["receptacle"]["top1_reasonable_in_house"] > m["receptacle"]["global_prior"]


def _reasoning(houses, views, checkpoint: Path, epochs: int, seed: int = 0):
    """The reasoning stage alone, on frames embedded by a seeded untrained encoder."""
    torch.manual_seed(seed)
    model = new_model(houses, True)
    embed_frames(model, views)
    cfg = TrainConfig(batch=32, epochs={"reasoning": epochs})
    fit_stage(model, "reasoning", views, views, cfg, checkpoint, False)
    return model


def test_same_seed_same_weights_and_resume_is_exact(houses, views, tmp_path):
    a = _reasoning(houses, views, tmp_path / "a.pt", 2)
    b = _reasoning(houses, views, tmp_path / "b.pt", 2)
    for (k, x), y in zip(a.state_dict().items(), b.state_dict().values(), strict=True):
        assert torch.equal(x, y), k
    # a run stopped after 1 of 2 epochs, resumed from its checkpoint, ends where a straight
    # run does
    _reasoning(houses, views, tmp_path / "c.pt", 1)
    c = _reasoning(houses, views, tmp_path / "c.pt", 2)
    for (k, x), y in zip(a.state_dict().items(), c.state_dict().values(), strict=True):
        assert torch.equal(x, y), k


def test_a_checkpoint_made_on_other_encoders_is_started_over(houses, views, tmp_path):
    _reasoning(houses, views, tmp_path / "ck.pt", 1, seed=0)
    resumed = _reasoning(houses, views, tmp_path / "ck.pt", 1, seed=1)
    fresh = _reasoning(houses, views, tmp_path / "fresh.pt", 1, seed=1)
    for (k, x), y in zip(fresh.state_dict().items(), resumed.state_dict().values(), strict=True):
        assert torch.equal(x, y), k


def test_checkpoint_round_trip(houses, views, tmp_path):
    model = new_model(houses, True).eval()
    save_perception(model, tmp_path / "agent")
    loaded = load_perception(tmp_path / "agent")
    assert loaded.cfg == model.cfg and loaded.nodes == model.nodes
    half = {
        k: v.half().float() if v.is_floating_point() else v for k, v in model.state_dict().items()
    }
    for k, v in loaded.state_dict().items():
        assert torch.equal(v, half[k]), k
    size = (tmp_path / "agent" / "model.pt").stat().st_size
    assert size < 10e6  # fp16: the agents/ folder stays small


def test_cheaper_encoders_are_built_saved_and_named_as_asked(houses, tmp_path):
    from maniskill_tidy.training.perception_trainer import model_card

    train = TrainConfig(visual_widths=(8, 16, 24, 32), scene_widths=(8, 16, 16, 40))
    model = new_model(houses, True, train).eval()
    convs = [m.out_channels for m in model.visual.conv if isinstance(m, torch.nn.Conv2d)]
    assert convs == [8, 16, 24, 32]
    convs = [m.out_channels for m in model.scene.conv if isinstance(m, torch.nn.Conv2d)]
    assert convs == [8, 16, 16, 40]
    assert model.sv(torch.zeros(2, 64, 64, 3, dtype=torch.uint8)).shape == (2, 256)
    assert model.sm(torch.zeros(2, 20, 20, K + 2, dtype=torch.uint8)).shape == (2, 256)
    shipped = new_model(houses, True)
    count = lambda m: sum(p.numel() for p in m.parameters())  # noqa: E731
    assert count(model.visual) < count(shipped.visual) / 4
    assert count(model.scene) < count(shipped.scene) / 3
    save_perception(model, tmp_path / "agent")  # config.json holds the widths as lists
    loaded = load_perception(tmp_path / "agent")
    assert loaded.cfg == model.cfg and loaded.cfg.scene_widths == (8, 16, 16, 40)
    # its own checkpoints, apart from the shipped widths'
    assert train.checkpoints(tmp_path) != TrainConfig().checkpoints(tmp_path)
    card = {"variant": "knowledge", "knowledge": True, "config": {**vars(train), "env": "x"},
            "dataset_hash": "0" * 12, "views_hash": "0" * 12, "code_version": "c", "seed": 0,
            "views": {"train_frames": 1, "train_detections": 1}, "views_seconds": 1,
            "train_seconds": 1, "stages": {}}  # fmt: skip
    text = model_card(json.loads(json.dumps(card)))  # as read back from card.json
    assert "--visual-widths 8,16,24,32 --scene-widths 8,16,16,40" in text
    assert "| 8-16-24-32 / 8-16-16-40 |" in text
    card["config"] = vars(TrainConfig())
    text = model_card(json.loads(json.dumps(card)))
    assert "`maniskill-tidy train perception --env HeteroTidy-v1` (`make train`)" in text
    assert "--visual" not in text


def test_views_refuse_another_configuration(views_dir, tmp_path):
    (tmp_path / "train").mkdir()
    manifest = (views_dir / "train" / "manifest.json").read_text()
    (tmp_path / "train" / "manifest.json").write_text(manifest)
    with pytest.raises(ValueError, match="every"):
        build_views(tmp_path, None, replace(VIEWS, every=3), workers=1, progress=False)
    assert [p.name for p in (tmp_path / "train").iterdir()] == ["manifest.json"]


def test_average_precision_by_hand():
    from maniskill_tidy.training.perception_report import average_precision

    # ranks: 0.9 (hit), 0.8 (miss), 0.7 (hit): precisions 1 and 2/3
    score = np.array([0.7, 0.9, 0.8])
    truth = np.array([True, True, False])
    assert average_precision(score, truth) == pytest.approx((1 + 2 / 3) / 2)
    assert average_precision(score, np.zeros(3, bool)) == 0.0


def test_perception_reports_side_by_side_name_each_look(tmp_path):
    from maniskill_tidy.training.perception_report import beside

    shipped = Path(__file__).resolve().parents[1] / "agents" / "perception"
    metrics = json.loads((shipped / "test_metrics.json").read_text())
    for name, env, scale in (("v1", "HeteroTidy-v1", 1.0), ("v2", "HeteroTidy-v2", 0.5)):
        (tmp_path / name / "knowledge").mkdir(parents=True)
        card = json.loads((shipped / "knowledge" / "card.json").read_text())
        card["config"]["env"] = env
        (tmp_path / name / "knowledge" / "card.json").write_text(json.dumps(card))
        m = json.loads(json.dumps(metrics))
        m["knowledge"]["room"]["accuracy"] *= scale
        (tmp_path / name / "test_metrics.json").write_text(json.dumps(m))
    table = beside(tmp_path / "v2", [tmp_path / "v1"], "test")
    head = table.splitlines()[0]
    assert head.index("with knowledge, HeteroTidy-v2") < head.index("with knowledge, HeteroTidy-v1")
    room = next(line for line in table.splitlines() if line.startswith("| room classifier"))
    acc = metrics["knowledge"]["room"]["accuracy"]
    assert room.split("|")[2].strip() == f"{acc * 0.5:.3f}"
    assert room.split("|")[3].strip() == f"{acc:.3f}"
    assert (tmp_path / "v2" / "TEST_BESIDE.md").read_text().startswith(head)
    with pytest.raises(FileNotFoundError, match="perception-report --agents"):
        beside(tmp_path / "v2", [tmp_path / "missing"], "test")


def test_channels_last_weights_give_a_team_the_same_bits():
    """A team's models run with channels-last convolution weights (``for_agents``, faster):
    every encoder of the shipped models must give the bits the stored layout gives, on the
    channels-last inputs the agents pass (H x W x C permuted)."""
    import copy

    from maniskill_tidy.models.checkpoints import for_agents, load_decision

    perception = load_perception(Path("agents/perception/knowledge"))
    decision, _ = load_decision(Path("agents/hangrcom/setting_I"))
    rng = np.random.default_rng(0)
    k = perception.cfg.categories + 2
    rgb = torch.from_numpy(rng.integers(0, 256, (6, 1, 64, 64, 3), dtype=np.uint8))
    crop = torch.from_numpy(rng.random((6, 1, 20, 20, k)) < 0.1)
    layout = torch.from_numpy((rng.random((6, 1, 20, 20, 4)) < 0.3).astype(np.float32))
    encoders = [(perception.visual, rgb), (perception.scene, crop)]
    encoders += [(a.subgoal.layout, layout) for a in decision.agents if a.subgoal.layout]
    assert len(encoders) > 2
    for encoder, inputs in encoders:
        fast = for_agents(copy.deepcopy(encoder))
        assert any(p.dim() == 4 and not p.is_contiguous() for p in fast.parameters())
        with torch.inference_mode():
            for x in inputs:
                assert torch.equal(fast(x), encoder(x)), type(encoder).__name__
