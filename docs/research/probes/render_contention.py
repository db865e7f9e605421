"""How much of the machine one frame's render takes, and what a Python thread beside it costs.

    python docs/research/probes/render_contention.py [--env HeteroTidy-v2] [--frames 60] \
        [--switch-interval 0.0005]

Times the env's ``get_obs`` (every agent's camera drawn and read back) alone, with the cores
it keeps busy (process CPU seconds / wall seconds), then with a thread spinning in Python
beside it, as an agent thinking during the render would (issue 48: why overlapping the agents'
thinking with the render gains nothing on 2 cores). ``--switch-interval`` sets Python's
(``sys.setswitchinterval``, default 5 ms): how long the env's thread may wait for the
interpreter's lock, each time the renderer hands control back, while the other thread holds it.
Nothing is written.
"""

from __future__ import annotations

import argparse
import sys
import threading
import time

from maniskill_tidy.eval.runner import RunConfig, make_env


def timed(call, frames: int) -> tuple[float, float]:
    """(ms per call, cores busy)."""
    wall, cpu = time.perf_counter(), time.process_time()
    for _ in range(frames):
        call()
    wall = time.perf_counter() - wall
    return 1e3 * wall / frames, (time.process_time() - cpu) / wall


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env", default="HeteroTidy-v1")
    p.add_argument("--frames", type=int, default=60)
    p.add_argument("--dataset", default="data/tidy120")
    p.add_argument("--switch-interval", type=float, default=sys.getswitchinterval())
    args = p.parse_args()
    if not args.switch_interval > 0:
        p.error(f"--switch-interval must be > 0 seconds, got {args.switch_interval}")
    sys.setswitchinterval(args.switch_interval)
    env = make_env(RunConfig("heuristic-none", "I", "test", args.dataset, 1, env=args.env))
    env.reset(seed=0, options={"episode": 0})
    u = env.unwrapped
    timed(u.get_obs, 5)  # warm-up
    ms, cores = timed(u.get_obs, args.frames)
    print(f"{args.env}: get_obs alone {ms:.1f} ms, {cores:.2f} cores busy")
    stop = threading.Event()

    def spin() -> None:
        while not stop.is_set():
            pass

    thread = threading.Thread(target=spin)
    thread.start()
    try:
        ms_beside, cores_beside = timed(u.get_obs, args.frames)
    finally:
        stop.set()
        thread.join()
    print(f"{args.env}: with a Python thread spinning beside it (switch interval "
          f"{1e3 * sys.getswitchinterval():g} ms) {ms_beside:.1f} ms "
          f"({ms_beside / ms:.1f}x), {cores_beside:.2f} cores busy")  # fmt: skip
    env.close()


if __name__ == "__main__":
    main()
