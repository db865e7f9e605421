"""Options several commands share."""

from __future__ import annotations

import argparse


def env_option(p: argparse.ArgumentParser, by_team: bool = False) -> None:
    """``--env``, the look: v2 unless told; ``by_team``: None, for ``eval`` to play a team in
    the look its learned weights read pixels in (``Team.look``), else v2."""
    from maniskill_tidy.envs.registration import DEFAULT_ENV, VERSIONS

    p.add_argument(
        "--env",
        default=None if by_team else DEFAULT_ENV,
        choices=tuple(VERSIONS),
        help=f"the env version, i.e. the look (default {DEFAULT_ENV}"
        + (", or v1 for a team whose learned weights were trained on v1's views" if by_team else "")
        + "): v2 realistic meshes and materials, v1 flat-coloured primitives (where the "
        "leaderboard's first rows and the learned teams' weights were made); the task is the same",
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
