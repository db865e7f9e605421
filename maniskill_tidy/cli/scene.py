"""Commands that show the env: its looks, an episode, a semantic map, the renderers."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from maniskill_tidy.cli.options import env_option, episode_options


def _show_assets(args: argparse.Namespace) -> int:
    from maniskill_tidy.sim.gallery import write_gallery

    for path in write_gallery(Path(args.out)):
        print(f"wrote {path}")
    return 0


def _show_looks(args: argparse.Namespace) -> int:
    from maniskill_tidy.envs.looks_figure import looks_figure

    out = looks_figure(Path(args.out), args.dataset, args.split, args.episode)
    print(f"wrote {out}")
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


def _check_render(args: argparse.Namespace) -> int:
    from maniskill_tidy.eval import backend_check as bc

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


def _show_masks(args: argparse.Namespace) -> int:
    from maniskill_tidy.eval.masks_figure import masks_figure
    from maniskill_tidy.models.checkpoints import verify

    if not args.out.endswith(".png"):
        raise ValueError(f"--out {args.out}: expected a .png file name")
    verify(Path(args.segmenter), "maniskill-tidy train-segmenter")
    out = masks_figure(Path(args.out), args.segmenter, args.env, args.dataset, args.split,
                       args.episode)  # fmt: skip
    print(f"wrote {out}")
    return 0


def add_commands(sub: argparse._SubParsersAction) -> None:
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

    sm = sub.add_parser(
        "show-masks", help="agent frames: the truth, the segmenter's classes, objects agents find"
    )
    sm.add_argument("--segmenter", default="agents/segmenter-v2", help="a segmenter's folder")
    sm.add_argument("--dataset", help="default: the shipped dataset")
    sm.add_argument("--split", default="test")
    sm.add_argument("--episode", type=int, default=0)
    sm.add_argument("--out", required=True, help="a .png")
    env_option(sm)
    sm.set_defaults(func=_show_masks)

    e = sub.add_parser(
        "run-episode", help="play one episode with an exploring policy; save camera and house PNGs"
    )
    episode_options(e)
    e.add_argument("--steps", type=int, default=30)
    e.add_argument("--seed", type=int, default=0)
    e.add_argument("--out", default="out/episode")
    e.set_defaults(func=_run_episode)

    sm = sub.add_parser(
        "show-map", help="draw an agent's semantic map after a scripted look-around as a PNG"
    )
    episode_options(sm)
    sm.add_argument("--agent", default="agent_0")
    sm.add_argument(
        "--horizons", type=int, nargs="+", help="camera tilts to turn around at (default 0 30)"
    )
    sm.add_argument("--out", default="map.png")
    sm.set_defaults(func=_show_map)

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
