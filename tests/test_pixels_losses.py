"""What became of each misplaced object in a pixels run, judged against the renderer's masks:
the fates are told apart, and association errors and false pickups are counted."""

from __future__ import annotations

import json
from types import SimpleNamespace as NS

import numpy as np

from maniskill_tidy.eval.pixels_losses import FATES, PixelsLosses, summarise
from maniskill_tidy.sim.house_scene import Instance


def _world():
    env = NS(
        misplaced=["Apple_0", "Mug_0", "Cup_0", "Book_0"],
        manipulation=NS(
            types={"Apple_0": "Apple", "Mug_0": "Mug", "Cup_0": "Cup", "Book_0": "Book"}
        ),  # fmt: skip
        instances={
            5: Instance(5, "object", "Apple", "Apple_0"),
            6: Instance(6, "object", "Mug", "Mug_0"),
            7: Instance(7, "object", "Cup", "Cup_0"),
            8: Instance(8, "object", "Book", "Book_0"),
            9: Instance(9, "object", "Plate", "Plate_0"),
        },  # fmt: skip
        agents=[NS(name="agent_0", held=None)],
        picked={"Book_0"},
        is_reasonable=lambda oid: oid == "Book_0",
    )
    table = NS(instances={1024: Instance(1024, "object", "Apple", "Apple#0"),
                          1025: Instance(1025, "object", "Apple", "Apple#1"),
                          1026: Instance(1026, "object", "Apple", "Apple#2"),
                          16: Instance(16, "furniture", "Table", "Table_0")})  # fmt: skip
    agent = NS(seg=None, table=table, aimed=1026)
    return env, agent


def test_fates_tracks_merges_and_false_pickups():
    env, agent = _world()
    losses = PixelsLosses()
    losses.start(env, None, None)
    losses.executing({"agent_0": agent})
    truth = np.zeros((40, 40), dtype=np.int32)
    truth[0:10, 0:10] = 5  # the apple
    truth[20:30, 0:10] = 6  # the mug
    truth[20:30, 20:30] = 9  # a plate, in place
    truth[0:2, 30:32] = 7  # the cup: 4 pixels, too few to be in view
    for step, apple_slot in enumerate((1024, 1025)):
        seg = np.zeros_like(truth)
        seg[0:10, 0:10] = apple_slot  # the apple, seen as a new track the second time
        seg[20:30, 0:10] = 1026  # the mug, taken for an apple ...
        seg[20:30, 20:30] = 1026  # ... in one mask with the plate: IoU 0.5, merged
        agent.seg = seg
        losses.observed(step, {"agent_0": {"segmentation": truth}}, {})
        losses.decided(step, {"agent_0": 0}, {})
    env.agents[0].held = "Plate_0"  # the plate, picked up though it was in place
    losses.log_step(2, None, None, None, None, None)
    out = losses.result()
    fates = {o["type"]: o for o in out["objects"]}
    assert fates["Apple"]["fate"] == "detected, not picked" and fates["Apple"]["tracks"] == 2
    assert not fates["Apple"]["merged"]
    assert fates["Mug"]["fate"] == "wrong type" and fates["Mug"]["merged"]
    assert fates["Cup"]["fate"] == "never in view"
    assert fates["Book"]["fate"] == "placed"
    assert out["false_pickups"] == 1
    assert out["in_place_picked"] == [{"type": "Plate", "believed": "Apple"}]
    assert fates["Apple"]["largest_view"] == 100 and fates["Cup"]["largest_view"] == 0

    summary = summarise([{"pixels": out}, {"success": True}])  # ground-truth records: no key
    assert summary["objects"] == 4 and summary["episodes"] == 2
    assert summary["fates"]["wrong type"] == 1 and sum(summary["fates"].values()) == 4
    assert list(summary["fates"]) == list(FATES)
    assert summary["split_into_tracks"] == 1 and summary["merged_with_another"] == 1
    assert summary["by_type"]["Mug"] == {"wrong type": 1}
    assert summary["median_largest_view"]["wrong type"] == 100
    assert summary["in_place_picked_as"] == {"another type": 1}


def test_an_object_in_view_without_a_mask_is_never_detected():
    env, agent = _world()
    losses = PixelsLosses()
    losses.start(env, None, None)
    losses.executing({"agent_0": agent})
    truth = np.zeros((40, 40), dtype=np.int32)
    truth[0:10, 0:10] = 5
    agent.seg = np.zeros_like(truth)
    agent.seg[0:10, 0:3] = 1024  # a sliver of it: IoU 0.3
    losses.observed(0, {"agent_0": {"segmentation": truth}}, {})
    losses.decided(0, {"agent_0": 0}, {})
    fates = {o["type"]: o["fate"] for o in losses.result()["objects"]}
    assert fates["Apple"] == "never detected" and fates["Mug"] == "never in view"


def test_the_command_reads_a_pixels_run_and_refuses_another(tmp_path):
    from tests.test_cli_errors import cli, one_line_error

    env, agent = _world()
    losses = PixelsLosses()
    losses.start(env, None, None)
    out = losses.result()  # nothing seen: the book placed, the rest never in view
    run = tmp_path / "run"
    run.mkdir()
    (run / "episodes.jsonl").write_text(json.dumps({"episode": "e", "pixels": out}) + "\n")
    p = cli("pixels-losses", str(run), "--json", str(tmp_path / "l.json"))
    assert p.returncode == 0, p.stderr
    assert "| never in view | 3 | 0.75 |" in p.stdout and "| placed | 1 | 0.25 |" in p.stdout
    assert json.loads((tmp_path / "l.json").read_text())["objects"] == 4
    (run / "episodes.jsonl").write_text(json.dumps({"episode": "e", "success": True}) + "\n")
    one_line_error(cli("pixels-losses", str(run)), "no record holds object fates")
    one_line_error(cli("pixels-losses", str(tmp_path / "none")), "no episodes.jsonl")


def test_object_fates_plays_a_camera_team_and_refuses_the_expert(tmp_path):
    from tests.test_cli_errors import cli, one_line_error

    p = cli("object-fates", "heuristic-none", "--split", "test", "--episodes", "1",
            "--workers", "1", "--out", str(tmp_path / "fates.jsonl"))  # fmt: skip
    assert p.returncode == 0, p.stderr[-2000:]
    rows = [json.loads(line) for line in (tmp_path / "fates.jsonl").read_text().splitlines()]
    assert rows and all(r["fate"] in ("never in view", "in view, never picked",
                                      "picked, not placed", "placed") for r in rows)  # fmt: skip
    assert "heuristic-none, Setting I, test: 1 episodes" in p.stdout
    one_line_error(cli("object-fates", "expert"), "expected a camera team")
    one_line_error(cli("object-fates", "memory", "--episodes", "0"), "expected a positive")


def test_unsolved_objects_replays_a_runs_failed_episodes(tmp_path):
    from tests.test_cli_errors import cli, one_line_error

    p = cli("eval", "--policy", "random", "--setting", "I", "--episodes", "1", "--env",
            "HeteroTidy-v1", "--out", str(tmp_path))  # fmt: skip
    assert p.returncode == 0, p.stderr[-2000:]
    run = tmp_path / "eval/results/setting_I/random"
    p = cli("unsolved-objects", str(run))
    assert p.returncode == 0, p.stderr[-2000:]
    lines = p.stdout.splitlines()
    assert lines[0] == "1 of 1 episodes failed (random, HeteroTidy-v1)"
    rows = [line.split(" | ") for line in lines[2:]]
    assert rows and all(len(r) == 5 and r[3] in ("True", "False") for r in rows)
    one_line_error(cli("unsolved-objects", str(tmp_path)), "no run.json")
