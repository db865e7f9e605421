"""Ray actors play the same episodes as local processes, and a killed actor costs nothing."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from maniskill_tidy.common.parallel import MAX_ATTEMPTS, run_jobs, start_ray
from maniskill_tidy.eval.runner import RunConfig, evaluate
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


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> list[dict]:
    """The expert's records of the 4 episodes every test plays, from local processes."""
    out = tmp_path_factory.mktemp("pool")
    evaluate(RunConfig("expert", "I", "test", None, 4), out, workers=2, progress=False)
    return _records(out / TAIL)


def _records(path) -> list[dict]:
    rows = [json.loads(x) for x in path.read_text().splitlines()]
    for r in rows:
        r.pop("seconds")
    return sorted(rows, key=lambda r: r["episode"])


def _actor_pids() -> list[int]:
    p = subprocess.run(["pgrep", "-f", "ray::JobActor"], capture_output=True, text=True)
    return [int(x) for x in p.stdout.split()]


def test_eval_joins_a_cluster_started_with_ray_start(tmp_path, reference):
    """`ray start` makes a cluster with token authentication (Ray >= 2.52): a driver that did
    not set RAY_AUTH_MODE waited on "InvalidAuthToken" and failed to join."""
    import socket

    from ray.util import get_node_ip_address

    with socket.socket() as s:
        s.bind(("", 0))
        port = s.getsockname()[1]
    address = f"{get_node_ip_address()}:{port}"  # what `ray start` registers and prints
    env = {k: v for k, v in os.environ.items() if k != "RAY_AUTH_MODE"}
    env["RAY_worker_niceness"] = "0"
    head = subprocess.Popen(
        [str(Path(sys.executable).with_name("ray")), "start", "--head", "--block",
         "--port", str(port), "--num-cpus", "2", "--object-store-memory", str(200 * 2**20),
         "--include-dashboard=false"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env, start_new_session=True,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        while True:
            try:
                socket.create_connection(address.rsplit(":", 1), timeout=1).close()
                break
            except OSError:
                assert head.poll() is None and time.monotonic() < deadline, "ray start failed"
                time.sleep(0.5)
        p = cli("eval", "--policy", "expert", "--episodes", "4", "--workers", "2", "--env",
                "HeteroTidy-v1", "--ray", address, "--out", str(tmp_path / "cluster"))  # fmt: skip
        assert p.returncode == 0, p.stderr[-2000:]
    finally:  # only this cluster: `ray stop` would stop every Ray on the machine
        os.killpg(head.pid, signal.SIGTERM)
        head.wait(timeout=120)
    assert _records(tmp_path / "cluster" / TAIL) == reference


def test_ray_actors_give_the_records_of_local_processes(tmp_path, local_ray, reference):
    cfg = RunConfig("expert", "I", "test", None, 4)
    summary = evaluate(cfg, tmp_path / "ray", workers=2, progress=False, ray=local_ray)
    assert summary["ray"] == "local" and summary["episodes"] == 4
    assert _records(tmp_path / "ray" / TAIL) == reference


def test_a_killed_actor_is_replaced_and_no_episode_is_lost_or_counted_twice(
    tmp_path, local_ray, reference
):
    cfg = RunConfig("expert", "I", "test", None, 4)
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
    assert summary["episodes"] == 4
    assert _records(jsonl) == reference


def test_a_dataset_generated_on_ray_actors_is_the_one_local_processes_make(tmp_path, local_ray):
    from maniskill_tidy.tasks.dataset import generate_dataset

    pool = generate_dataset(tmp_path / "pool", 6, seed=9, progress=False, workers=2)
    on_ray = generate_dataset(tmp_path / "ray", 6, seed=9, progress=False, workers=2, ray=local_ray)
    assert on_ray["dataset_hash"] == pool["dataset_hash"]
    assert (tmp_path / "ray/manifest.json").read_bytes() == (
        tmp_path / "pool/manifest.json"
    ).read_bytes()


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


def test_a_job_that_raises_on_an_actor_stops_the_run_with_its_name_and_cause(local_ray):
    from maniskill_tidy.common.parallel import JobError

    def stale_id(x: int) -> int:
        return {0: 0}[x]

    with pytest.raises(JobError, match="job 2 failed: KeyError: 2") as info:
        list(run_jobs([0, 2], stale_id, 2, ray=local_ray, ordered=True))
    assert isinstance(info.value.cause, KeyError)


def test_ray_refuses_an_address_where_nothing_answers(tmp_path):
    out = tmp_path / "out"
    p = cli("eval", "--policy", "random", "--episodes", "1", "--ray", "127.0.0.1:1",
            "--out", str(out))  # fmt: skip
    one_line_error(p, "--ray 127.0.0.1:1", "nothing answers")
    assert not out.exists()
    p = cli("generate", "--houses", "2", "--ray", "no-port", "--out", str(out))
    one_line_error(p, "--ray 'no-port'", "ray start --head")
    assert not out.exists()
    one_line_error(cli("demos", "--ray", "--out", str(out)), "--ray", "--features")
    assert not out.exists()
