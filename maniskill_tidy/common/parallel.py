"""One way to spread jobs over processes: in this process, a local process pool, or Ray actors.

Every parallel command (eval, demonstrations, perception views, dataset generation) hands its
jobs to :func:`run_jobs`. Each worker is set up once by ``init`` (SAPIEN allows one renderer per
process, so a worker builds its env once and never pickles it) and then runs ``work(job)`` for
many jobs; results stream back as they finish, so callers append them to their resumable files.

With ``ray`` a worker is a Ray actor, on a local Ray instance (``ray="local"``, ``workers``
CPUs) or on a running cluster (``ray="ADDRESS"``, ``workers`` actors). An actor that dies (its
process killed, its node lost) is replaced and its job run again on the new one; a job that kills
:data:`MAX_ATTEMPTS` actors in a row stops the run with its name. A job that raises stops the run
with a :class:`JobError` naming it, its cause (with the worker's traceback) chained. Ray hides
GPUs from actors that do not ask for one (it sets ``CUDA_VISIBLE_DEVICES`` to empty), so on a
cluster with GPUs each actor asks for a share of one and SAPIEN can render through CUDA there.
"""

from __future__ import annotations

import os
import socket
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from typing import Any

MAX_ATTEMPTS = 3  # actors one job may lose before the run stops

# The thread pools a worker process would otherwise size to every core of the machine: lavapipe's
# rasteriser (LP_NUM_THREADS), OpenMP (torch's intra-op pool, open3d's loops) and the BLAS
# libraries. N workers each spreading over all cores fight for them (issue 48).
# TIDY_AGENT_THREADS: the threads a team's agents think on (``agent_pool``). TIDY_PIN_WORKERS=1
# also pins each worker to its own cores (``core_shares``).
THREAD_KNOBS = (
    "LP_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS",
    "TIDY_AGENT_THREADS",
)  # fmt: skip


class WorkerLostError(RuntimeError):
    """A job killed :data:`MAX_ATTEMPTS` workers: the job, not the cluster, is at fault."""


class JobError(RuntimeError):
    """A job raised ``cause``: the run stops, naming the job (what finished is kept)."""

    def __init__(self, job: Any, cause: BaseException) -> None:
        super().__init__(f"job {job!r} failed: {type(cause).__name__}: {cause}")
        self.job = job
        self.cause = cause


LOCAL = "local"  # --ray without an address: start a Ray instance on this machine


def die_with_parent() -> None:
    """Linux: a worker gets SIGTERM when the runner dies (else a killed run leaves it running)."""
    try:
        import ctypes
        import signal

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, int(signal.SIGTERM))  # PDEATHSIG
    except (OSError, AttributeError):
        pass


def worker_threads(workers: int) -> int:
    """Threads each of ``workers`` local processes may use: its share of this machine's cores."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return max(1, (cores or 1) // max(1, workers))


def core_shares(workers: int) -> list[frozenset[int]] | None:
    """With ``TIDY_PIN_WORKERS=1``, each of ``workers`` local processes' own cores: disjoint
    slices of this process's cores, as even as they divide (None otherwise, or where there are
    fewer cores than workers). Off by default: on 2 cores it gained nothing beyond the spread
    between runs (``docs/research/probes/pinning_ab.py``; docs/scaling.md, Two workers), and a
    pinned worker cannot use the core its neighbour leaves idle."""
    if os.environ.get("TIDY_PIN_WORKERS") != "1" or not hasattr(os, "sched_setaffinity"):
        return None
    cores = sorted(os.sched_getaffinity(0))
    n = len(cores)
    if workers < 1 or n < workers:
        return None
    return [frozenset(cores[i * n // workers : (i + 1) * n // workers]) for i in range(workers)]


def auto_workers(jobs: int) -> int:
    """``--workers auto``: one process per core of this machine's share, no more than there
    are jobs. One process keeps only about 1.4 cores busy (lavapipe and the agents wait on each
    other), so on 2 cores a second process plays 1.4-1.9 times the episodes in steady state
    (``bench --only teams``, which varies that much between runs; docs/scaling.md)."""
    return max(1, min(worker_threads(1), jobs))


def workers_option(value: str | int) -> int | None:
    """``--workers``: a number of processes (at least 1), or ``auto`` (None: see
    :func:`auto_workers`); anything else is refused."""
    if value == "auto":
        return None
    try:
        n = int(value)
    except (TypeError, ValueError):
        raise ValueError(f"--workers {value!r}: expected a number of processes or auto") from None
    if n < 1:
        raise ValueError(f"--workers {n}: expected at least 1 process")
    return n


def agent_processes_knob() -> bool | None:
    """``TIDY_AGENT_PROCESSES``: True (1), False (0) or None (unset: the team and the cores
    decide, ``eval/agent_processes.py``); anything else is refused."""
    knob = os.environ.get("TIDY_AGENT_PROCESSES", "")
    if knob not in ("", "0", "1"):
        raise ValueError(f"TIDY_AGENT_PROCESSES={knob!r}: expected 0 or 1 (or unset)")
    return None if knob == "" else knob == "1"


_agent_pools: dict[int, Any] = {}


def agent_threads() -> int:
    """``TIDY_AGENT_THREADS``, else every core of this process's share: the threads (or, for
    teams whose agents think in processes, the cores) a team's agents may use."""
    return int(os.environ.get("TIDY_AGENT_THREADS") or worker_threads(1))


def agent_pool():
    """A thread pool for a team's agents (:func:`agent_threads` threads), or None where that is
    one thread."""
    from concurrent.futures import ThreadPoolExecutor

    threads = agent_threads()
    if threads < 2:
        return None
    if threads not in _agent_pools:
        _agent_pools[threads] = ThreadPoolExecutor(threads, thread_name_prefix="agent")
    return _agent_pools[threads]


@contextmanager
def thread_budget(threads: int) -> Iterator[None]:
    """Processes started inside inherit ``threads`` per pool in :data:`THREAD_KNOBS` (read when
    the libraries load, so they must be in the environment before a worker imports them); a
    knob the user set is left as it is. The environment is restored afterwards."""
    saved = {k: os.environ.get(k) for k in THREAD_KNOBS}
    for k in THREAD_KNOBS:
        os.environ.setdefault(k, str(threads))
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _pool_init(init: Callable | None, initargs: tuple, shares: Any = None) -> None:
    """A pool worker's set-up; ``shares``: a queue of core sets, one taken per worker."""
    die_with_parent()
    if shares is not None:  # before the worker makes its env and loads its models
        os.sched_setaffinity(0, shares.get())
    if init is not None:
        init(*initargs)


def run_jobs(
    jobs: Iterable,
    work: Callable[[Any], Any],
    workers: int = 1,
    init: Callable | None = None,
    initargs: tuple = (),
    ray: str | None = None,
    ordered: bool = False,
) -> Iterator[tuple[Any, Any]]:
    """Yield ``(job, work(job))`` for every job, as they finish (in job order if ``ordered``).

    ``init(*initargs)`` sets up each worker once; in this process (``workers`` 1, no Ray) a
    callable it returns is called at the end (to close the env)."""
    jobs = list(jobs)
    if not jobs:
        return
    if ray is not None:
        yield from _ray_jobs(jobs, work, workers, init, initargs, ray, ordered)
    elif workers <= 1:
        close = init(*initargs) if init is not None else None
        try:
            for job in jobs:
                try:
                    result = work(job)
                except Exception as e:
                    raise JobError(job, e) from e
                yield job, result
        finally:
            if callable(close):
                close()
    else:
        from concurrent.futures import ProcessPoolExecutor, as_completed
        from multiprocessing import get_context

        n = min(workers, len(jobs))
        context = get_context("spawn")
        shares = None
        if (pinned := core_shares(n)) is not None:  # each worker takes one as it starts
            shares = context.Queue()
            for share in pinned:
                shares.put(share)
        pool = ProcessPoolExecutor(
            n, mp_context=context, initializer=_pool_init, initargs=(init, initargs, shares)
        )
        with pool:
            # the workers start as jobs are submitted: the budget holds for that moment only
            with thread_budget(worker_threads(n)):
                futures = {pool.submit(work, job): job for job in jobs}
            done = futures if ordered else as_completed(futures)
            try:
                for fut in done:
                    try:
                        result = fut.result()
                    except Exception as e:  # the worker's traceback is chained to e
                        raise JobError(futures[fut], e) from e
                    yield futures[fut], result
            finally:  # a failed or abandoned run leaves no queued job to run on
                pool.shutdown(wait=True, cancel_futures=True)


# ---------------------------------------------------------------------- Ray
class JobActor:
    """One Ray worker process: set up once, then runs jobs."""

    def __init__(self, cwd: str, init: Callable | None, initargs: tuple) -> None:
        if os.path.isdir(cwd):  # relative paths (a dataset folder) mean what they meant there
            os.chdir(cwd)
        # an actor has one CPU of its node (num_cpus=1), not the node's every core: its team's
        # agents think on one thread, in this process
        os.environ.setdefault("TIDY_AGENT_THREADS", "1")
        if init is not None:
            init(*initargs)  # the env lives as long as the actor's process

    def run(self, work: Callable, job: Any) -> Any:
        return work(job)


def check_ray(address: str) -> None:
    """A one-line error unless Ray is installed and, for an address, something answers there."""
    if address != LOCAL and "RAY_AUTH_MODE" not in os.environ and _token_available():
        # `ray start` makes clusters with token authentication; a driver joining one sends the
        # token (~/.ray/auth_token, RAY_AUTH_TOKEN or RAY_AUTH_TOKEN_PATH) only when the mode is
        # set before ray is imported, else it retries on "InvalidAuthToken" until it gives up.
        os.environ["RAY_AUTH_MODE"] = "token"
    try:
        import ray  # noqa: F401
    except ImportError:
        raise ValueError("--ray needs the ray package: pip install 'maniskill-tidy[ray]'") from None
    if address != LOCAL:
        _probe(address)  # ray.init waits minutes for an address where nothing listens


def start_ray(address: str, workers: int) -> bool:
    """Join the cluster at ``address``, or start a local instance with ``workers`` CPUs; True
    if this call started Ray (and so should shut it down)."""
    check_ray(address)
    import ray

    if ray.is_initialized():
        return False
    common = {"include_dashboard": False, "log_to_driver": False, "configure_logging": False}
    if address == LOCAL:
        # Ray starts its workers niced (15 by default): beside any other busy process on this
        # machine the actors then got an eighth of the time that pool workers get.
        os.environ.setdefault("RAY_worker_niceness", "0")
        # address="local": a new instance even where `ray start` left one to join
        ray.init(address="local", num_cpus=workers, object_store_memory=200 * 2**20, **common)
    else:
        try:
            ray.init(address=address, **common)
        except (ConnectionError, ValueError, RuntimeError) as e:
            raise ValueError(
                f"--ray {address}: no Ray cluster answers there ({str(e).splitlines()[0]}); "
                f"expected {EXAMPLE}"
            ) from None
    return True


def _token_available() -> bool:
    path = os.environ.get("RAY_AUTH_TOKEN_PATH") or os.path.expanduser("~/.ray/auth_token")
    return bool(os.environ.get("RAY_AUTH_TOKEN")) or os.path.isfile(path)


EXAMPLE = "the address `ray start --head` printed, such as 10.0.0.5:6379"


def _probe(address: str, timeout: float = 5.0) -> None:
    """A one-line error unless something listens at a HOST:PORT address ("auto" and ray://
    addresses are left to Ray)."""
    if address == "auto" or "://" in address:
        return
    host, sep, port = address.rpartition(":")
    if not sep or not host or not port.isdigit():
        raise ValueError(f"--ray {address!r}: expected {EXAMPLE}")
    try:
        socket.create_connection((host, int(port)), timeout=timeout).close()
    except OSError as e:
        raise ValueError(
            f"--ray {address}: nothing answers there ({e.strerror or e}); expected {EXAMPLE}"
        ) from None


def _ray_jobs(jobs, work, workers, init, initargs, address, ordered):
    import ray
    from ray.exceptions import RayActorError, RayTaskError

    started = start_ray(address, workers)
    try:
        gpus = ray.cluster_resources().get("GPU", 0.0)
        n = max(1, min(workers, len(jobs)))
        options = {"num_cpus": 1, "max_restarts": 0}
        if gpus:
            options["num_gpus"] = min(1.0, gpus / n)
        actor_cls = ray.remote(JobActor).options(**options)
        cwd = os.getcwd()

        def new_actor():
            return actor_cls.remote(cwd, init, initargs)

        queue = deque(enumerate(jobs))
        attempts = [0] * len(jobs)
        pending: dict = {}  # object ref -> (actor, index)
        finished: dict[int, Any] = {}
        next_out = 0

        def submit(actor) -> None:
            if queue:
                i, job = queue.popleft()
                pending[actor.run.remote(work, job)] = (actor, i)

        for _ in range(n):
            submit(new_actor())
        while pending:
            (ref,), _ = ray.wait(list(pending), num_returns=1)
            actor, i = pending.pop(ref)
            try:
                result = ray.get(ref)
            except RayActorError:
                attempts[i] += 1
                if attempts[i] >= MAX_ATTEMPTS:
                    raise WorkerLostError(
                        f"job {jobs[i]!r} lost {MAX_ATTEMPTS} Ray workers in a row; stopping"
                    ) from None
                queue.appendleft((i, jobs[i]))
                ray.kill(actor)
                submit(new_actor())
                continue
            except RayTaskError as e:
                raise JobError(jobs[i], e.cause) from e
            submit(actor)
            if not ordered:
                yield jobs[i], result
                continue
            finished[i] = result
            while next_out in finished:
                yield jobs[next_out], finished.pop(next_out)
                next_out += 1
    finally:
        if started:
            ray.shutdown()
