"""Demonstrations with features, the behaviour-cloning trainer and agent configs."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

from maniskill_tidy.cli import main
from maniskill_tidy.envs.actions import Action
from maniskill_tidy.knowledge import load_catalog
from maniskill_tidy.models.checkpoints import load_decision, save_decision
from maniskill_tidy.models.decision import (
    DecisionConfig,
    StateExtractor,
    SubGoalPredictor,
    TeamDecision,
    crop_goal,
    crop_layout,
    goal_maps,
    suspects,
)
from maniskill_tidy.policies.agent_config import AgentConfig, TrainSettings
from maniskill_tidy.policies.base import OPERATIONS
from maniskill_tidy.training.decision_data import (
    DemoConfig,
    build_demo_features,
    load_demo_features,
)
from maniskill_tidy.training.decision_features import embed_split
from maniskill_tidy.training.decision_metrics import evaluate, selection_score
from maniskill_tidy.training.decision_trainer import fit
from tests.conftest import taken_action

DEMOS = DemoConfig(setting="I", split="train", starts=1, tasks=1, houses=1)
PERCEPTION = Path(__file__).resolve().parents[1] / "agents" / "perception" / "knowledge"


@pytest.fixture(scope="module")
def demos(small_dataset, tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("demos")
    for split in ("train", "val"):
        build_demo_features(root, str(small_dataset), replace(DEMOS, split=split), progress=False)
    return root


def test_demos_hold_every_agents_inputs_and_the_experts_labels(demos):
    d = load_demo_features(demos / "setting_I" / "train")
    manifest = json.loads((demos / "setting_I" / "train" / "manifest.json").read_text())
    assert manifest["trajectories"] == len(d["episodes"]) == 1 and manifest["rows"] == len(d["t"])
    k = len(load_catalog().categories)
    assert d["rgb"].shape[1:] == (64, 64, 3) and d["seen"].shape[1:] == (k,)
    assert np.unpackbits(d["crop"], axis=1).shape[1] >= 20 * 20 * (k + 2)
    assert d["wide"].shape[1:] == (20, 20, 3) and d["wide"].dtype == np.uint8
    for agent in range(3):  # one sequence per agent: steps 0, 1, ... up to its Stop
        rows = np.flatnonzero(d["agent"] == agent)
        assert rows.tolist() == sorted(rows) and d["t"][rows].tolist() == list(range(len(rows)))
        assert (d["capability"][rows] == [(1, 0, 0), (1, 0, 1), (1, 1, 1)][agent]).all()
    stops = d["action"] == int(Action.Stop)
    assert (d["stop"][stops] == 1).all(), "the expert's Stop is labelled stop"
    assert d["episodes"][0]["success"], "the expert tidied this task"
    assert ((-4 <= d["dx"]) & (d["dx"] <= 4) & (-4 <= d["dy"]) & (d["dy"] <= 4)).all()
    assert set(d["ope"].tolist()) <= set(range(len(OPERATIONS)))
    place = d["kind"] == 1
    assert place.any() and (d["object"][place] >= 0).all() and (d["receptacle"][place] >= 0).all()
    assert (d["ope"] == OPERATIONS.index("PickUp")).any(), "the manipulator picks something up"
    assert (d["det_row"] < len(d["t"])).all() and len(d["det_row"]) > 0
    held = d["held"] >= 0
    assert held.any() and (d["agent"][held] == 2).all(), "only the manipulator holds things"


def test_demos_resume_and_refuse_another_configuration(demos, small_dataset):
    folder = demos / "setting_I" / "train"
    before = {p.name: p.stat().st_mtime_ns for p in folder.iterdir()}
    m = build_demo_features(demos, str(small_dataset), DEMOS, progress=False)
    shards = [p for p in before if p.startswith("house_")]
    assert all((folder / p).stat().st_mtime_ns == before[p] for p in shards)  # not rendered again
    assert m["demos_hash"] == json.loads((folder / "manifest.json").read_text())["demos_hash"]
    assert DEMOS.teacher == "expert" and m["teacher_rules"] == ""  # the expert has no rules
    with pytest.raises(ValueError, match="starts"):
        build_demo_features(demos, str(small_dataset), replace(DEMOS, starts=2), progress=False)
    with pytest.raises(ValueError, match="teacher"):  # one teacher per folder
        build_demo_features(
            demos, str(small_dataset), replace(DEMOS, teacher="heuristic-none"), progress=False
        )
    with pytest.raises(ValueError, match="unknown teacher 'oracle'"):
        build_demo_features(demos, str(small_dataset), replace(DEMOS, teacher="oracle"))
    with pytest.raises(ValueError, match=r"other settings \(env\)"):  # one look per folder
        build_demo_features(
            demos, str(small_dataset), replace(DEMOS, env="HeteroTidy-v2"), progress=False
        )


def test_a_folder_played_under_a_teachers_first_rules_takes_no_shards_under_new_ones(tmp_path):
    """Shards of a teacher whose rules changed (``Team.rules``) never mix with its old ones: a
    folder made before the field was played under the first rules."""
    from maniskill_tidy.training.house_jobs import check_same_config

    manifest = tmp_path / "manifest.json"
    manifest.write_text(json.dumps({"teacher": "heuristic-detection", "starts": 1}))
    first = {"teacher": "heuristic-detection", "starts": 1, "teacher_rules": ""}
    check_same_config(manifest, first)
    with pytest.raises(ValueError, match=r"other settings \(teacher_rules\)"):
        check_same_config(manifest, {**first, "teacher_rules": "full-surface"})


def test_also_train_demonstrations_must_share_the_teachers_rules_and_look(tmp_path):
    """also_train adds another folder's demonstrations to a config's own: labels played under
    other rules would teach two teachers at once, and another look's views would train one
    model on two renderers, so training refuses before it embeds them."""
    from maniskill_tidy.training.decision_trainer import same_demo_conditions

    new, old = {"teacher_rules": "full-surface"}, {"teacher": "heuristic-detection"}
    same_demo_conditions(new, dict(new), tmp_path)
    same_demo_conditions({}, old, tmp_path)  # both made under the first rules, in v1
    same_demo_conditions({"env": "HeteroTidy-v1"}, {}, tmp_path)  # v1 folders leave env out
    with pytest.raises(ValueError, match=r"made with teacher_rules '', the config's "
                       r"demonstrations with teacher_rules 'full-surface'"):  # fmt: skip
        same_demo_conditions(new, old, tmp_path)
    v2 = {**new, "env": "HeteroTidy-v2"}
    with pytest.raises(ValueError, match=r"made with env 'HeteroTidy-v2', the config's "
                       r"demonstrations with env 'HeteroTidy-v1'; expected the same"):  # fmt: skip
        same_demo_conditions(new, v2, tmp_path)


def test_demos_hash_names_the_data_not_how_long_it_took(demos, tmp_path):
    """Two builds of the same demonstrations differ only in each house's render time: they
    must share a hash (the model cards quote it as the data's identity); other data must not."""
    from maniskill_tidy.training.house_jobs import shards_digest

    shard = next((demos / "setting_I" / "train").glob("house_*.npz"))
    with np.load(shard) as z:
        arrays = {name: z[name] for name in z.files}
    assert "seconds" in arrays

    def digest(folder: str, **change) -> str:
        (tmp_path / folder).mkdir()
        np.savez_compressed(tmp_path / folder / shard.name, **{**arrays, **change})
        return shards_digest(tmp_path / folder, "house_*.npz")

    same = digest("a")
    assert digest("b", seconds=arrays["seconds"] + 100.0) == same
    assert digest("c", t=arrays["t"] + 1) != same


def test_a_camera_only_team_can_teach(small_dataset, tmp_path):
    """Demos from heuristic-none: its own labels, with exploration, line up with its actions."""
    cfg = replace(DEMOS, teacher="heuristic-none")
    m = build_demo_features(tmp_path, str(small_dataset), cfg, progress=False)
    assert m["teacher"] == "heuristic-none" and m["trajectories"] == 1
    assert m["teacher_rules"] == "full-surface"  # the rules its labels were played under
    d = load_demo_features(tmp_path / "setting_I" / "train")
    assert (d["kind"] == 0).any(), "it searches before it knows of a misplaced object"
    picks = d["action"] == int(Action.PickUp)
    assert picks.any() and (d["ope"][picks] == OPERATIONS.index("PickUp")).all()
    assert (d["object"][d["kind"] == 1] >= 0).all()


@pytest.fixture(scope="module")
def rows(demos, tmp_path_factory):
    cache = tmp_path_factory.mktemp("features")
    train = embed_split(demos / "setting_I" / "train", PERCEPTION, cache, progress=False)
    val = embed_split(demos / "setting_I" / "val", PERCEPTION, cache, progress=False)
    return train, val


def _cfg() -> DecisionConfig:
    catalog = load_catalog()
    return DecisionConfig(
        objects=len(catalog.pickupable), receptacles=len(catalog.receptacles), layout=True
    )


def test_features_line_up_with_the_rows(rows):
    train, _ = rows
    assert train.index.shape[0] == 1 and train.index.shape[2] == 3
    n = int((train.index >= 0).sum())
    assert n == len(train.x["sv"]) and sorted(train.index[train.index >= 0].tolist()) == list(
        range(n)
    )
    assert train.x["sv"].dtype == torch.float16 and train.x["sv"].shape[1] == 256
    xs, present, ys = train.batch(np.array([0]))
    layout = xs[2]["layout"][present[..., 2]]  # the manipulator's map, step by step
    assert layout.dtype == torch.uint8 and layout.shape[1:] == (20, 20, 3)
    explored = layout[..., 1].flatten(1).sum(1)
    assert explored[-1] > explored[0] > 0, "its map grows as it moves"
    wide = xs[2]["wide"][present[..., 2]].float()  # the same map, coarse and whole
    assert wide.shape[1:] == (20, 20, 3) and wide.max() <= 255
    assert wide[-1, ..., 1].sum() > wide[0, ..., 1].sum() > 0
    assert present.shape[-1] == 3 and all(y["dx"][present[..., i]].min() >= 0
                                          for i, y in enumerate(ys))  # fmt: skip
    suspect = train.x["suspect"].float()
    assert suspect.shape == (n, len(load_catalog().pickupable)) and suspect.max() <= 1
    assert suspect.max() > 0, "the expert's agents see misplaced objects"
    assert (train.x["det"][suspect.amax(1) > 0] == 1).all(), "a suspect is a detection"


def test_behaviour_cloning_learns_is_seeded_and_resumes(rows, tmp_path):
    train, val = rows
    s = TrainSettings(epochs=4, batch=1, lr=3e-3, seed=0, hard_fraction=0.5, patience=10)

    def run(folder: Path, epochs: int) -> TeamDecision:
        torch.manual_seed(0)
        model = TeamDecision(_cfg(), 3)
        fit(model, train, train, replace(s, epochs=epochs), folder / "ckpt", progress=False)
        return model

    torch.manual_seed(0)
    before = evaluate(TeamDecision(_cfg(), 3), train, hard=True)
    model = run(tmp_path / "a", 4)
    after = evaluate(model, train, hard=True)
    assert after["loss"] < before["loss"] * 0.8, (before["loss"], after["loss"])
    same = run(tmp_path / "b", 4)
    assert all(torch.equal(p, q) for p, q in zip(model.parameters(), same.parameters(),
                                                 strict=True))  # fmt: skip
    run(tmp_path / "c", 2)  # interrupted after two epochs ...
    resumed = run(tmp_path / "c", 4)  # ... and resumed
    assert all(torch.equal(p, q) for p, q in zip(model.parameters(), resumed.parameters(),
                                                 strict=True))  # fmt: skip


def test_a_rerun_that_trains_nothing_keeps_the_code_version_that_trained(
    rows, tmp_path, monkeypatch
):
    """The model card names the code that trained the weights; a later no-op rerun (a queue
    restarted, `make train-all`) must not relabel them."""
    import maniskill_tidy.common.provenance as provenance

    train, _ = rows
    s = TrainSettings(epochs=2, batch=1, lr=3e-3, seed=0, hard_fraction=0.5, patience=10)

    def fit_at(version: str, epochs: int) -> dict:
        monkeypatch.setattr(provenance, "code_version", lambda: version)
        model = TeamDecision(_cfg(), 3)
        return fit(model, train, train, replace(s, epochs=epochs), tmp_path / "ckpt", False)

    assert fit_at("trained", 2)["code_version"] == "trained"
    assert fit_at("later", 2)["code_version"] == "trained"  # nothing left to train
    assert fit_at("resumed", 3)["code_version"] == "resumed"  # it trained the last epoch


def test_selection_by_accuracy_rewards_heads_above_the_majority_baseline():
    better = {
        "loss": 9.0,
        "accuracy": {"dx": 0.5, "object": None},
        "majority": {"dx": 0.3, "object": None},
    }
    worse = {
        "loss": 8.0,
        "accuracy": {"dx": 0.3, "object": None},
        "majority": {"dx": 0.3, "object": None},
    }
    assert selection_score(better, "accuracy") < selection_score(worse, "accuracy")
    assert selection_score(worse, "loss") < selection_score(better, "loss")


def test_crop_layout_keeps_obstacles_explored_cells_and_any_object():
    k = len(load_catalog().categories)
    crop = np.zeros((20, 20, k + 2), bool)
    crop[0, 0, 0] = crop[1, 1, 1] = crop[2, 2, 2 + 7] = crop[3, 3, 2 + k - 1] = True
    layout = crop_layout(crop)
    assert layout.shape == (20, 20, 3) and layout.sum() == 4
    assert layout[0, 0, 0] and layout[1, 1, 1] and layout[2, 2, 2] and layout[3, 3, 2]


def _goal_cfg() -> DecisionConfig:
    """F_g reading the sub-task's target in the crop (layout and goal map)."""
    catalog = load_catalog()
    return DecisionConfig(
        categories=len(catalog.categories), objects=len(catalog.pickupable),
        receptacles=len(catalog.receptacles), layout=True, goal_map=True,
    )  # fmt: skip


def test_goal_map_points_at_the_subtask_target_object_or_receptacle():
    """The goal channel holds the predicted object's cells while the hands are empty and the
    predicted receptacle's while holding; a type the crop does not hold gives an empty goal."""
    catalog = load_catalog()
    k = len(catalog.categories)
    cfg = _goal_cfg()
    apple, table = catalog.pickupable.index("Apple"), catalog.receptacles.index("DiningTable")
    crop = np.zeros((20, 20, k + 2), bool)
    crop[2, 3, 2 + catalog.category_index("Apple")] = True
    crop[15, 5, 2 + catalog.category_index("DiningTable")] = True
    packed = torch.from_numpy(crop_goal(crop))[None, None].repeat(1, 2, 1)
    x = {"layout": torch.zeros(1, 2, 20, 20, 3), "goal": packed,
         "held": torch.tensor([[-1, catalog.category_index("Apple")]])}  # fmt: skip
    task = {"object": torch.full((1, 2, cfg.objects), -50.0),
            "receptacle": torch.full((1, 2, cfg.receptacles), -50.0)}  # fmt: skip
    task["object"][..., apple] = 50.0
    task["receptacle"][..., table] = 50.0
    goal = SubGoalPredictor(cfg).goal(x, task)
    assert goal.shape == (1, 2, 20, 20)
    assert goal[0, 0, 2, 3] > 0.99 and goal[0, 0].sum() < 1.01  # empty hands: the apple
    assert goal[0, 1, 15, 5] > 0.99 and goal[0, 1].sum() < 1.01  # holding: the table
    task["object"][..., apple] = -50.0
    task["object"][..., catalog.pickupable.index("Mug")] = 50.0
    assert SubGoalPredictor(cfg).goal(x, task)[0, 0].sum() < 1e-3  # no mug in the crop
    with pytest.raises(ValueError, match="goal_map needs layout"):
        SubGoalPredictor(replace(cfg, layout=False))


def test_agents_unpacked_goal_maps_give_the_packed_training_rows_bits():
    """A learned agent hands its crop's goal maps to F_g as they are, training rows store them
    bit-packed: the goal channel must be the same, bit for bit, on a busy crop."""
    catalog = load_catalog()
    k = len(catalog.categories)
    cfg = _goal_cfg()
    rng = np.random.default_rng(0)
    crop = rng.random((20, 20, k + 2)) < 0.2
    held = torch.tensor([[-1, 3]])
    task = {
        "object": torch.randn(1, 2, cfg.objects),
        "receptacle": torch.randn(1, 2, cfg.receptacles),
    }
    f_g = SubGoalPredictor(cfg)
    packed = f_g.goal(
        {
            "layout": torch.zeros(1, 2, 20, 20, 3),
            "held": held,
            "goal": torch.from_numpy(crop_goal(crop))[None, None].repeat(1, 2, 1),
        },
        task,
    )
    maps = torch.from_numpy(goal_maps(crop))[None, None].float().repeat(1, 2, 1, 1, 1)
    unpacked = f_g.goal({"goal_maps": maps, "held": held}, task)
    assert packed.sum() > 0 and torch.equal(packed, unpacked)


def test_suspects_keep_each_pickupable_types_highest_misplaced_probability():
    catalog = load_catalog()
    kinds = [catalog.category_index(t) for t in ("Apple", "Apple", "DiningTable", "Mug")]
    out = suspects(torch.tensor([0, 0, 0, 1]), torch.tensor(kinds),
                   torch.tensor([0.3, 0.8, 0.9, 0.5]), 2, len(catalog.pickupable))  # fmt: skip
    apple, mug = catalog.pickupable.index("Apple"), catalog.pickupable.index("Mug")
    assert out.shape == (2, len(catalog.pickupable))
    assert out[0, apple] == pytest.approx(0.8) and out[0].sum() == pytest.approx(0.8)  # no table
    assert out[1, mug] == pytest.approx(0.5) and out[1].sum() == pytest.approx(0.5)


def _state_inputs(t: int, objects: int, rng: np.random.Generator) -> dict[str, torch.Tensor]:
    def f(*shape):
        return torch.from_numpy(rng.normal(size=(1, t, *shape)).astype(np.float32))

    suspect = torch.zeros(1, t, objects)
    suspect[0, 0, 5] = 0.9  # in view at the first step only
    return dict(sv=f(256), sm=f(256), fd=f(256), fp=f(256), failed=torch.zeros(1, t),
                mis=torch.rand(1, t), det=torch.ones(1, t), pose=f(4), held=torch.full((1, t), -1),
                va=torch.ones(1, t, 3), suspect=suspect)  # fmt: skip


def test_the_suspect_memory_carries_a_sighting_and_steps_as_the_episode_trains():
    """Step by step (acting) gives the whole-episode forward's sf (training), and a misplaced
    object seen at the first step still changes sf at the last."""
    torch.manual_seed(0)
    cfg = DecisionConfig(suspects=True)
    f = StateExtractor(cfg).eval()
    x = _state_inputs(6, cfg.objects, np.random.default_rng(0))
    with torch.no_grad():
        whole, (_, memory) = f(x)
        state, steps = None, []
        for t in range(6):
            sf, state = f({k: v[:, t : t + 1] for k, v in x.items()}, state)
            steps.append(sf)
        assert torch.allclose(torch.cat(steps, 1), whole, atol=1e-5)
        assert memory[0, 5] == pytest.approx(0.9) and state[1][0, 5] == pytest.approx(0.9)
        lstm, memory = f({k: v[:, :1] for k, v in x.items()})[1]  # after the sighting
        late = {k: v[:, 1:] for k, v in x.items()}  # the steps after it: the type not in view
        remembered = f(late, (lstm, memory))[0]
        assert not torch.allclose(remembered, f(late, (lstm, torch.zeros_like(memory)))[0])
        unseen = {**x, "suspect": torch.zeros_like(x["suspect"])}
        blind = StateExtractor(replace(cfg, misplaced_detector=False)).eval()
        assert torch.equal(blind(x)[0], blind(unseen)[0]), "w/o MisObjDec. has no suspects"


def test_an_ope_threshold_lets_a_likely_operation_win_over_the_argmax():
    from maniskill_tidy.policies.learned import decode

    catalog = load_catalog()
    logits = {"kind": torch.zeros(2), "object": torch.zeros(len(catalog.pickupable)),
              "receptacle": torch.zeros(len(catalog.receptacles)), "room": torch.zeros(4),
              "dx": torch.zeros(9), "dy": torch.zeros(9), "drot": torch.zeros(4),
              "stop": torch.zeros(2),
              "ope": torch.log(torch.tensor([0.8, 0.15, 0.04, 0.01]))}  # fmt: skip
    assert decode(logits).subgoal.ope == "NoAction"  # the paper's argmax
    assert decode(logits, 0.1).subgoal.ope == "PickUp"
    assert decode(logits, 0.2).subgoal.ope == "NoAction"
    assert decode(logits).subgoal.dx == -4  # argmax of equal logits: the first class
    logits["dy"] = torch.tensor([-50.0] * 8 + [50.0])  # all the mass on dy = +4
    rng = np.random.default_rng(0)
    drawn = [decode(logits, rng=rng).subgoal for _ in range(200)]
    assert {g.dy for g in drawn} == {4}
    assert len({g.dx for g in drawn}) == 9  # drawn from the uniform head, seeded
    again = [decode(logits, rng=np.random.default_rng(0)).subgoal.dx for _ in range(1)]
    assert again[0] == drawn[0].dx
    logits["dx"] = torch.log(torch.tensor([0.3] + [0.7 / 8] * 8))  # dx = -4 likeliest, 30 %
    for t, low, high in ((1.0, 0.2, 0.4), (0.25, 0.9, 1.0)):
        rng = np.random.default_rng(1)
        dx = [decode(logits, rng=rng, temperature=t).subgoal.dx for _ in range(400)]
        assert low <= dx.count(-4) / 400 <= high, t  # T = 0.25: 0.3^4 against 8 x 0.0875^4


def test_auc_is_the_chance_a_positive_outranks_a_negative():
    from maniskill_tidy.training.decision_metrics import auc

    positive = torch.tensor([True, False, True, False])
    assert auc(torch.tensor([0.9, 0.1, 0.8, 0.2]), positive) == 1.0
    assert auc(torch.tensor([0.1, 0.9, 0.2, 0.8]), positive) == 0.0
    assert auc(torch.tensor([0.9, 0.5, 0.3, 0.1]), positive) == 0.75
    assert auc(torch.tensor([0.5, 0.5, 0.5, 0.5]), positive) == 0.5
    assert auc(torch.tensor([0.5, 0.2]), torch.tensor([False, False])) is None


@pytest.mark.parametrize(
    "variant", [{"hierarchical": False}, {"communication": "cmpr"}, {"wide_layout": True}]
)
def test_a_variant_learns_its_own_heads_from_the_same_rows(rows, tmp_path, variant):
    """w/o HierDec. clones the teacher's low-level actions; a baseline's auxiliary loss (the
    code's reconstruction) is part of what is minimised."""
    train, _ = rows
    cfg = replace(_cfg(), **variant)
    torch.manual_seed(0)
    model = TeamDecision(cfg, 3)
    before = evaluate(model, train, hard=True)
    s = TrainSettings(epochs=4, batch=1, lr=3e-3, seed=0, hard_fraction=0.5, patience=10)
    fit(model, train, train, s, tmp_path / "ckpt", progress=False)
    after = evaluate(model, train, hard=True)
    assert after["loss"] < before["loss"] * 0.8, (before["loss"], after["loss"])
    heads = ("action", "receptacle") if variant.get("hierarchical") is False else None
    if heads:
        assert set(after["accuracy"]) == set(heads) and "ope_auc" not in after
        assert after["accuracy"]["action"] > after["majority"]["action"]
        n = int((train.index >= 0).sum())
        assert after["labelled"]["action"] == n  # every row has the teacher's action


def test_a_saved_model_loads_in_fp16_precision(tmp_path):
    torch.manual_seed(1)
    model = TeamDecision(_cfg(), 3)
    save_decision(model, tmp_path, {"name": "x"})
    loaded, saved = load_decision(tmp_path)
    assert saved["name"] == "x" and len(loaded.agents) == 3
    for p, q in zip(model.parameters(), loaded.parameters(), strict=True):
        assert torch.allclose(p, q, atol=1e-2, rtol=1e-2)
    assert (tmp_path / "model.pt").stat().st_size < 3 * 2.5e6  # fp16, three agents


def test_agent_config_errors_name_what_is_wrong(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\nout: y\nlearning_rate: 3\n")
    with pytest.raises(ValueError, match="unknown keys \\['learning_rate'\\]"):
        AgentConfig.load(bad)
    bad.write_text("name: x\nout: y\ntrain: {epochz: 3}\n")
    with pytest.raises(ValueError, match="unknown train keys"):
        AgentConfig.load(bad)
    bad.write_text("name: x\nout: y\ntrain: {select: f1}\n")
    with pytest.raises(ValueError, match="train select 'f1'"):
        AgentConfig.load(bad).settings()
    bad.write_text("name: x\nout: y\nact: {ope_threshold: 2}\n")
    with pytest.raises(ValueError, match="act ope_threshold 2: expected a probability"):
        AgentConfig.load(bad)
    bad.write_text("name: x\nout: y\nmodel: {goal_map: true}\n")
    with pytest.raises(ValueError, match="goal_map needs layout"):
        AgentConfig.load(bad)
    bad.write_text("out: y\n")
    with pytest.raises(ValueError, match="missing 'name'"):
        AgentConfig.load(bad)
    assert main(["train", str(tmp_path / "none.yaml"), "--setting", "I"]) == 2
    assert "no such agent config" in capsys.readouterr().err
    assert main(["eval", "--policy", str(tmp_path / "none.yaml")]) == 2


class Legal:
    """Checks every action against the acting agent's capability."""

    def start(self, env, team, channel) -> None:
        self.env, self.actions = env, 0

    def decided(self, t, actions, labels) -> None:
        for a in self.env.agents:
            if a.name in actions:
                act = taken_action(a, actions[a.name])
                assert a.manipulator or act < Action.PickUp, (a.name, act)
                assert a.name in labels  # it says which sub-task and sub-goal it pursues
                self.actions += 1


@pytest.mark.parametrize("setting", ["I", "II"])
def test_the_shipped_hangrcom_team_loads_and_plays_a_short_episode(setting):
    from maniskill_tidy.eval.episode import play_episode
    from maniskill_tidy.eval.runner import RunConfig, make_env
    from maniskill_tidy.policies import make_team

    env = make_env(RunConfig("hangrcom", setting, "test", None, 1))
    env.unwrapped.max_steps = 12
    legal = Legal()
    try:
        record = play_episode(env, make_team("hangrcom"), 0, 0, [legal])
        stopped = all(a.stopped for a in env.unwrapped.agents)
    finally:
        env.close()
    assert record.length == 12 or (record.length < 12 and stopped)
    assert legal.actions >= record.length and record.comm > 0


def test_the_oracle_variant_alone_is_given_the_misplaced_objects_and_fetches_one(tmp_path):
    """SA(Oracle)'s one difference: the misplaced objects' locations at reset. Its manipulator
    walks to the nearest and picks it up, and its rows are marked privileged."""
    from maniskill_tidy.eval.episode import play_episode
    from maniskill_tidy.eval.runner import RunConfig, make_env
    from maniskill_tidy.policies.base import PublicInfo
    from maniskill_tidy.policies.learned import learned_team_class

    config = tmp_path / "oracle.yaml"
    config.write_text(
        f"base: {Path('agents/hangrcom.yaml').resolve()}\n"
        "name: oracle-test\nact: {oracle: true}\n"
    )
    oracle = learned_team_class(config)
    assert oracle.oracle and oracle.privileged
    assert not learned_team_class("agents/hangrcom.yaml").privileged

    env = make_env(RunConfig("hangrcom", "I", "test", None, 1))
    try:
        env.reset(seed=0, options={"episode": 20})  # a manipulator starts a step from a view
        u = env.unwrapped
        assert PublicInfo.of(u, 0).oracle_misplaced == {}
        given = PublicInfo.of(u, 0, oracle=True).oracle_misplaced
        assert set(given) == set(u.misplaced)
        u.max_steps = 40
        record = play_episode(env, oracle(), 20, 0, [Legal()])
    finally:
        env.close()
    assert record.found >= 1


def test_the_oracle_goes_for_the_next_object_once_it_holds_the_one_it_walked_to(tmp_path):
    """Regression: picking up the object it was walking to drops it from the targets; once
    that object is put down, the oracle walks to the next target instead of failing on the
    stale one (KeyError in the SA(Oracle) test run, episode 6 here)."""
    from maniskill_tidy.eval.episode import play_episode
    from maniskill_tidy.eval.runner import RunConfig, make_env
    from maniskill_tidy.policies.learned import learned_team_class

    config = tmp_path / "oracle.yaml"
    config.write_text(
        f"base: {Path('agents/hangrcom.yaml').resolve()}\n"
        "name: oracle-test\nact: {oracle: true}\n"
    )
    env = make_env(RunConfig("hangrcom", "I", "test", None, 1))
    try:
        env.reset(seed=0, options={"episode": 6})
        env.unwrapped.max_steps = 140
        record = play_episode(env, learned_team_class(config)(), 6, 0, [])
    finally:
        env.close()
    assert record.found >= 2


# ---------------------------------------------------------------------------------- DAgger
class Played:
    """What the playing team sent to the env, step by step."""

    def decided(self, t, actions, labels) -> None:
        self.steps = getattr(self, "steps", []) + [dict(actions)]


def test_a_shadow_teacher_labels_the_states_the_student_reaches(small_dataset):
    """DAgger's rows: the student's moves reach the env, the watching teacher's labels and
    actions are stored, and the teacher's messages are not counted as the student's."""
    from maniskill_tidy.eval.episode import play_episode
    from maniskill_tidy.eval.runner import RunConfig, make_env
    from maniskill_tidy.policies import make_team
    from maniskill_tidy.training.decision_data import DemoRecorder, ShadowTeacher

    env = make_env(RunConfig("random", "I", "train", str(small_dataset), "standard"), images=True)
    env.unwrapped.max_steps = 25
    recorder, played = DemoRecorder(), Played()
    recorder.shadow = ShadowTeacher("heuristic-detection", 0)
    record = play_episode(env, make_team("random"), 0, 0, [played, recorder])
    env.close()
    d = recorder.arrays("h")
    assert record.comm == 0, "the random student sends nothing; the teacher's channel is its own"
    assert len(d["t"]) > 0 and (d["dx"] != 0).any()  # the teacher's sub-goals, not empty rows
    pairs = zip(d["t"], d["agent"], strict=True)
    student = [played.steps[int(t)][f"agent_{int(a)}"] for t, a in pairs]
    student = [int(getattr(s, "action", s)) for s in student]
    assert (d["action"] != np.asarray(student)).any(), "stored actions are the teacher's"


def test_rows_of_two_folders_add_up_episode_by_episode(rows):
    train, val = rows
    both = train + val
    n = len(train.y["dx"])
    assert both.episodes == train.episodes + val.episodes
    assert len(both.y["dx"]) == n + len(val.y["dx"])
    second = both.index[train.episodes :, : val.index.shape[1]]
    assert torch.equal(second, torch.where(val.index >= 0, val.index + n, -1))
    assert (both.index[train.episodes :, val.index.shape[1] :] == -1).all()
    for e in range(both.episodes):  # every row of a batch is the one it was in its own folder
        xs, present, ys = both.batch(np.array([e]))
        src, i = (train, e) if e < train.episodes else (val, e - train.episodes)
        xs2, present2, ys2 = src.batch(np.array([i]))
        assert torch.equal(present, present2)
        assert all(torch.equal(a["dx"], b["dx"]) for a, b in zip(ys, ys2, strict=True))
    fewer = replace(val, x={k: v for k, v in val.x.items() if k != next(iter(val.x))})
    with pytest.raises(ValueError, match="rows with inputs"):
        train + fewer


def test_a_config_refuses_also_train_folders_that_do_not_exist(tmp_path):
    from maniskill_tidy.training.decision_trainer import train_decision

    config = tmp_path / "c.yaml"
    config.write_text(
        f"name: c\nout: {tmp_path / 'out'}\nalso_train: [{tmp_path / 'nowhere'}]\n"
        f"demos: {tmp_path / 'demos'}\n"
        "train_demos: {starts: 1, tasks: 1, houses: 1}\n"
        "val_demos: {starts: 1, tasks: 1, houses: 1}\n"
    )
    with pytest.raises(FileNotFoundError, match="also_train .*nowhere.* has no demonstrations"):
        train_decision(config, "I", progress=False)


def test_a_student_without_a_trained_model_is_refused_before_anything_is_written(
    tmp_path, small_dataset
):
    config = tmp_path / "untrained.yaml"
    config.write_text(f"name: untrained\nout: {tmp_path / 'models'}\n")
    cfg = replace(DEMOS, student=str(config))
    with pytest.raises(ValueError, match=r"student .*model.pt not found \(looked in .*; train it"):
        build_demo_features(tmp_path / "demos", str(small_dataset), cfg, progress=False)
    assert not (tmp_path / "demos").exists()


def test_a_config_refuses_a_subgoal_temperature_that_is_not_positive(tmp_path):
    from maniskill_tidy.policies.agent_config import AgentConfig

    config = tmp_path / "t.yaml"
    config.write_text(
        f"name: t\nout: {tmp_path}\nact: {{sample_subgoal: true, subgoal_temperature: 0}}\n"
    )
    with pytest.raises(ValueError, match="subgoal_temperature 0: expected a number above 0"):
        AgentConfig.load(config).acting()


def test_each_variants_runs_line_says_what_it_leaves_out():
    from maniskill_tidy.policies.learned import LearnedTeam, learned_team_class

    names = ("hangrcom", "wo_comm", "wo_hierdec", "wo_misobjdec", "wo_know")
    line = {name: learned_team_class(f"agents/{name}.yaml").perception for name in names}
    assert line["hangrcom"].endswith("hierarchical decision, HanGrCom")
    assert LearnedTeam.perception == line["hangrcom"]  # `--policy hangrcom` is the same team
    assert line["wo_comm"].endswith("hierarchical decision, no communication")
    assert "low-level (no sub-tasks) decision" in line["wo_hierdec"]
    assert line["wo_misobjdec"].endswith("without misplaced-object detector")
    assert "agents/perception/no-knowledge" in line["wo_know"]


# ------------------------------------------------------------------- sub-goal steps (issue 48)
def test_every_kth_row_keeps_each_row_once_in_its_phase(rows):
    train, _ = rows
    k = 4
    sub = train.every(k)
    assert train.every(1) is train
    assert sub.index.shape[1] == -(-train.index.shape[1] // k)
    kept = sub.index[sub.index >= 0]
    assert sorted(kept.tolist()) == sorted(train.index[train.index >= 0].tolist())
    e = 0  # the first episode's phases follow each other: phase p holds steps p, p + k, ...
    for p in range(k):
        assert torch.equal(sub.index[p, : len(train.index[e, p::k])], train.index[e, p::k])
    xs, present, ys = sub.batch(np.array([1]))  # prev_task is the previous sub-goal step's
    task = torch.stack([ys[0][key] for key in ("kind", "object", "receptacle", "room")], -1)
    assert torch.equal(xs[0]["prev_task"][0, 1:], task[0, :-1])


def test_agents_deciding_every_4_steps_run_their_models_and_exchange_only_then(
    tmp_path, monkeypatch
):
    from maniskill_tidy.eval.episode import play_episode
    from maniskill_tidy.eval.runner import RunConfig, make_env
    from maniskill_tidy.models.decision import StateExtractor
    from maniskill_tidy.policies import make_team
    from maniskill_tidy.policies.learned import learned_team_class

    config = tmp_path / "every4.yaml"
    config.write_text(
        f"base: {Path('agents/hangrcom.yaml').resolve()}\n"
        "name: every4-test\nact: {decide_every: 4}\n"
    )
    team = learned_team_class(config)()
    monkeypatch.setenv("TIDY_AGENT_PROCESSES", "0")  # count the calls in this process
    calls = []
    real = StateExtractor.forward

    def counted(self, *args, **kwargs):  # F_s: the first model an agent runs to decide
        calls.append(self)
        return real(self, *args, **kwargs)

    env = make_env(RunConfig("hangrcom", "I", "test", None, 1))
    env.unwrapped.max_steps = 12
    try:
        with monkeypatch.context() as patch:
            patch.setattr(StateExtractor, "forward", counted)
            every4 = play_episode(env, team, 0, 0, [Legal()])
        every1 = play_episode(env, make_team("hangrcom"), 0, 0, [Legal()])
    finally:
        env.close()
    assert len(calls) == 3 * 3  # 3 agents at steps 0, 4 and 8 of 12
    assert 0 < every4.comm < every1.comm / 2  # HanGrCom's vectors cross only at those steps


def test_a_config_refuses_a_cadence_that_is_not_a_positive_integer(tmp_path):
    config = tmp_path / "bad.yaml"
    base = Path("agents/hangrcom.yaml").resolve()
    config.write_text(f"base: {base}\nact: {{decide_every: 0}}\n")
    with pytest.raises(ValueError, match="act decide_every 0: expected an integer >= 1"):
        AgentConfig.load(config).acting()
    config.write_text(f"base: {base}\nmodel: {{decide_every: 2.5}}\n")
    with pytest.raises(ValueError, match="model decide_every 2.5: expected an integer >= 1"):
        AgentConfig.load(config).decision()


def test_an_agent_that_sends_between_its_sub_goal_steps_is_stopped(monkeypatch):
    """The runner makes a step between sub-goal steps one call per agent with empty inboxes
    (``Agent.quiet_step``), which is only what the agents would have read if nobody sends
    then: an agent that does is an error naming it and the step, not a message lost."""
    from maniskill_tidy.eval.episode import play_episode
    from maniskill_tidy.eval.runner import RunConfig, make_env
    from maniskill_tidy.policies.learned import LearnedAgent, learned_team_class

    real = LearnedAgent.send

    def chatty(self, round, inbox):
        real(self, round, inbox)
        if not self.deciding:
            self.outbox.send([n for n in self.public.agents if n != self.name], [0.0], "chat")

    monkeypatch.setattr(LearnedAgent, "send", chatty)
    team = learned_team_class("agents/experiments/hangrcom-every4-untrained.yaml")()
    monkeypatch.setenv("TIDY_AGENT_PROCESSES", "0")  # its agents here, where send is patched
    env = make_env(RunConfig("hangrcom", "I", "test", None, 1))
    env.unwrapped.max_steps = 3
    try:
        between = r"agent_\d \(chat\).* sent at step 1, between the team's sub-goal steps"
        with pytest.raises(RuntimeError, match=between):
            play_episode(env, team, 0, 0)
    finally:
        env.close()
