"""A job that raises stops the run, names the job and keeps the worker's traceback."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

from maniskill_tidy.common.parallel import JobError, run_jobs


def lookup_or_fail(job: tuple[str, int]) -> int:
    """Job ``(folder, n)``: job 0 fails as a stale-id bug would; the others take a while."""
    folder, n = job
    if n == 0:
        return {"CD_1": 1}["CD_2"]
    time.sleep(0.3)
    (Path(folder) / f"{n}.done").touch()
    return n


@pytest.mark.parametrize("workers", [1, 2])
def test_a_job_that_raises_stops_the_run_with_its_name_and_cause(tmp_path, workers):
    jobs = [(str(tmp_path), n) for n in range(1, 4)] + [(str(tmp_path), 0)]
    with pytest.raises(JobError) as info:
        list(run_jobs(jobs, lookup_or_fail, workers, ordered=True))
    assert info.value.job == (str(tmp_path), 0)
    assert isinstance(info.value.cause, KeyError)
    assert str(info.value) == f"job {(str(tmp_path), 0)!r} failed: KeyError: 'CD_2'"


def test_a_failed_job_in_a_pool_cancels_the_jobs_still_queued(tmp_path):
    """The pool used to run every queued episode before the error came out."""
    jobs = [(str(tmp_path), n) for n in range(40)]
    with pytest.raises(JobError):
        list(run_jobs(jobs, lookup_or_fail, 2))
    time.sleep(0.5)
    assert len(list(tmp_path.glob("*.done"))) < 10


def test_the_workers_traceback_comes_with_the_error(tmp_path):
    import traceback

    with pytest.raises(JobError) as info:
        list(run_jobs([(str(tmp_path), 0)] * 2, lookup_or_fail, 2))
    text = "".join(traceback.format_exception(info.value.cause))
    assert "lookup_or_fail" in text and '{"CD_1": 1}["CD_2"]' in text


def thread_knobs(_job: int) -> dict[str, str | None]:
    import os

    from maniskill_tidy.common.parallel import THREAD_KNOBS

    return {k: os.environ.get(k) for k in THREAD_KNOBS}


def test_pool_workers_get_their_share_of_the_cores_and_the_parent_is_untouched(monkeypatch):
    import os

    from maniskill_tidy.common.parallel import THREAD_KNOBS, worker_threads

    for k in THREAD_KNOBS:
        monkeypatch.delenv(k, raising=False)
    monkeypatch.setenv("OMP_NUM_THREADS", "7")  # one the user set stays
    seen = [env for _, env in run_jobs(range(4), thread_knobs, workers=2)]
    share = str(worker_threads(2))
    for env in seen:
        assert env["LP_NUM_THREADS"] == share and env["MKL_NUM_THREADS"] == share
        assert env["OMP_NUM_THREADS"] == "7"
    assert "LP_NUM_THREADS" not in os.environ and os.environ["OMP_NUM_THREADS"] == "7"
    # in this process (one worker) nothing is changed
    (_, env), *_ = run_jobs([0], thread_knobs, workers=1)
    assert env["LP_NUM_THREADS"] is None


_meeting = None  # a worker's handle on the barrier both workers' jobs wait at


def join_meeting(barrier) -> None:
    global _meeting
    _meeting = barrier


def affinity(_job: int) -> list[int]:
    _meeting.wait(timeout=60)  # the other worker holds the other job: two workers answer
    return sorted(os.sched_getaffinity(0))


def test_core_shares_split_the_cores_into_disjoint_slices(monkeypatch):
    from maniskill_tidy.common import parallel

    monkeypatch.setattr(parallel.os, "sched_getaffinity", lambda pid: {4, 1, 2})
    monkeypatch.delenv("TIDY_PIN_WORKERS", raising=False)
    assert parallel.core_shares(2) is None  # off unless asked for
    monkeypatch.setenv("TIDY_PIN_WORKERS", "1")
    assert parallel.core_shares(2) == [{1}, {2, 4}]
    assert parallel.core_shares(3) == [{1}, {2}, {4}]
    assert parallel.core_shares(4) is None  # fewer cores than workers: left to the scheduler


@pytest.mark.skipif(
    not hasattr(os, "sched_getaffinity") or len(os.sched_getaffinity(0)) < 2,
    reason="needs 2 cores and sched_setaffinity",
)
def test_pool_workers_are_pinned_to_their_own_cores_and_the_parent_is_not(monkeypatch):
    from multiprocessing import get_context

    monkeypatch.setenv("TIDY_PIN_WORKERS", "1")
    parent = os.sched_getaffinity(0)
    barrier = get_context("spawn").Barrier(2)
    jobs = run_jobs(range(2), affinity, workers=2, init=join_meeting, initargs=(barrier,))
    seen = {tuple(cores) for _, cores in jobs}
    assert len(seen) == 2 and all(seen)
    first, second = (set(c) for c in seen)
    assert not first & second and first | second <= parent
    assert os.sched_getaffinity(0) == parent


def test_auto_workers_is_a_process_per_core_but_never_more_than_the_jobs(monkeypatch):
    from maniskill_tidy.common import parallel

    monkeypatch.setattr(parallel, "worker_threads", lambda workers: 2)
    assert [parallel.auto_workers(n) for n in (0, 1, 2, 200)] == [1, 1, 2, 2]
    assert parallel.workers_option("auto") is None and parallel.workers_option("3") == 3
    for bad, why in (("0", "at least 1"), ("many", "a number of processes or auto")):
        with pytest.raises(ValueError, match=why):
            parallel.workers_option(bad)
