"""Commands that make, check, draw and convert datasets."""

from __future__ import annotations

import argparse
import json
import re
import time
from pathlib import Path

from maniskill_tidy.cli.options import ray_option
from maniskill_tidy.knowledge import load_catalog, load_placement
from maniskill_tidy.tasks.metatask import SINGLE_FRACTION


def _split_numbers(text: str | None) -> tuple | None:
    if text is None:
        return None
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 3:
        raise ValueError(f"--split {text!r}: expected three numbers TRAIN,VAL,TEST")
    return values


def _generate_procthor(args: argparse.Namespace) -> int:
    from maniskill_tidy.tasks.procthor_dataset import DEFAULT_WEIGHTS, generate_procthor_dataset

    start = time.perf_counter()
    manifest = generate_procthor_dataset(
        Path(args.procthor),
        Path(args.out),
        args.seed,
        _split_numbers(args.split) or DEFAULT_WEIGHTS,
        limit=args.houses,
        workers=args.workers,
        single_fraction=args.single_fraction,
        ray=args.ray,
    )
    elapsed = time.perf_counter() - start
    read = manifest["source"]["houses_read"]
    print(
        f"wrote {args.out}: {manifest['houses']} of {read} ProcTHOR houses kept "
        f"{manifest['splits']}, tasks {manifest['tasks']}, hash {manifest['dataset_hash'][:12]}, "
        f"{read / elapsed:.1f} houses/s ({elapsed:.1f} s, {args.workers} workers)"
    )
    reasons: dict[str, int] = {}
    for r in manifest["rejected"]:
        key = re.sub(r"\d+", "N", r["reason"].split(":")[0])
        reasons[key] = reasons.get(key, 0) + 1
    for reason, n in sorted(reasons.items(), key=lambda kv: -kv[1]):
        print(f"  rejected {n}: {reason}")
    return 0


def _generate(args: argparse.Namespace) -> int:
    from maniskill_tidy.tasks.dataset import generate_dataset, secret_seed

    if args.procthor:
        return _generate_procthor(args)
    if args.houses is None:
        raise ValueError("--houses is required (or --procthor FILE to import houses)")
    split = _split_numbers(args.split)
    counts = tuple(int(v) for v in split) if split else None
    if split is not None and counts != split:
        raise ValueError(f"--split {args.split!r}: expected three house counts TRAIN,VAL,TEST")
    secret = args.secret_seed_file is not None or args.secret_seed
    seed = secret_seed(args.secret_seed_file) if secret else args.seed
    start = time.perf_counter()
    manifest = generate_dataset(
        Path(args.out),
        args.houses,
        seed,
        counts,
        workers=args.workers,
        single_fraction=args.single_fraction,
        ray=args.ray,
        secret=secret,
    )
    elapsed = time.perf_counter() - start
    print(
        f"wrote {args.out}: {manifest['houses']} houses {manifest['splits']}, "
        f"tasks {manifest['tasks']}, hash {manifest['dataset_hash'][:12]}, "
        f"{args.houses / elapsed:.1f} houses/s ({elapsed:.1f} s, {args.workers} workers)"
    )
    return 0


def _export(args: argparse.Namespace) -> int:
    from maniskill_tidy.houses.procthor_export import ON_LEFT_OUT, export_houses
    from maniskill_tidy.tasks.dataset import SPLITS, load_dataset, read_manifest

    if not args.out.endswith((".jsonl", ".jsonl.gz")):
        raise ValueError(f"--out {args.out}: expected a .jsonl or .jsonl.gz file name")
    read_manifest(Path(args.procthor))  # a dataset directory, or a one-line error
    houses = [
        h for split in SPLITS for h in load_dataset(Path(args.procthor), split).houses.values()
    ]
    left_out = export_houses(houses, Path(args.out))
    print(f"wrote {args.out}: {len(houses)} houses in ProcTHOR's format")
    no_asset = {t: n for t, n in left_out.items() if ON_LEFT_OUT not in t}
    carried = sum(n for t, n in left_out.items() if ON_LEFT_OUT in t)
    if no_asset:
        what = ", ".join(f"{t} x{n}" for t, n in sorted(no_asset.items()))
        print(f"  left out, no asset of their type in ProcTHOR's database: {what}")
    if carried:
        print(f"  left out with them: {carried} objects and pieces that stood on them")
    return 0


def _validate(args: argparse.Namespace) -> int:
    from maniskill_tidy.tasks.validate import validate_dataset

    problems = validate_dataset(Path(args.dir))
    if args.physics and not problems:  # the simulator is imported only when it is needed
        from maniskill_tidy.envs.settle_check import physics_problems

        problems = physics_problems(Path(args.dir))
    for p in problems[: args.max_problems]:
        print(p)
    if len(problems) > args.max_problems:
        print(f"... and {len(problems) - args.max_problems} more")
    print(f"{args.dir}: {'OK' if not problems else f'{len(problems)} problems'}")
    return 1 if problems else 0


def _stats(args: argparse.Namespace) -> int:
    from maniskill_tidy.tasks.stats import dataset_stats, format_stats, plot_stats

    stats = dataset_stats(Path(args.dir))
    print(format_stats(stats))
    out = plot_stats(stats, Path(args.png or Path(args.dir) / "dataset-stats.png"))
    if args.json:
        Path(args.json).write_text(json.dumps(stats, indent=1) + "\n")
    print(f"figure: {out}")
    return 0


def _show_house(args: argparse.Namespace) -> int:
    from maniskill_tidy.houses.draw import draw_house

    highlight, title = {}, None
    if args.procthor:
        from maniskill_tidy.houses.procthor import read_procthor_houses

        problems: list[str] = []
        wanted = f"procthor_{args.index:05d}"
        house = next(
            (h for h in read_procthor_houses(Path(args.procthor), problems) if h.id == wanted),
            None,
        )
        if house is None:
            bad = [p for p in problems if p.startswith(f"house {args.index} ")]
            raise ValueError(
                bad[0] if bad else f"{args.procthor} has fewer than {args.index + 1} houses"
            )
    elif args.dataset:
        from maniskill_tidy.tasks.dataset import load_dataset
        from maniskill_tidy.tasks.metatask import apply_task

        data = load_dataset(Path(args.dataset), args.split)
        houses = list(data.houses.values())
        if not 0 <= args.index < len(houses):
            raise ValueError(f"--index {args.index}: split {args.split} has {len(houses)} houses")
        house = houses[args.index]
        if args.task is not None:
            tasks = [t for t in data.tasks if t.house_id == house.id]
            if not 0 <= args.task < len(tasks):
                raise ValueError(f"--task {args.task}: {house.id} has {len(tasks)} meta-tasks")
            task = tasks[args.task]
            house = apply_task(house, task)
            highlight = {m.object: "#d32f2f" for m in task.misplaced}
            title = f"{task.id}: {task.kind}, k={task.k}: " + ", ".join(
                f"{m.type} ({m.how})" for m in task.misplaced
            )
    else:
        from maniskill_tidy.houses.generator import generate_house

        house = generate_house(args.seed, args.index)
    out = draw_house(house, Path(args.out), highlight=highlight, title=title)
    print(
        f"{house.id}: {len(house.rooms)} rooms {house.room_spec}, {len(house.furniture)} "
        f"furniture, {len(house.objects)} objects -> {out}"
    )
    return 0


def _knowledge(args: argparse.Namespace) -> int:
    catalog, knowledge = load_catalog(), load_placement()
    print(
        f"{len(catalog.categories)} object categories, {len(catalog.pickupable)} pickupable "
        f"({len(catalog.tidyable)} with a reasonable place), {len(catalog.receptacles)} "
        f"receptacle types, {sum(len(v) for v in knowledge.reasonable.values())} reasonable "
        f"(object, receptacle, room) triples"
    )
    if args.object:
        locs = sorted(knowledge.locations(args.object))
        print(f"{args.object}: " + (", ".join(f"{p} in {r}" for p, r in locs) or "nowhere"))
    return 0


def add_commands(sub: argparse._SubParsersAction) -> None:
    g = sub.add_parser("generate", help="generate houses and tidy-up tasks")
    g.add_argument(
        "--houses", type=int, help="how many houses (with --procthor: read at most the first N)"
    )
    g.add_argument("--seed", type=int, default=0)
    g.add_argument(
        "--secret-seed-file",
        metavar="FILE",
        help="a split whose seed no file records: read the seed from FILE (or, with "
        "--secret-seed, from $MANISKILL_TIDY_SECRET_SEED); the dataset says 'secret'",
    )
    g.add_argument(
        "--secret-seed", action="store_true", help="the seed of $MANISKILL_TIDY_SECRET_SEED"
    )
    g.add_argument("--out", required=True)
    g.add_argument(
        "--procthor",
        metavar="FILE",
        help="build the dataset from the houses of a ProcTHOR .jsonl(.gz) file, repairing or "
        "rejecting each (reasons in the manifest)",
    )
    g.add_argument(
        "--split",
        help="TRAIN,VAL,TEST house counts (default: 4:1:1 as 80/20/20); with --procthor, "
        "proportions of the kept houses (default 4,1,1)",
    )
    g.add_argument("--workers", type=int, default=1)
    ray_option(g)
    g.add_argument(
        "--single-fraction",
        type=float,
        default=SINGLE_FRACTION,
        help="share of meta-tasks meant to be Single-room (default %(default)s: the paper's "
        "test split, 565 of 1000)",
    )
    g.set_defaults(func=_generate)

    x = sub.add_parser("export", help="write a dataset's houses in another format")
    x.add_argument(
        "--procthor", required=True, metavar="DIR", help="dataset directory to write as ProcTHOR"
    )
    x.add_argument("--out", required=True, help="ProcTHOR house file (.jsonl or .jsonl.gz)")
    x.set_defaults(func=_export)

    v = sub.add_parser("validate", help="check a dataset and explain what is wrong")
    v.add_argument("dir")
    v.add_argument("--max-problems", type=int, default=50)
    v.add_argument(
        "--physics",
        action="store_true",
        help="also build every house in the simulator and check that no object moves more "
        "than 3 cm when an episode starts (about 0.3 s a meta-task)",
    )
    v.set_defaults(func=_validate)

    s = sub.add_parser("dataset-stats", help="Fig. 5 statistics of a dataset, printed and drawn")
    s.add_argument("dir")
    s.add_argument("--png")
    s.add_argument("--json")
    s.set_defaults(func=_stats)

    h = sub.add_parser("show-house", help="draw a house top-down as a PNG")
    h.add_argument("--seed", type=int, default=0)
    h.add_argument("--index", type=int, default=0, help="house index (in the split or file)")
    h.add_argument("--dataset", help="draw a house of this dataset")
    h.add_argument("--split", default="train")
    h.add_argument("--task", type=int, help="with --dataset: show this meta-task's mess")
    h.add_argument("--procthor", help="draw a house of a ProcTHOR .jsonl(.gz) file")
    h.add_argument("--out", default="house.png")
    h.set_defaults(func=_show_house)

    k = sub.add_parser("knowledge", help="type counts; reasonable places of an object type")
    k.add_argument("object", nargs="?")
    k.set_defaults(func=_knowledge)
