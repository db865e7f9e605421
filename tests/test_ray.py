"""Ray actors play the same episodes as local processes, and a killed actor costs nothing."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from maniskill_tidy.eval.runner import RunConfig, evaluate
from maniskill_tidy.parallel import MAX_ATTEMPTS, run_jobs, start_ray
from tests.test_cli_errors import cli, one_line_error

TAIL = "eval/results/setting_I/expert/episodes.jsonl"


@pytest.fixture(scope="module")
def local_ray():
    """One 2-CPU local Ray instance for the module (starting one takes seconds)."""
    import ray

    started = start_ray("local", 2)
    yield "local"
    if started:
        ray.shutdown()


def _records(path) -> list[dict]:
    rows = [json.loads(x) for x in path.read_text().splitlines()]
    for r in rows:
        r.pop("seconds")
    return sorted(rows, key=lambda r: r["episode"])


def _actor_pids() -> list[int]:
    p = subprocess.run(["pgrep", "-f", "ray::JobActor"], capture_output=True, text=True)
    return [int(x) for x in p.stdout.split()]


def test_eval_joins_a_cluster_started_with_ray_start(tmp_path):
    """`ray start` makes a cluster with token authentication (Ray >= 2.52): a driver that did
    not set RAY_AUTH_MODE waited on "InvalidAuthToken" and failed to join."""
    import socket

    with socket.socket() as s:
        s.bind(("", 0))
        port = s.getsockname()[1]
    ray_bin = str(Path(sys.executable).with_name("ray"))
    env = {k: v for k, v in os.environ.items() if k != "RAY_AUTH_MODE"}
    env["RAY_worker_niceness"] = "0"
    start = subprocess.run(
        [ray_bin, "start", "--head", "--port", str(port), "--num-cpus", "2",
         "--include-dashboard=false"],
        capture_output=True, text=True, env=env, timeout=120,
    )  # fmt: skip
    try:
        assert start.returncode == 0, start.stderr[-2000:]
        address = re.search(r"--address='([^']+)'", start.stdout + start.stderr).group(1)
        p = cli("eval", "--policy", "expert", "--episodes", "3", "--workers", "2",
                "--ray", address, "--out", str(tmp_path / "cluster"))  # fmt: skip
        assert p.returncode == 0, p.stderr[-2000:]
    finally:
        subprocess.run([ray_bin, "stop", "--force"], capture_output=True, timeout=120)
    cfg = RunConfig("expert", "I", "test", None, 3)
    evaluate(cfg, tmp_path / "pool", workers=1, progress=False)
    assert _records(tmp_path / "cluster" / TAIL) == _records(tmp_path / "pool" / TAIL)


def test_ray_actors_give_the_records_of_local_processes(tmp_path, local_ray):
    cfg = RunConfig("expert", "I", "test", None, 4)
    evaluate(cfg, tmp_path / "pool", workers=2, progress=False)
    summary = evaluate(cfg, tmp_path / "ray", workers=2, progress=False, ray=local_ray)
    assert summary["ray"] == "local" and summary["episodes"] == 4
    assert _records(tmp_path / "ray" / TAIL) == _records(tmp_path / "pool" / TAIL)


def test_a_killed_actor_is_replaced_and_no_episode_is_lost_or_counted_twice(tmp_path, local_ray):
    cfg = RunConfig("expert", "I", "test", None, 6)
    evaluate(cfg, tmp_path / "pool", workers=2, progress=False)
    jsonl = tmp_path / "ray" / TAIL
    killed: list[int] = []

    def kill_one_actor_after_the_first_episode() -> None:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline:
            pids = _actor_pids()
            if pids and jsonl.exists() and jsonl.read_text().count("\n") >= 1:
                os.kill(pids[0], signal.SIGKILL)
                killed.append(pids[0])
                return
            time.sleep(0.2)

    killer = threading.Thread(target=kill_one_actor_after_the_first_episode)
    killer.start()
    summary = evaluate(cfg, tmp_path / "ray", workers=2, progress=False, ray=local_ray)
    killer.join()
    assert killed, "no actor was killed: the test shows nothing"
    assert summary["episodes"] == 6
    assert _records(jsonl) == _records(tmp_path / "pool" / TAIL)


def test_a_job_whose_worker_dies_runs_again_on_a_new_one(tmp_path, local_ray):
    marker = tmp_path / "died"

    def square_but_die_once_on_3(x: int) -> int:
        if x == 3 and not marker.exists():
            marker.write_text(str(os.getpid()))
            os.kill(os.getpid(), signal.SIGKILL)
        return x * x

    results = list(run_jobs(range(8), square_but_die_once_on_3, 2, ray=local_ray))
    assert marker.exists()
    assert sorted(results) == [(x, x * x) for x in range(8)]
    ordered = list(run_jobs(range(8), abs, 2, ray=local_ray, ordered=True))
    assert ordered == [(x, x) for x in range(8)]


def test_a_job_that_kills_every_worker_stops_the_run_with_its_name(local_ray):
    def always_die(x: int) -> int:
        if x == 1:
            os.kill(os.getpid(), signal.SIGKILL)
        return x

    with pytest.raises(RuntimeError, match=f"job 1 lost {MAX_ATTEMPTS} Ray workers"):
        list(run_jobs(range(3), always_die, 2, ray=local_ray))


def test_ray_refuses_an_address_where_nothing_answers(tmp_path):
    out = tmp_path / "out"
    p = cli("eval", "--policy", "random", "--episodes", "1", "--ray", "127.0.0.1:1",
            "--out", str(out))  # fmt: skip
    one_line_error(p, "--ray 127.0.0.1:1", "nothing answers")
    assert not out.exists()
    p = cli("generate", "--houses", "2", "--ray", "no-port", "--out", str(out))
    one_line_error(p, "--ray 'no-port'", "ray start --head")
    assert not out.exists()
