"""Metrics on hand-made episode logs, communication accounting, the resumable runner."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from maniskill_tidy.eval.metrics import EpisodeRecord, ces, summarize
from maniskill_tidy.eval.runner import read_records, select
from maniskill_tidy.policies.channel import CENTRAL, Channel


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


def test_episode_selection_is_spread_and_deterministic():
    assert select(1000, None) == list(range(1000))
    assert select(1000, 4) == [0, 250, 500, 750]
    with pytest.raises(ValueError, match="positive"):
        select(10, 0)


def test_read_records_cuts_a_torn_last_line(tmp_path):
    path = tmp_path / "episodes.jsonl"
    good = json.dumps(rec("Single", 1, 1, 1, 10, 0).to_dict()) + "\n"
    path.write_text(good + good[: len(good) // 2])
    assert len(read_records(path)) == 1
    assert path.read_text() == good


def _eval(out, extra=()):
    cmd = [sys.executable, "-m", "maniskill_tidy.cli", "eval", "--policy", "expert"]
    cmd += ["--episodes", "4", "--split", "test", "--out", str(out), *extra]
    return cmd


def test_runner_resumes_after_a_kill_with_the_same_totals(tmp_path):
    full = subprocess.run(_eval(tmp_path / "full"), capture_output=True, text=True, timeout=600)
    assert full.returncode == 0, full.stderr
    proc = subprocess.Popen(_eval(tmp_path / "cut"), stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    jsonl = tmp_path / "cut/eval/results/setting_I/expert/episodes.jsonl"
    deadline = time.time() + 300
    while time.time() < deadline and not (jsonl.exists() and jsonl.read_text().count("\n") >= 1):
        time.sleep(0.2)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    partial = jsonl.read_text().count("\n")
    assert 1 <= partial < 4
    again = subprocess.run(_eval(tmp_path / "cut"), capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr
    lines = [json.loads(x) for x in jsonl.read_text().splitlines()]
    assert len(lines) == 4 and len({x["episode"] for x in lines}) == 4
    a = json.loads((tmp_path / "full/eval/results/setting_I/expert/summary.json").read_text())
    b = json.loads((tmp_path / "cut/eval/results/setting_I/expert/summary.json").read_text())
    assert a["metrics"] == b["metrics"] and a["dataset_hash"] == b["dataset_hash"]
    refused = subprocess.run(
        _eval(tmp_path / "cut", ["--seed", "5"]), capture_output=True, text=True, timeout=600
    )
    assert refused.returncode != 0 and "other arguments" in refused.stderr
