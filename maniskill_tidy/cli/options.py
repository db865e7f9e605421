"""Options several commands share."""

from __future__ import annotations

import argparse


def env_option(p: argparse.ArgumentParser) -> None:
    from maniskill_tidy.envs.registration import VERSIONS

    p.add_argument(
        "--env",
        default="HeteroTidy-v1",
        choices=tuple(VERSIONS),
        help="the env version, i.e. the look: v1 flat-coloured primitives (the committed "
        "results), v2 realistic meshes and materials; the task is the same",
    )


def episode_options(p: argparse.ArgumentParser) -> None:
    """Which episode a command plays: --setting, --dataset, --split, --episode, --env."""
    env_option(p)
    p.add_argument("--setting", default="I")
    p.add_argument("--dataset", help="dataset directory (default: the env's shipped dataset)")
    p.add_argument("--split", default="test")
    p.add_argument("--episode", default="0", help="index or id in the split")


def ray_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--ray",
        nargs="?",
        const="local",
        metavar="ADDRESS",
        help="run the workers as Ray actors: alone, a local Ray instance with --workers CPUs; "
        "with the address of a running cluster (ray start --head), --workers actors there",
    )
