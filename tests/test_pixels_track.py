"""The pixels track: what a pixels team's agents receive (no segmentation, no instance id),
a tiny segmenter's masks feeding a camera-only team's map, and runs that are their own rows
and replay."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from maniskill_tidy.policies.base import Agent, Team


class SpyAgent(Agent):
    seen: list = []
    failures: list = []

    def observe(self, view) -> None:
        self.seen.append((self.name, set(view.obs), int(view.obs.get("held", 0)),
                          dict(self.public.instances)))  # fmt: skip
        if view.failed:
            self.failures.append(view.failed)

    def act(self, inbox):
        return 8 if self.public.capability(self.name)[1] else 3  # PickUp, or turn


class SpyTeam(Team):
    name = "spy"

    def make_agent(self, name, public, outbox):
        return SpyAgent(name, public, outbox)


class PixelsSpyTeam(SpyTeam):
    pixels = True


@pytest.mark.parametrize("team_cls, pixels", [(SpyTeam, False), (PixelsSpyTeam, True)])
def test_a_pixels_team_receives_no_segmentation_and_no_instance_id(team_cls, pixels):
    """The env renders every image (as for a recording); the runner passes a pixels team none
    of the renderer's labels, held as a flag only, and the env's failure reasons without the
    object ids they name."""
    from maniskill_tidy.envs.hetero_tidy import HeteroTidyEnv
    from maniskill_tidy.eval.episode import Execution
    from maniskill_tidy.eval.runner import ALL_IMAGES

    env = HeteroTidyEnv(setting="I", split="test", obs_mode=ALL_IMAGES)
    SpyAgent.seen, SpyAgent.failures = [], []
    try:
        obs, info = env.reset(seed=0, options={"episode": 0})
        execution = Execution(team_cls(), env, 0)
        for _ in range(6):
            obs, _, _, _, info = env.step(execution.step(obs, info))
        held = [int(v) for v in env.get_obs()["agent_2"]["held"].reshape(-1)]
        objects = [i.id for i in env.instances.values() if i.kind == "object"]
    finally:
        env.close()
    # the env's reasons name objects ("already holding HandTowel_0"); a pixels agent's do not
    named = [f for f in SpyAgent.failures if any(o in f for o in objects)]
    assert SpyAgent.failures and (not named if pixels else named)
    keys = set.union(*(k for _, k, _, _ in SpyAgent.seen))
    tables = [t for *_, t in SpyAgent.seen]
    if pixels:
        assert "segmentation" not in keys and {"rgb", "depth", "pose", "intrinsics"} <= keys
        assert all(t == {} for t in tables)
        assert {h for _, _, h, _ in SpyAgent.seen} <= {0, 1}
    else:  # the ground-truth track: the renderer's labels, as before
        assert "segmentation" in keys and all(len(t) > 10 for t in tables)
    assert held  # the env itself still knows the id


@pytest.fixture(scope="module")
def segmenter(tmp_path_factory):
    """A tiny segmenter trained on one house per split (a few seconds; it sees little)."""
    from maniskill_tidy.training.segmenter_data import SegDataConfig, build_segmenter_data
    from maniskill_tidy.training.segmenter_trainer import SegTrainConfig, train_segmenter

    root = tmp_path_factory.mktemp("pixels")
    for split in ("train", "val", "test"):
        cfg = SegDataConfig(None, split, "HeteroTidy-v1", every=3, max_steps=13, houses=1)
        build_segmenter_data(cfg, root / "data" / split, progress=False)
    # unweighted classes: in 3 epochs it learns the floor and walls (pixel accuracy ~0.35 on
    # val), what a map is made of; with the objects weighted up it learns next to nothing
    cfg = SegTrainConfig(str(root / "data"), str(root / "segmenter-tiny"), epochs=3, batch=4,
                         crop=96, widths=(8, 12, 16, 16, 16), lr=0.01,
                         weight_power=0.0)  # fmt: skip
    train_segmenter(cfg, progress=False)
    return root / "segmenter-tiny"


def _play(segmenter, steps: int):
    """A pixels heuristic team's first steps: (its agent_1, every step's actions and info)."""
    from maniskill_tidy.envs.hetero_tidy import HeteroTidyEnv
    from maniskill_tidy.eval.episode import Execution
    from maniskill_tidy.policies import make_team
    from maniskill_tidy.policies.pixels import PixelsTeam

    env = HeteroTidyEnv(setting="I", split="test", obs_mode="rgb+depth", targets="pixels")
    trace = []
    try:
        obs, info = env.reset(seed=0, options={"episode": 0})
        execution = Execution(PixelsTeam(make_team("heuristic-none"), str(segmenter)), env, 0)
        for _ in range(steps):
            actions = execution.step(obs, info)
            obs, _, _, _, info = env.step(actions)
            trace.append((actions, info["failed"]))
        return execution.agents["agent_1"], obs, trace
    finally:
        env.close()


def test_predicted_masks_feed_a_heuristic_agents_map_and_replay(segmenter, monkeypatch):
    """The inner team's map is fed each frame's predicted ids, and its voxels carry only the
    labels of what was predicted. (How much a 3-epoch segmenter predicts varies with the
    renders it trained on: the test asserts the wiring, not the segmenter's quality.)"""
    from maniskill_tidy.perception.semantic_map import SemanticMap

    fed, update = [], SemanticMap.update

    def spy(self, obs):
        fed.append((self, np.array(obs["segmentation"])))
        return update(self, obs)

    monkeypatch.setattr(SemanticMap, "update", spy)
    agent, obs, trace = _play(segmenter, 8)
    monkeypatch.setattr(SemanticMap, "update", update)
    _, _, again = _play(segmenter, 8)
    assert trace == again  # same seed, same pixels team, same steps
    assert "segmentation" not in obs["agent_1"]
    ids = set(np.unique(agent.seg).tolist())
    assert ids - {0} and ids <= set(agent.table.instances) | {0}
    own = agent.inner.map
    segs = [seg for m, seg in fed if m is own]
    assert own.frames == len(segs) == 8 and np.array_equal(segs[-1], agent.seg)
    predicted = set(np.unique(own.labels[np.concatenate([s.ravel() for s in segs])]).tolist())
    stored = set(np.unique(own.voxels).tolist()) - {0}
    assert stored and stored <= predicted  # its map, built from the predicted ids' labels
    assert own.explored.any()


@pytest.mark.parametrize("key, before", [("segmenter_sha256", "0" * 64), ("pixels_pipeline", None)])
def test_a_pixels_run_is_not_resumed_with_other_segmenter_weights_or_pipeline(
    segmenter, tmp_path, monkeypatch, key, before
):
    """Its episodes would mix two segmenters under the sha256 of the last, or two ways of
    reading its labels: refused at once, for that field alone (every other argument of the
    run.json the runner wrote is the same; ``None``: a run from before the field)."""
    from maniskill_tidy.eval.runner import RunConfig, RunFile, evaluate, run_dir

    class Started(Exception):
        pass

    def start_then_stop(self, directory, config):
        write(self, directory, config)
        raise Started

    cfg = RunConfig("heuristic-none", "I", "test", None, episodes=1,
                    segmentation=str(segmenter))  # fmt: skip
    write = RunFile.__init__
    monkeypatch.setattr(RunFile, "__init__", start_then_stop)
    with pytest.raises(Started):  # run.json written, no episode played
        evaluate(cfg, tmp_path, workers=1, progress=False)
    monkeypatch.undo()
    path = run_dir(tmp_path, cfg) / "run.json"
    started = json.loads(path.read_text())
    now = started.pop(key)
    if before is not None:
        started[key] = before
    path.write_text(json.dumps(started))
    diff = re.escape(str({key: (before, now)}))
    with pytest.raises(ValueError, match=f"other arguments {diff} "):
        evaluate(cfg, tmp_path, workers=1, progress=False)
    assert not (path.parent / "episodes.jsonl").exists()


@pytest.mark.slow  # two whole heuristic episodes through a segmenter: minutes
def test_a_pixels_run_is_its_own_row_records_its_segmenter_and_replays(segmenter, tmp_path):
    from maniskill_tidy.eval.runner import RunConfig, evaluate

    cfg = RunConfig("heuristic-none", "I", "test", None, episodes=1,
                    segmentation=str(segmenter))  # fmt: skip
    a = evaluate(cfg, tmp_path / "a", workers=1, progress=False)
    sha = json.loads((segmenter / "card.json").read_text())["int8"]["sha256"]  # what ran
    assert a["segmentation"] == f"learned:{sha}" and a["obs_mode"] == "rgb+depth"
    assert a["policy"] == "heuristic-none-pixels-segmenter-tiny"
    evaluate(cfg, tmp_path / "b", workers=1, progress=False)
    rows = [
        [json.loads(line) for line in (t / "eval/results/setting_I" / a["policy"] /
                                       "episodes.jsonl").read_text().splitlines()]
        for t in (tmp_path / "a", tmp_path / "b")
    ]  # fmt: skip
    for r in rows:
        for rec in r:
            rec.pop("seconds")
    assert rows[0] == rows[1]  # same seed, same pixels-team records
    with pytest.raises(ValueError, match="camera-only"):
        expert = RunConfig("expert", "I", "test", None, episodes=1, segmentation=str(segmenter))
        evaluate(expert, tmp_path / "c", progress=False)


@pytest.mark.slow  # a whole heuristic episode through a segmenter, and its replay
def test_the_teams_bench_times_a_pixels_team_and_its_stages(segmenter):
    from maniskill_tidy.eval.team_benchmark import bench_team, report

    row = bench_team("heuristic-none", episodes=1, segmentation=str(segmenter))
    assert row["team"] == f"heuristic-none-pixels ({segmenter})" and row["ratio"] > 1.0
    ms = row["ms_per_frame"]
    assert row["frames"] >= 3 and all(v > 0 for v in ms.values())
    # the stages are part of the team's time, never more than it
    assert sum(ms.values()) * row["frames"] / 1000 < row["team_s"]
    text = report([row], [])
    assert "heuristic-none-pixels" in text and "segmenter (ONNX Runtime" in text


def test_show_masks_draws_each_agents_frame_beside_the_truth(segmenter, tmp_path):
    from maniskill_tidy.eval.masks_figure import masks_figure
    from tests.test_cli_errors import cli, one_line_error

    out = masks_figure(tmp_path / "masks.png", str(segmenter), "HeteroTidy-v1", steps=6)
    assert out.read_bytes()[:4] == b"\x89PNG"
    one_line_error(cli("show-masks", "--segmenter", str(tmp_path / "none"), "--out",
                       str(tmp_path / "m.png")), "model.pt not found")  # fmt: skip
    one_line_error(cli("show-masks", "--segmenter", str(segmenter), "--out",
                       str(tmp_path / "m.jpg")), "expected a .png")  # fmt: skip
    assert not (tmp_path / "m.png").exists()


def test_a_segmenter_of_another_class_table_is_refused(segmenter, tmp_path):
    import shutil

    from maniskill_tidy.policies.pixels import Segmenter

    other = tmp_path / "other"
    shutil.copytree(segmenter, other)
    card = json.loads((other / "card.json").read_text())
    card["config"]["classes"] = "000000000000"  # trained before the object types changed
    (other / "card.json").write_text(json.dumps(card))
    with pytest.raises(ValueError, match="another class table"):
        Segmenter(str(other))
    own = json.loads((segmenter / "card.json").read_text())
    assert Segmenter(str(segmenter)).sha256 == own["int8"]["sha256"]  # its own table: loads
