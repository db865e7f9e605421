"""Commands that evaluate teams and report: eval, leaderboard, compare, replay."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from maniskill_tidy.cli.options import env_option, ray_option


def _look(policy: str, env: str | None) -> str:
    """The look ``eval`` plays: ``--env``, else the team's (``Team.look``), else the default;
    a note where the team's learned weights were trained on the other look's views."""
    from maniskill_tidy.envs.registration import DEFAULT_ENV
    from maniskill_tidy.policies import team_class

    look = getattr(team_class(policy), "look", None)  # a privileged team reads no pixels
    if env is None and look not in (None, DEFAULT_ENV):
        print(f"note: {policy} reads pixels through weights trained on {look}'s views; "
              f"playing {look} (--env {DEFAULT_ENV} to play it there anyway)")  # fmt: skip
    elif env is not None and look not in (None, env):
        print(f"note: {policy}'s weights were trained on {look}'s views: in {env} the run "
              "measures the look change as well as the team")  # fmt: skip
    return env or look or DEFAULT_ENV


def _segmenter_note(segmentation: str, env: str) -> None:
    """A note where ``--segmentation DIR`` names a segmenter trained on the other look's
    frames (the cross-look row: its own row, ``NAME-pixels-DIR``)."""
    import json

    card = Path(segmentation) / "card.json"
    look = json.loads(card.read_text()).get("look") if card.is_file() else None
    if look not in (None, env):
        print(f"note: {segmentation} was trained on {look}'s frames; played in {env}")


def _eval(args: argparse.Namespace) -> int:
    from maniskill_tidy.common.parallel import workers_option
    from maniskill_tidy.eval.runner import RunConfig, episode_spec, evaluate, run_dir

    env = _look(args.policy, args.env)
    if args.segmentation not in ("ground-truth", "learned"):
        _segmenter_note(args.segmentation, env)
    cfg = RunConfig(
        policy=args.policy,
        setting=args.setting,
        split=args.split,
        dataset=args.dataset,
        episodes=episode_spec(args.episodes),
        seed=args.seed,
        task_type=args.task_type,
        env=env,
        segmentation=args.segmentation,
    )
    summary = evaluate(
        cfg,
        Path(args.out),
        workers=workers_option(args.workers),
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


def _policies(args: argparse.Namespace) -> int:
    from maniskill_tidy.policies import POLICIES

    for name, cls in POLICIES.items():
        comm = getattr(cls, "communication", "none")
        seen = getattr(cls, "perception", "")
        print(f"{name:22s} communication: {comm:10s} perception: {seen}")
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
    print(f"same Success on {d['same_success']} of {d['episodes']} episodes; "
          f"{d['identical']} records identical (all but wall time)")  # fmt: skip
    return 0


def _pixels_losses(args: argparse.Namespace) -> int:
    import json

    from maniskill_tidy.common.files import write_atomic
    from maniskill_tidy.eval.pixels_losses import losses_table, summarise

    path = Path(args.run)
    path = path if path.suffix == ".jsonl" else path / "episodes.jsonl"
    if not path.is_file():
        raise ValueError(f"{args.run}: no episodes.jsonl; expected a pixels run's folder")
    records = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    if not any("pixels" in r for r in records):
        raise ValueError(f"{args.run}: no record holds object fates; expected a pixels run "
                         "(eval --segmentation learned)")  # fmt: skip
    summary = summarise(records)
    print(losses_table(summary, args.top), end="")
    if args.json:
        write_atomic(Path(args.json), json.dumps(summary, indent=1).encode())
    return 0


def _object_fates(args: argparse.Namespace) -> int:
    import json

    from maniskill_tidy.common.files import write_atomic
    from maniskill_tidy.eval.object_fates import object_fates, report

    rows, failures, traces, n = object_fates(args.policy, args.setting, args.split,
                                             args.episodes, args.dataset, args.workers,
                                             args.trace, _look(args.policy, args.env))  # fmt: skip
    for line in traces:
        print(line)
    if args.out is not None:
        write_atomic(Path(args.out), "".join(json.dumps(r) + "\n" for r in rows).encode())
    print(report(args.policy, args.setting, args.split, rows, failures, n))
    return 0


def _unsolved_objects(args: argparse.Namespace) -> int:
    from maniskill_tidy.eval.unsolved_objects import unsolved_objects

    for line in unsolved_objects(Path(args.run), args.dataset):
        print(line)
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
    web = args.web or not has_display()
    if web and not args.web:
        print("no display (DISPLAY and WAYLAND_DISPLAY unset): serving the web viewer on "
              f"{args.bind} instead; open the address it prints")  # fmt: skip
    cmd = [viewer, str(path)] + (["--web-viewer", "--bind", args.bind] if web else [])
    print(" ".join(cmd))
    return subprocess.call(cmd)


def has_display() -> bool:
    """Whether a native window can open here (X11 or Wayland; macOS and Windows always)."""
    import os

    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def add_commands(sub: argparse._SubParsersAction) -> None:
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
        help="a team name (`maniskill-tidy policies` lists them: expert, random, sa, "
        "heuristic-none, -detection, -broadcast, -central, hangrcom, qmix, memory), a learned "
        "team's agent config (agents/NAME.yaml), your own team as package.module:TeamClass, or "
        "an installed package's team (entry point maniskill_tidy.teams)",
    )
    ev.add_argument("--setting", default="I", help="I, II or a preset JSON file")
    env_option(ev, by_team=True)
    ev.add_argument("--split", default="test", choices=("train", "val", "test"))
    ev.add_argument("--task-type", default="all", choices=("all", "single", "cross"))
    ev.add_argument(
        "--episodes",
        default="standard",
        help="standard (first start of every meta-task, the default), all, or a number N "
        "(an evenly spread subset)",
    )
    ev.add_argument(
        "--workers",
        default="auto",
        help="processes playing episodes: a number, or auto (the default: one per core, no "
        "more than the episodes left)",
    )
    ray_option(ev)
    ev.add_argument("--record", default="none", choices=("none", "failures", "all"))
    ev.add_argument("--dataset", help="dataset directory (default: the env's shipped dataset)")
    ev.add_argument("--seed", type=int, default=0)
    ev.add_argument(
        "--images",
        action="store_true",
        help="render every camera every step even for teams that ignore images (timing)",
    )
    ev.add_argument(
        "--segmentation",
        default="ground-truth",
        help="ground-truth (the renderer's, the default), learned (the pixels track: agents see "
        "RGB-D only, through the look's segmenter agents/segmenter-v1 or -v2), or a segmenter "
        "folder (e.g. another look's); a pixels run is its own row, NAME-pixels",
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

    pl = sub.add_parser(
        "pixels-losses", help="why a pixels run lost objects: each misplaced object's fate, by type"
    )
    pl.add_argument("run", help="a pixels run's folder (eval/results/setting_I/NAME-pixels)")
    pl.add_argument("--top", type=int, default=12, help="types listed (most objects lost first)")
    pl.add_argument("--json", help="also write the counts here")
    pl.set_defaults(func=_pixels_losses)

    of = sub.add_parser(
        "object-fates",
        help="what became of each misplaced object in a camera team's episodes (ground truth)",
    )
    of.add_argument("policy", help="a camera team (memory, heuristic-detection, hangrcom, ...)")
    of.add_argument("--setting", default="I", choices=["I", "II"])
    of.add_argument("--split", default="val", choices=["train", "val", "test"])
    of.add_argument("--episodes", type=int, default=40)
    env_option(of, by_team=True)
    of.add_argument("--dataset", help="default: the shipped dataset")
    of.add_argument("--workers", type=int, default=2)
    of.add_argument("--out", help="one JSON line per object (default: print only)")
    of.add_argument("--trace", metavar="EPISODE", help="play only this episode (an id: "
                    "house_00091/task_5/start_0) and print its PickUps and PutDowns")  # fmt: skip
    of.set_defaults(func=_object_fates)

    uo = sub.add_parser(
        "unsolved-objects",
        help="why a run's failed episodes failed, object by object (replays them)",
    )
    uo.add_argument("run", help="an eval run's folder (eval/results/setting_S/NAME)")
    uo.add_argument("--dataset", help="the dataset it ran on, if moved (default: run.json's)")
    uo.set_defaults(func=_unsolved_objects)

    rp = sub.add_parser("replay", help="open an episode recording (.rrd) in the rerun viewer")
    rp.add_argument("file")
    rp.add_argument(
        "--web",
        action="store_true",
        help="serve the web viewer instead (the default where there is no display)",
    )
    rp.add_argument(
        "--bind",
        default="127.0.0.1",
        help="the web viewer's address (default: this machine only; 0.0.0.0 to share)",
    )
    rp.set_defaults(func=_replay)
