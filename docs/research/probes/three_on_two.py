"""What three agents' hosts can get out of two cores, with no agent in them (issue 48).

    python docs/research/probes/three_on_two.py [--ms 6.5 3.2] [--phases 200]

Starts three processes that each burn ``--ms`` milliseconds of CPU per phase when told to over a
pipe, as an agent's host does for observe and act, and times the phase: from the first message
posted to the last answer read. Three equal jobs on two cores take 1.5 jobs' time if the
kernel shares the cores evenly, 2 if two of them share one core to the end. Prints the median
phase and both bounds. Nothing is written.
"""

from __future__ import annotations

import argparse
import multiprocessing
import statistics
import time

HOSTS, CORES = 3, 2


def burn(conn) -> None:
    """A host: burn the CPU milliseconds it is sent, answer, until it is sent None."""
    while (ms := conn.recv()) is not None:
        end = time.process_time() + ms / 1e3
        while time.process_time() < end:
            pass
        conn.send(None)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--ms", type=float, nargs="+", default=[6.5, 3.2],
                   help="CPU milliseconds per job (an agent's observe, act)")  # fmt: skip
    p.add_argument("--phases", type=int, default=200)
    args = p.parse_args()
    if min(args.ms) <= 0 or args.phases < 1:
        p.error("--ms must be > 0 and --phases at least 1")
    pipes, hosts = [], []
    for _ in range(HOSTS):
        ours, theirs = multiprocessing.Pipe()
        hosts.append(multiprocessing.Process(target=burn, args=(theirs,), daemon=True))
        hosts[-1].start()
        pipes.append(ours)
    try:
        for ms in args.ms:
            walls = []
            for _ in range(args.phases):
                start = time.perf_counter()
                for conn in pipes:
                    conn.send(ms)
                for conn in pipes:
                    conn.recv()
                walls.append(1e3 * (time.perf_counter() - start))
                time.sleep(0.005)  # the env's turn: the hosts sleep
            phase, shared = statistics.median(walls), HOSTS * ms / CORES
            print(f"{HOSTS} jobs of {ms:g} ms CPU on {CORES} cores: phase {phase:.2f} ms "
                  f"(median of {args.phases}); cores shared evenly {shared:.2f}, two jobs on "
                  f"one core {2 * ms:.2f}")  # fmt: skip
    finally:
        for conn in pipes:
            conn.send(None)
        for h in hosts:
            h.join(timeout=5)


if __name__ == "__main__":
    main()
