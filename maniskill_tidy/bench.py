"""``make bench``: throughput of the loops that matter, as ratios to a same-run reference.

The machines are shared and noisy, so every figure is printed next to a reference measured in
the same run. For dataset generation the reference is a fixed pure-Python workload
(``calibration``); the ratio "houses per calibration unit" is comparable across runs.
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

from tqdm import tqdm


def calibration(n: int = 2_000_000) -> float:
    """Seconds for a fixed pure-Python loop (the same work on every machine)."""
    start = time.perf_counter()
    acc = 0
    for i in range(n):
        acc = (acc + i * i) % 1_000_003
    return time.perf_counter() - start


def bench_generation(houses: int, workers: int) -> dict:
    from maniskill_tidy.tasks.dataset import generate_dataset

    out = Path(tempfile.mkdtemp(prefix="bench-gen-"))
    try:
        ref = calibration()
        start = time.perf_counter()
        generate_dataset(out, houses, seed=1234, workers=workers, progress=False)
        elapsed = time.perf_counter() - start
        ref = (ref + calibration()) / 2
    finally:
        shutil.rmtree(out, ignore_errors=True)
    rate = houses / elapsed
    return {
        "houses": houses,
        "workers": workers,
        "houses_per_s": rate,
        "calibration_s": ref,
        "houses_per_calibration": rate * ref,
    }


SAMPLE = Path(__file__).resolve().parents[1] / "tests" / "data" / "procthor-sample-20.jsonl.gz"


def bench_procthor_generation(source: Path, workers: int) -> dict:
    """``generate --procthor``: import, repair, meta-tasks, written and hashed."""
    from maniskill_tidy.tasks.procthor_dataset import generate_procthor_dataset

    out = Path(tempfile.mkdtemp(prefix="bench-procthor-"))
    try:
        ref = calibration()
        start = time.perf_counter()
        manifest = generate_procthor_dataset(source, out, seed=0, workers=workers, progress=False)
        elapsed = time.perf_counter() - start
        ref = (ref + calibration()) / 2
    finally:
        shutil.rmtree(out, ignore_errors=True)
    houses = manifest["source"]["houses_read"]
    return {
        "houses": houses,
        "kept": manifest["houses"],
        "workers": workers,
        "houses_per_s": houses / elapsed,
        "calibration_s": ref,
        "houses_per_calibration": houses / elapsed * ref,
    }


LOOKS = {"v1": "HeteroTidy-v1", "v2": "HeteroTidy-v2"}


def _teams(text: str) -> tuple[str, ...]:
    """``--teams``: registered policies or agent configs, comma-separated."""
    from maniskill_tidy.policies import team_class

    names = tuple(t.strip() for t in text.split(",") if t.strip())
    if not names:
        raise argparse.ArgumentTypeError("expected one or more team names, comma-separated")
    for name in names:
        try:
            team_class(name)
        except ValueError as e:
            raise argparse.ArgumentTypeError(str(e)) from None
    return names


def _looks(text: str) -> tuple[str, ...]:
    """``--looks``: v1, v2 or both, comma-separated."""
    names = tuple(t.strip() for t in text.split(",") if t.strip())
    if not names or any(n not in LOOKS for n in names):
        raise argparse.ArgumentTypeError(f"expected {' and/or '.join(LOOKS)}, got {text!r}")
    return tuple(LOOKS[n] for n in names)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--houses", type=int, default=120)
    parser.add_argument(
        "--only",
        choices=(
            "generation",
            "env",
            "looks",
            "map",
            "map-accuracy",
            "eval",
            "throughput",
            "teams",
        ),  # fmt: skip
        default=None,
    )
    parser.add_argument("--eval-dataset", help="dataset for the eval row (default: shipped one)")
    parser.add_argument(
        "--teams", type=_teams, default=None,
        help="teams bench: the teams to time, comma-separated (policies or agents/*.yaml; "
        "default: heuristic-none, heuristic-broadcast, hangrcom, memory)",
    )  # fmt: skip
    parser.add_argument(
        "--looks", type=_looks, default=tuple(LOOKS.values()),
        help="teams bench: v1, v2 or both (default), for the team and demos rows",
    )  # fmt: skip
    parser.add_argument(
        "--skip", nargs="+", default=(), choices=("workers", "machine", "demos", "pixels"),
        help="teams bench: parts to leave out (the 2-worker rows play 12 episodes per team; "
        "pixels: the pixels-track rows of heuristic-none and memory)",
    )  # fmt: skip
    parser.add_argument(
        "--segmenter", default="learned", metavar="DIR",
        help="teams bench: the pixels rows through this segmenter's folder (default: the "
        "look's shipped one, agents/segmenter-v1 or -v2)",
    )  # fmt: skip
    parser.add_argument(
        "--procthor",
        default=str(SAMPLE),
        help="ProcTHOR house file for the import row (default: the 20 sample houses of tests/data)",
    )
    args = parser.parse_args(argv)
    if args.segmenter != "learned" and not (Path(args.segmenter) / "model.pt").is_file():
        parser.error(f"--segmenter: no {Path(args.segmenter) / 'model.pt'}; expected a "
                     "segmenter's folder (agents/segmenter-v2) or `learned`")  # fmt: skip
    if args.only in (None, "eval"):
        from maniskill_tidy.eval.benchmark import bench_eval, report

        print(report(bench_eval(dataset=args.eval_dataset)))
        print()
        if args.only == "eval":
            return 0
    if args.only in (None, "throughput"):
        from maniskill_tidy.eval.benchmark import bench_throughput, report_throughput

        print(report_throughput(bench_throughput(dataset=args.eval_dataset)))
        print()
        if args.only == "throughput":
            return 0
    if args.only in (None, "teams"):
        from maniskill_tidy.eval.team_benchmark import (
            PIXELS_TEAMS,
            TEAMS,
            bench_machine,
            bench_team,
            bench_workers,
            pixels_jobs,
            report,
        )
        from maniskill_tidy.training.demos_benchmark import bench_demos

        teams, looks, skip, data = args.teams or TEAMS, args.looks, args.skip, args.eval_dataset
        jobs = [(team, v, "ground-truth") for v in looks for team in teams]
        if "pixels" not in skip:  # where the look's segmenter is trained
            jobs += pixels_jobs([t for t in teams if t in PIXELS_TEAMS], looks, args.segmenter)
        rows = [bench_team(team, dataset=data, env_id=v, segmentation=seg)
                for team, v, seg in tqdm(jobs, desc="teams bench", unit="row")]  # fmt: skip
        workers = [] if "workers" in skip else [bench_workers(t, dataset=data) for t in teams]
        machine = None if "machine" in skip else bench_machine()
        demos = [] if "demos" in skip else [bench_demos(dataset=data, env_id=v) for v in looks]
        print(report(rows, workers, demos, machine))
        print()
        if args.only == "teams":
            return 0
    if args.only in (None, "map-accuracy"):
        from maniskill_tidy.perception.accuracy import bench_map_accuracy, report

        print(report(bench_map_accuracy()))
        print()
        if args.only == "map-accuracy":
            return 0
    if args.only in (None, "map"):
        from maniskill_tidy.perception.benchmark import bench_map, report

        print(report(bench_map()))
        print()
        if args.only == "map":
            return 0
    if args.only in (None, "looks"):
        from maniskill_tidy.envs.looks_benchmark import bench_looks, bench_memory, report

        runs = [bench_looks(s, q) for s in ("I", "II") for q in ("fast", "high")]
        print(report(runs, [bench_memory("realistic")]))
        print()
        if args.only == "looks":
            return 0
    if args.only != "generation":
        from maniskill_tidy.envs.benchmark import bench_env, report

        print(report([bench_env("I"), bench_env("II"), bench_env("I", quality="high")]))
        print()
    if args.only == "env":
        return 0
    print("dataset generation (houses + 10 meta-tasks each, written and hashed)")
    print(f"{'workers':>7} {'houses':>6} {'houses/s':>9} {'calib s':>8} {'houses/calib':>12}")
    for workers in (1, 2):
        r = bench_generation(args.houses, workers)
        print(
            f"{r['workers']:>7} {r['houses']:>6} {r['houses_per_s']:>9.1f} "
            f"{r['calibration_s']:>8.3f} {r['houses_per_calibration']:>12.2f}"
        )
    print()
    source = Path(args.procthor)
    print(f"dataset generation from ProcTHOR houses ({source.name}: import, repair, meta-tasks)")
    header = ("workers", "houses", "kept", "houses/s", "calib s", "houses/calib")
    print(" ".join(f"{h:>{w}}" for h, w in zip(header, (7, 6, 5, 9, 8, 12), strict=True)))
    for workers in (1, 2):
        r = bench_procthor_generation(source, workers)
        print(
            f"{r['workers']:>7} {r['houses']:>6} {r['kept']:>5} {r['houses_per_s']:>9.1f} "
            f"{r['calibration_s']:>8.3f} {r['houses_per_calibration']:>12.2f}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
