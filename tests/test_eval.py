"""Metrics on hand-made episode logs, communication accounting, the resumable runner."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from maniskill_tidy.eval.leaderboard import misprints, paper_reference, table, write_leaderboard
from maniskill_tidy.eval.metrics import EpisodeRecord, ces, summarize
from maniskill_tidy.eval.paper_tables import extract
from maniskill_tidy.eval.runner import (
    RunConfig,
    evaluate,
    exclusive,
    read_records,
    run_dir,
    select,
)
from maniskill_tidy.policies.channel import CENTRAL, Channel

REFERENCE = Path(__file__).resolve().parents[2] / "shared" / "reference"


def rec(kind: str, k: int, reasonable: int, found: int, length: int, comm: int, agents: int = 3):
    return EpisodeRecord(
        episode=f"e{kind}{k}{reasonable}{length}",
        task_kind=kind,
        k=k,
        success=reasonable == k,
        reasonable=reasonable,
        found=found,
        length=length,
        comm=comm,
        agents=agents,
        seed=0,
    )


def test_metrics_follow_the_paper_definitions():
    records = [
        rec("Single", 2, 2, 2, 100, 3 * 100 * 820),  # success, ACm 820
        rec("Single", 4, 1, 3, 300, 0),  # partial: 1/4 placed, 3/4 found
        rec("Cross", 5, 0, 0, 300, 3 * 300 * 10),
    ]
    m = summarize(records)
    assert m["Single"]["Success"] == pytest.approx(0.5)
    assert m["Single"]["%PS"] == pytest.approx((1.0 + 0.25) / 2)
    assert m["Single"]["%FM"] == pytest.approx((1.0 + 0.75) / 2)
    assert m["Single"]["#PL"] == pytest.approx(200.0)
    assert m["Single"]["ACm"] == pytest.approx(410.0)
    assert m["Cross"]["Success"] == 0.0 and m["Cross"]["ACm"] == pytest.approx(10.0)
    assert m["All"]["Success"] == pytest.approx(1 / 3)
    assert m["All"]["%PS"] == pytest.approx((1.0 + 0.25 + 0.0) / 3)
    assert m["All"]["episodes"] == 3


def test_paired_differences_use_only_the_episodes_both_runs_played():
    from dataclasses import replace

    from maniskill_tidy.eval.metrics import paired_difference

    b = [replace(rec("Single", 4, 1, 2, 300, 0), episode=f"e{i}") for i in range(6)]
    a = [replace(r, reasonable=3, found=4, failed_actions=i) if i < 2 else r
         for i, r in enumerate(b)]  # fmt: skip
    a[2] = replace(a[2], length=250, comm=30)  # shorter, but talks more
    a[3] = replace(a[3], seconds=99.0)  # played slower, otherwise the same record
    a.append(replace(b[0], episode="only-in-a", reasonable=4, success=True, failed_actions=50))
    d = paired_difference(a, b)
    assert d["episodes"] == 6
    # totals count only the shared episodes: "only-in-a" adds neither its 4 objects nor 50 fails
    totals_a = {"placed": 2 * 3 + 4 * 1, "misplaced": 24, "failed_per_episode": 1 / 6,
                "agent_steps_per_episode": (5 * 300 + 250) * 3 / 6}  # fmt: skip
    assert d["totals"]["A"] == totals_a
    assert d["totals"]["B"]["placed"] == 6 and d["totals"]["B"]["failed_per_episode"] == 0
    assert d["%PS"]["difference"] == pytest.approx(2 * (3 - 1) / 4 / 6)
    assert (d["%PS"]["better"], d["%PS"]["worse"]) == (2, 0)
    assert d["#PL"]["difference"] == pytest.approx(-50 / 6)
    assert (d["#PL"]["better"], d["#PL"]["worse"]) == (1, 0)  # fewer steps is better
    assert (d["ACm"]["better"], d["ACm"]["worse"]) == (0, 1)  # more messages is worse
    assert d["%FM"]["difference"] == pytest.approx(2 * (4 - 2) / 4 / 6)
    assert d["Success"]["difference"] == 0 and d["Success"]["ci95"] == [0.0, 0.0]
    assert d["same_success"] == 6 and d["identical"] == 3  # a[0..2] differ; wall time does not
    lo, hi = d["%PS"]["ci95"]
    assert 0 <= lo < d["%PS"]["difference"] < hi
    with pytest.raises(ValueError, match="no episode in common"):
        paired_difference(a[-1:], b)


def test_ces_against_the_single_agent_baseline():
    assert ces(0.103, 0.038, 364.6) == pytest.approx(1.78, abs=0.01)  # the paper's "Ours", I
    assert ces(0.03, 0.038, 20.0) == 0.0  # worse than SA: clipped at 0
    assert ces(0.5, 0.0, 0.0) is None  # no communication: undefined


def test_channel_counts_every_dimension_received():
    ch = Channel(["a", "b", "c"])
    ch.send("a", ["b", "c"], np.zeros(410), "state+map")  # a broadcast of 410 values
    ch.send("b", "c", np.zeros((2, 3)), "detections")
    assert ch.step_total == 820 + 6 and ch.total == 826
    assert [m.sender for m in ch.inbox("c")] == ["a", "b"]
    assert ch.matrix()[0, 1] == 410 and ch.matrix()[1, 2] == 6 and ch.matrix()[2].sum() == 0
    assert ch.groups() == [["a", "b", "c"]]
    ch.new_step()
    assert ch.step_total == 0 and ch.total == 826 and ch.inbox("c") == []
    assert ch.groups() == [["a"], ["b"], ["c"]]
    with pytest.raises(KeyError, match="unknown endpoint"):
        ch.send("a", "z", [1.0], "x")
    with pytest.raises(KeyError, match="unknown endpoint"):
        ch.send("a", CENTRAL, [1.0], "x")  # no central node in this channel
    hub = Channel(["a", "b"], central=True)
    hub.send("a", CENTRAL, [1.0, 2.0], "state")
    hub.send(CENTRAL, "b", [3.0], "assignment")
    assert hub.total == 3 and hub.groups() == [["a", "b"]]


def test_episode_selection_follows_the_protocol():
    starts = [s for _ in range(200) for s in range(5)]  # 200 meta-tasks x 5 starts
    standard = select(starts, "standard")
    assert len(standard) == 200 and all(starts[i] == 0 for i in standard)
    assert select(starts, "all") == list(range(1000))
    assert select(starts, 4) == [0, 250, 500, 750]
    assert select(starts, "4") == [0, 250, 500, 750]
    for bad in (0, -3, "1.5", "some", "4x"):
        with pytest.raises(ValueError, match="--episodes"):
            select(starts, bad)


def test_bootstrap_intervals_are_seeded_and_cover_the_mean():
    records = [rec("Single", 2, 2 * (i % 3 == 0), 2, 50 + i, 0) for i in range(60)]
    a, b = summarize(records), summarize(records)
    assert a == b  # seeded: the same records give the same intervals
    m = a["All"]
    for metric in ("Success", "%PS", "#PL"):
        lo, hi = m["ci95"][metric]
        assert lo < m[metric] < hi
    lo, hi = m["ci95"]["Success"]
    assert 0.15 < hi - lo < 0.5  # about 2 x 1.96 x sqrt(p (1 - p) / n) for p = 1/3, n = 60
    wider = summarize(records[:15])["All"]["ci95"]["Success"]
    assert wider[1] - wider[0] > hi - lo  # fewer episodes, wider interval


def test_read_records_cuts_a_torn_last_line(tmp_path):
    path = tmp_path / "episodes.jsonl"
    good = json.dumps(rec("Single", 1, 1, 1, 10, 0).to_dict()) + "\n"
    path.write_text(good + good[: len(good) // 2])
    assert len(read_records(path)) == 1
    assert path.read_text() == good


def _eval(out, extra=()):
    # v1, the look the RunConfig runs below default to (old run files name none)
    cmd = [sys.executable, "-m", "maniskill_tidy.cli", "eval", "--policy", "expert", "--env",
           "HeteroTidy-v1"]  # fmt: skip
    cmd += ["--episodes", "3", "--split", "test", "--out", str(out), *extra]
    return cmd


def test_runner_resumes_after_a_kill_with_the_same_totals(tmp_path):
    full = subprocess.run(_eval(tmp_path / "full"), capture_output=True, text=True, timeout=600)
    assert full.returncode == 0, full.stderr
    from maniskill_tidy.common.parallel import auto_workers

    summary = json.loads((tmp_path / "full/eval/results/setting_I/expert/summary.json").read_text())
    assert summary["workers"] == auto_workers(3)  # --workers auto, the default
    proc = subprocess.Popen(_eval(tmp_path / "cut"), stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    jsonl = tmp_path / "cut/eval/results/setting_I/expert/episodes.jsonl"
    deadline = time.time() + 300
    while time.time() < deadline and not (jsonl.exists() and jsonl.read_text().count("\n") >= 1):
        time.sleep(0.2)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    partial = jsonl.read_text().count("\n")
    assert 1 <= partial < 3
    run = json.loads((jsonl.parent / "run.json").read_text())  # the killed session's share kept
    assert run["wall_seconds"] > 0 and run["code_versions"]
    again = subprocess.run(_eval(tmp_path / "cut"), capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr
    lines = [json.loads(x) for x in jsonl.read_text().splitlines()]
    assert len(lines) == 3 and len({x["episode"] for x in lines}) == 3
    a = json.loads((tmp_path / "full/eval/results/setting_I/expert/summary.json").read_text())
    b = json.loads((tmp_path / "cut/eval/results/setting_I/expert/summary.json").read_text())
    assert a["metrics"] == b["metrics"] and a["dataset_hash"] == b["dataset_hash"]
    refused = subprocess.run(
        _eval(tmp_path / "cut", ["--seed", "5"]), capture_output=True, text=True, timeout=600
    )
    assert refused.returncode != 0 and "other arguments" in refused.stderr


# ---------------------------------------------------------------------- runs, workers, the floor
def _records(path) -> list[dict]:
    rows = [json.loads(x) for x in path.read_text().splitlines()]
    for r in rows:
        r.pop("seconds")
    return sorted(rows, key=lambda r: r["episode"])


def test_one_and_two_workers_give_identical_episode_records(tmp_path):
    """One worker plays every episode after another in one env, two split them: an episode
    must not depend on what its worker played before."""
    cfg = RunConfig("expert", "I", "test", None, 4)
    for w in (1, 2):
        evaluate(cfg, tmp_path / f"w{w}", workers=w, progress=False)
    tail = "eval/results/setting_I/expert/episodes.jsonl"
    assert _records(tmp_path / "w1" / tail) == _records(tmp_path / "w2" / tail)
    cfg = RunConfig("random", "II", "test", None, 3)  # per-agent random streams, 4 agents
    for w in (1, 2):
        evaluate(cfg, tmp_path / f"r{w}", workers=w, progress=False)
    tail = "eval/results/setting_II/random/episodes.jsonl"
    assert _records(tmp_path / "r1" / tail) == _records(tmp_path / "r2" / tail)


def test_a_second_run_on_the_same_results_folder_is_refused(tmp_path):
    """Two runs appending to one episodes.jsonl would play and count episodes twice."""
    cfg = RunConfig("random", "I", "test", None, 2)
    directory = run_dir(tmp_path, cfg)
    directory.mkdir(parents=True)
    with exclusive(directory):
        with pytest.raises(ValueError, match="being written by another eval run"):
            evaluate(cfg, tmp_path, progress=False)
    assert not (directory / "episodes.jsonl").exists()
    assert evaluate(cfg, tmp_path, progress=False)["episodes"] == 2  # free once it ends


def test_a_learned_run_resumed_with_other_weights_is_refused(tmp_path, seeded_config):
    """A run's episodes must all come from one model: retraining between the start and the
    resumption of a run would otherwise mix two models' episodes in one row."""
    import torch

    config = seeded_config(tmp_path, "learned", "{}", settings=(("I", 3),))
    cfg = RunConfig(str(config), "I", "test", None, 1)
    evaluate(cfg, tmp_path / "out", progress=False)
    directory = run_dir(tmp_path / "out", cfg)
    fingerprint = json.loads((directory / "run.json").read_text())["model_hash"]
    assert evaluate(cfg, tmp_path / "out", progress=False)["episodes"] == 1  # same weights
    path = tmp_path / "learned" / "setting_I" / "model.pt"
    saved = torch.load(path, weights_only=False)
    first = next(k for k, v in saved["state"].items() if v.is_floating_point())
    saved["state"][first] = saved["state"][first] + 1
    torch.save(saved, path)
    before = (directory / "episodes.jsonl").read_bytes()
    with pytest.raises(ValueError, match=f"model_hash.*{fingerprint}"):
        evaluate(cfg, tmp_path / "out", progress=False)
    assert (directory / "episodes.jsonl").read_bytes() == before


def test_the_expert_solves_most_standard_test_episodes(tmp_path):
    cfg = RunConfig("expert", "I", "test", None, "standard")
    summary = evaluate(cfg, tmp_path, workers=2, progress=False)
    m = summary["metrics"]["All"]
    assert m["episodes"] == 20  # first start of each of the split's 20 meta-tasks
    assert summary["protocol"] == "standard"
    assert m["Success"] >= 0.85, m  # measured 0.95 on the 120-house test split (1000 episodes)
    assert m["ci95"]["Success"][0] <= m["Success"] <= m["ci95"]["Success"][1]


# ---------------------------------------------------------------------- leaderboard, paper tables
def _summary(policy: str, success: list[bool], acm_values: int, **extra) -> dict:
    records = [
        rec("Single" if i % 2 else "Cross", 2, 2 if ok else 0, 2, 100, acm_values * 100 * 3)
        for i, ok in enumerate(success)
    ]
    return {
        "policy": policy,
        "setting": "I",
        "team": [[1, 0, 0], [1, 0, 1], [1, 1, 1]],
        "communication": extra.get("communication", "none"),
        "privileged": False,
        "perception": "ground truth",
        "protocol": "standard",
        "dataset_hash": "abc" * 10,
        "code_version": extra.get("versions", ["v1"])[-1],
        "code_versions": extra.get("versions", ["v1"]),
        "episodes": len(records),
        "metrics": summarize(records),
        "episode_seconds_mean": 1.0,
    }


def test_a_row_played_under_a_teams_earlier_rules_is_marked_and_not_resumed(tmp_path):
    """A team whose rules changed on purpose (``Team.rules``): its old rows are marked on the
    leaderboard until re-run, and an old run folder is not resumed under the new rules."""
    from maniskill_tidy.policies import team_class
    from maniskill_tidy.policies.heuristic import HeuristicAgent

    assert HeuristicAgent.FULL_SURFACE_RULE  # the default that "full-surface" names
    assert team_class("heuristic-none").rules == "full-surface"
    assert team_class("agents/memory.yaml").rules == "full-surface"  # the same agent
    assert team_class("hangrcom").rules == "" and not hasattr(team_class("expert"), "rules")
    for policy, rules in [("heuristic-none", ""), ("heuristic-broadcast", "full-surface"),
                          ("hangrcom", "")]:  # fmt: skip
        folder = tmp_path / "results" / "setting_I" / policy
        folder.mkdir(parents=True)
        summary = {**_summary(policy, [True, False] * 5, 10), "rules": rules}
        (folder / "summary.json").write_text(json.dumps(summary))
        (folder / "run.json").write_text(json.dumps({"policy": policy}))
    md = write_leaderboard(tmp_path).read_text()
    marked = {line.split("|")[1].strip() for line in md.splitlines() if "¶ |" in line}
    assert marked == {"**heuristic-none** ¶"}
    assert "¶ heuristic-none: played under the team's rules 'as first played', not today's " \
        "'full-surface'" in md  # fmt: skip

    # two episodes on two workers: a renderer made in pytest's own process crashes it later
    cfg = RunConfig("heuristic-none", "I", "test", None, 2)
    summary = evaluate(cfg, tmp_path / "out", workers=2, progress=False)
    directory = run_dir(tmp_path / "out", cfg)
    run = json.loads((directory / "run.json").read_text())
    assert run["rules"] == summary["rules"] == "full-surface"
    assert evaluate(cfg, tmp_path / "out", workers=2, progress=False)["episodes"] == 2  # resumed
    del run["rules"]  # as a run made before the rule
    (directory / "run.json").write_text(json.dumps(run))
    lines = (directory / "episodes.jsonl").read_text()
    with pytest.raises(ValueError, match="other arguments .'rules': .None, 'full-surface'"):
        evaluate(cfg, tmp_path / "out", workers=2, progress=False)
    assert (directory / "episodes.jsonl").read_text() == lines


def test_a_pixels_row_played_with_another_segmenter_than_the_one_that_ships_says_so():
    """A pixels row records the sha256 of what its agents ran and how they read its labels;
    once the segmenter it names is retrained, or the agents read labels otherwise, its row is
    to be played again, and the From-pixels table says so."""
    from maniskill_tidy.eval.leaderboard import pixels_table
    from maniskill_tidy.models.checkpoints import served_sha256
    from maniskill_tidy.policies.pixels import PIXELS_PIPELINE

    shipped = served_sha256(Path("agents/segmenter-v2"))
    other_look = served_sha256(Path("agents/segmenter-v1"))
    runs = {
        name: {**_summary(name, [True, False], 1), "env": "HeteroTidy-v2",
               "segmentation": f"learned:{sha}", "pixels_pipeline": PIXELS_PIPELINE}
        for name, sha in [("memory-v2-pixels", shipped), ("heuristic-none-v2-pixels", "0" * 64),
                          ("memory-v2-pixels-segmenter-v1", other_look),
                          ("heuristic-none-v2-pixels-segmenter-v1", shipped),
                          ("memory-links-v2-pixels", shipped)]
    }  # fmt: skip
    del runs["memory-links-v2-pixels"]["pixels_pipeline"]  # played before it was recorded
    rows = {line.split("|")[1].strip(): line for line in pixels_table(runs, {}).splitlines()[2:]}
    assert f"its own look's ({shipped[:12]}) |" in rows["**memory-v2-pixels**"]
    before = f"({shipped[:12]}; before the {PIXELS_PIPELINE!r} pipeline) |"
    assert before in rows["**memory-links-v2-pixels**"]
    assert "(000000000000; not the one that ships)" in rows["**heuristic-none-v2-pixels**"]
    assert f"segmenter-v1 ({other_look[:12]}) |" in rows["**memory-v2-pixels-segmenter-v1**"]
    stale = f"segmenter-v1 ({shipped[:12]}; not the one that ships)"
    assert stale in rows["**heuristic-none-v2-pixels-segmenter-v1**"]


def test_paper_figures_whose_all_lies_outside_single_and_cross_are_flagged():
    """All averages the Single and Cross episodes; the paper's Table 6 prints two rows where it
    cannot (w/o Know. %PS All 0.010, w/o HierDec. %PS Cross 0.99)."""
    row = [0.10, 0.20, 0.151, 0.1, 0.2, 0.25, 0.5, 0.6, 0.55, 200.0, 250.0, 250.1,
           300.0, 400.0, 350.0, 2.0, 1.0, 3.0]  # fmt: skip
    assert misprints(row) == ["%PS"]  # rounding slack kept, CES (a ratio) not checked
    reference = paper_reference()
    flagged = {
        (kind, setting, name): misprints(values)
        for kind in ("rows", "ablations")
        for setting, rows in reference[kind].items()
        for name, values in rows.items()
        if misprints(values)
    }
    assert flagged == {
        ("ablations", "II", "Ours w/o Know."): ["%PS"],
        ("ablations", "II", "Ours w/o HierDec."): ["%PS"],
    }
    md = table("II", {}, reference, "ablations")
    know = next(x for x in md.splitlines() if x.startswith("| Ours w/o Know."))
    assert know.split(" | ")[6] == "0.010 §"
    assert "§ Ours w/o Know. (paper): %PS Single 0.103, Cross 0.096, All 0.01" in md


def test_leaderboard_assembles_ces_intervals_and_notes(tmp_path):
    runs = {
        "sa": _summary("sa", [True, False, False, False] * 5, 0),
        "heuristic-broadcast": _summary(
            "heuristic-broadcast", [True, True, False, False] * 5, 820, communication="broadcast"
        ),
        "heuristic-central": _summary(
            "heuristic-central",
            [True, True, True, False] * 5,
            416,
            communication="central",
            versions=["v1", "v2"],
        ),
        "hangrcom": _summary(
            "hangrcom", [True, False, True, False] * 5, 240, communication="hangrcom"
        ),
    }
    runs["hangrcom"]["model_hash"] = "42e96e191cad5d14"
    for policy, s in runs.items():
        path = tmp_path / "results" / "setting_I" / policy / "summary.json"
        path.parent.mkdir(parents=True)
        path.write_text(json.dumps(s))
    md = write_leaderboard(tmp_path).read_text()
    rows = {
        line.split("|")[1].strip(): line.split("|")[2:-1]
        for line in md.splitlines()
        if line.startswith("| **")
    }
    broadcast = [c.strip() for c in rows["**heuristic-broadcast**"]]
    lo, hi = runs["heuristic-broadcast"]["metrics"]["All"]["ci95"]["Success"]
    assert broadcast[2] == f"0.500 [{lo:.3f}, {hi:.3f}]"  # Success All with its interval
    assert broadcast[-1] == f"{ces(0.5, 0.25, 820.0):.1f}"  # CES All against our SA row
    assert ces(0.5, 0.25, 820.0) == pytest.approx(10000 * 0.25 / 820)
    central_row = next(k for k in rows if "heuristic-central" in k)
    assert "‡" in central_row and "†" in "".join(rows[central_row])
    assert "the paper gives CentralComm. the broadcast figure" in md
    assert "code versions ['v1', 'v2']" in md
    assert "SA *(paper)*" in md  # the paper's rows beside ours
    lines = md.splitlines()
    ours = next(i for i, line in enumerate(lines) if line.startswith("| **hangrcom**"))
    assert lines[ours + 1].startswith("| Ours *(paper)* |")  # the learned row, then the paper's
    table_end = next(i for i in range(ours, len(lines)) if not lines[i].startswith("|"))
    assert not any("Ours *(paper)*" in line for line in lines[ours + 2 : table_end])
    assert (tmp_path / "leaderboard.png").read_bytes()[:4] == b"\x89PNG"
    assert "full protocol (every start" not in md  # no run of it yet
    runs_table = lines[lines.index("Runs:") + 2 :]
    weights = {r.split("|")[1].strip(): r.split("|")[8].strip() for r in runs_table if "|" in r}
    assert weights["hangrcom"] == "42e96e191cad5d14" and weights["sa"] == "-"


def test_a_full_protocol_run_gets_its_own_table_beside_the_standard_row(tmp_path):
    standard = _summary("hangrcom", [True, False] * 10, 240, communication="hangrcom")
    full = {**_summary("hangrcom", [True] + [False] * 49, 240, communication="hangrcom"),
            "protocol": "all"}  # fmt: skip
    for root, s in ((tmp_path, standard), (tmp_path / "all" / "eval", full)):
        path = root / "results" / "setting_I" / "hangrcom" / "summary.json"
        path.parent.mkdir(parents=True)
        path.write_text(json.dumps(s))
    md = write_leaderboard(tmp_path).read_text()
    before, after = md.split("The paper's full protocol (every start")
    success = [line.split("|")[4].strip() for line in md.splitlines()
               if line.startswith("| **hangrcom**")]  # fmt: skip
    assert success[0].startswith("0.500") and success[1].startswith("0.020")
    assert "| **hangrcom** |" in before and "| **hangrcom** |" in after.split("##")[0]
    assert "| hangrcom | " in after and "| all | 50 |" in after  # its details: protocol, episodes


def test_ablations_get_their_own_table_and_learned_rows_their_own_sa(tmp_path):
    from maniskill_tidy.eval.leaderboard import pareto_front

    learned = {"perception": "learned: small CNNs"}
    runs = {
        "sa": _summary("sa", [True, False, False, False] * 5, 0),
        "sa-learned": {**_summary("sa-learned", [True] + [False] * 9, 0), **learned},
        "hangrcom": {**_summary("hangrcom", [True, False] * 5, 240, communication="hangrcom"),
                     **learned},
        "wo_comm": {**_summary("wo_comm", [True, False, False, False] * 5, 0), **learned},
    }  # fmt: skip
    for policy, s in runs.items():
        path = tmp_path / "results" / "setting_I" / policy / "summary.json"
        path.parent.mkdir(parents=True)
        path.write_text(json.dumps(s))
    md = write_leaderboard(tmp_path).read_text()
    methods, ablations = md.split("Ablations (the paper's Table 5):")
    assert "| **wo_comm** |" in ablations and "| **wo_comm** |" not in methods
    lines = ablations.splitlines()
    i = next(k for k, line in enumerate(lines) if line.startswith("| **wo_comm** |"))
    assert lines[i + 1].startswith("| Ours w/o Comm. *(paper)* |")
    assert "| **hangrcom** |" in ablations  # the full model beside its ablations
    ours = next(line for line in methods.splitlines() if line.startswith("| **hangrcom** |"))
    assert ours.split("|")[-2].strip() == f"{ces(0.5, 0.1, 240.0):.1f}"  # against sa-learned
    assert pareto_front(runs) == [(0.0, 0.25), (240.0, 0.5)]
    without_wo_comm = {k: v for k, v in runs.items() if k != "wo_comm"}
    assert pareto_front(without_wo_comm) == [(0.0, 0.25), (240.0, 0.5)]  # the scripted sa
    assert pareto_front(without_wo_comm, learned_only=True) == [(0.0, 0.1), (240.0, 0.5)]
    # a learned team on ground-truth perception (the object-memory team) is a learned row
    memory = {**_summary("memory", [True] * 3 + [False], 300), "model_hash": "228bcdcab99f0bb9"}
    with_memory = {**without_wo_comm, "memory": memory}
    assert (300.0, 0.75) in pareto_front(with_memory, learned_only=True)


def test_the_papers_orderings_are_checked_on_our_learned_rows():
    from maniskill_tidy.eval.leaderboard import orderings

    runs = {
        "sa-learned": _summary("sa-learned", [True] + [False] * 19, 0),
        "hangrcom": _summary("hangrcom", [True, False] * 10, 240),
        "centralcomm": _summary("centralcomm", [True, False] * 10, 474),
        "condcomm": _summary("condcomm", [True, False, False, False] * 5, 400),
        "cmprcomm": _summary("cmprcomm", [True, False, False, False] * 5, 220),
        "wo_comm": _summary("wo_comm", [True, True, True, False] * 5, 0),  # beats Ours
    }
    found = {claim: (verdict, evidence) for claim, verdict, evidence in orderings(runs)}
    assert found["SA < Ours"][0] == "holds"  # 0.05 against 0.5: the intervals do not meet
    assert found["SA < Ours"][1].startswith("sa-learned 0.050 [")
    assert found["Ours <= CentralComm."][0] == "holds"  # equal Success
    assert found["Ours w/o Comm. < Ours"][0].startswith("fails")
    assert found["Ours w/o Know. < Ours"] == ("not run", "missing wo_know")
    assert found["QMIX < Ours"] == ("not run", "missing qmix")
    runs["qmix"] = _summary("qmix", [False] * 20, 512)
    found = {claim: (verdict, evidence) for claim, verdict, evidence in orderings(runs)}
    assert found["QMIX < Ours"][0] == "holds" and found["QMIX < Ours"][1].startswith("qmix 0.000")
    ces_claim = "Ours has the best CES among the partial-communication methods"
    assert found[ces_claim] == ("not run", "missing intencomm")
    runs["intencomm"] = _summary("intencomm", [True, False, False, False] * 5, 20)
    found = {claim: (verdict, evidence) for claim, verdict, evidence in orderings(runs)}
    assert found[ces_claim][0] == "fails"  # IntenComm. sends 20: its CES beats Ours'
    assert f"intencomm {ces(0.25, 0.05, 20.0):.1f}" in found[ces_claim][1]
    runs["intencomm"] = _summary("intencomm", [False] * 20, 20)
    found = {claim: (verdict, evidence) for claim, verdict, evidence in orderings(runs)}
    assert found[ces_claim][0] == "holds"
    runs["sa-learned"] = _summary("sa-learned", [True] * 20, 0)  # SA beats every row
    found = {claim: (verdict, evidence) for claim, verdict, evidence in orderings(runs)}
    assert found[ces_claim][0] == "fails (tied with condcomm, cmprcomm, intencomm)"  # all 0


SA_CELLS = "0.1 0.2 0.15 0.3 0.4 0.35 0.5 0.6 0.55 100.0 200.0 150.0 - - - - - -"
OURS_CELLS = (
    r"\textbf{0.121} 0.079 0.103 0.194 0.16 0.179 0.739 0.726 0.733 186.1 252.6 215.0 "
    "363.1 366.5 364.6 2.1 1.4 1.8"
)
TINY_TABLE = "\n".join(
    [
        r"\caption{x}\label{quan1}",
        r"\begin{tabular}{c|ccc}",
        r"\multirow{2}{*}{Methods} & \multicolumn{3}{c}{Success} \\",
        r"& Single & Cross & All & Single & Cross & All \\",
        "SA & " + " & ".join(SA_CELLS.split()) + r" \\",
        r"\rowcolor{lightgray!30} Ours & " + " & ".join(OURS_CELLS.split()) + r" \\",
        r"\end{tabular}",
    ]
)


def test_paper_tables_are_extracted_cell_by_cell():
    tex = TINY_TABLE + TINY_TABLE.replace("quan1", "quan2")
    ref = extract(tex)
    assert ref["rows"]["I"]["SA"][:3] == [0.1, 0.2, 0.15] and ref["rows"]["I"]["SA"][-1] is None
    assert ref["rows"]["I"]["Ours"][0] == 0.121  # bold stripped
    assert ref["rows"]["II"]["Ours"][-3:] == [2.1, 1.4, 1.8]
    assert len(ref["columns"]) == 18
    paper = REFERENCE / "../paper/heterogeneous-embodied-multi-agent-collaboration.tex"
    if paper.is_file():  # the shipped table is what the paper says
        shipped = extract(paper.read_text())
        assert shipped["rows"] == paper_reference()["rows"]
        assert shipped["ablations"] == paper_reference()["ablations"]
        assert shipped["ablations"]["I"]["Ours w/o Comm."][:3] == [0.045, 0.030, 0.038]


def _played(success: list[bool]) -> list[EpisodeRecord]:
    return [EpisodeRecord(episode=f"house_{i:05d}/task_0/start_0", task_kind="Single", k=2,
                          success=ok, reasonable=2 if ok else 0, found=2, length=100, comm=0,
                          agents=3, seed=0) for i, ok in enumerate(success)]  # fmt: skip


def test_orderings_judge_the_noise_by_the_paired_interval_when_the_episodes_are_there(tmp_path):
    """Ours wins 6 of 40 shared episodes and loses none: the two runs' own intervals overlap,
    the paired one excludes zero, so the leaderboard must not call the order unresolved."""
    from maniskill_tidy.eval.leaderboard import orderings, write_leaderboard

    ours = [i < 10 for i in range(40)]
    ablated = [i < 4 for i in range(40)]
    runs = {"hangrcom": _summary("hangrcom", ours, 240),
            "wo_know": _summary("wo_know", ablated, 240)}  # fmt: skip
    claim = "Ours w/o Know. < Ours"
    unpaired = dict((c, v) for c, v, _ in orderings(runs))[claim]
    assert unpaired == "holds (intervals overlap)"
    played = {"hangrcom": _played(ours), "wo_know": _played(ablated)}
    found = {c: (v, e) for c, v, e in orderings(runs, played)}
    assert found[claim][0] == "holds"
    assert "paired -0.150 [" in found[claim][1] and "over 40 episodes" in found[claim][1]
    played["wo_know"] = _played([i < 4 or i >= 36 for i in range(40)])  # wins 4 elsewhere
    runs["wo_know"] = _summary("wo_know", [r.success for r in played["wo_know"]], 240)
    found = {c: (v, e) for c, v, e in orderings(runs, played)}
    assert found[claim][0] == "holds (paired interval includes 0)"  # 0.20 < 0.25: 4 won, 6 lost
    # through the files: write_leaderboard pairs the runs' episodes.jsonl
    for policy, summary in runs.items():
        folder = tmp_path / "results" / "setting_I" / policy
        folder.mkdir(parents=True)
        (folder / "summary.json").write_text(json.dumps(summary))
        lines = "".join(json.dumps(r.to_dict()) + "\n" for r in played[policy])
        (folder / "episodes.jsonl").write_text(lines + '{"torn": ')  # a run still writing
    md = write_leaderboard(tmp_path).read_text()
    row = next(line for line in md.splitlines() if line.startswith(f"| {claim} |"))
    assert "| holds (paired interval includes 0) |" in row and "over 40 episodes" in row
    jsonl = tmp_path / "results" / "setting_I" / "wo_know" / "episodes.jsonl"
    assert jsonl.read_text().endswith('{"torn": ')  # a reader leaves the writer's line alone


def test_pixels_rows_get_their_own_table_paired_with_their_team_on_ground_truth(tmp_path):
    """A pixels run is never a row of the ground-truth tables; it sits beside the same team in
    the same look, the difference paired over their episodes."""
    import dataclasses

    from maniskill_tidy.eval.leaderboard import ground_truth_partner
    from maniskill_tidy.eval.runner import row_segmenter
    from maniskill_tidy.models.checkpoints import served_sha256

    assert ground_truth_partner("memory-v2-pixels-segmenter-v1") == "memory-v2"
    from maniskill_tidy.policies.pixels import PIXELS_PIPELINE

    shipped = served_sha256(row_segmenter("memory-v2-pixels", "HeteroTidy-v2"))
    outcomes = {"memory-v2": [True] * 16 + [False] * 4,
                "memory-v2-pixels": [True] * 8 + [False] * 12}  # fmt: skip
    for policy, success in outcomes.items():
        s = {
            **_summary(policy, success, 0),
            "env": "HeteroTidy-v2",
            "segmentation": f"learned:{shipped}" if "pixels" in policy else "ground-truth",
            **({"pixels_pipeline": PIXELS_PIPELINE} if "pixels" in policy else {}),
        }
        folder = tmp_path / "results" / "setting_I" / policy
        folder.mkdir(parents=True)
        (folder / "summary.json").write_text(json.dumps(s))
        records = [dataclasses.replace(rec("Single", 2, 2 if ok else 0, 2, 100, 0), episode=f"e{i}")
                   for i, ok in enumerate(success)]  # fmt: skip
        (folder / "episodes.jsonl").write_text(
            "".join(json.dumps(r.to_dict()) + "\n" for r in records)
        )
    md = write_leaderboard(tmp_path).read_text()
    main, pixels = md.split("From pixels")
    assert "| **memory-v2**" in main and "memory-v2-pixels" not in main
    row = next(line for line in pixels.splitlines() if line.startswith("| **memory-v2-pixels**"))
    cells = [c.strip() for c in row.split("|")[1:-1]]
    assert cells[1] == "HeteroTidy-v2" and cells[2] == f"its own look's ({shipped[:12]})"
    assert cells[3].startswith("0.400 [") and cells[4] == "0.800"
    assert cells[5].startswith("-0.400 [") and cells[6] == "0.50"


def test_a_pixels_run_says_its_team_perceives_predicted_masks_not_ground_truth():
    from maniskill_tidy.eval.runner import RunConfig, _perception
    from maniskill_tidy.policies import make_team, team_class
    from maniskill_tidy.policies.pixels import PixelsTeam

    team = team_class("heuristic-none")
    assert "ground-truth segmentation" in team.perception
    cfg = RunConfig("heuristic-none", "I", "test", None, segmentation="learned")
    pixels = _perception(cfg, team)
    assert pixels.startswith("learned segmenter from RGB-D and the floor plan (pixels track); ")
    assert "ground-truth segmentation" not in pixels and "predicted masks" in pixels
    assert _perception(RunConfig("heuristic-none", "I", "test", None), team) == team.perception
    assert PixelsTeam(make_team("heuristic-none"), "agents/segmenter-v2").perception == pixels
