"""A heuristic team with and without the full-surface rule, paired on the same episodes.

    python scripts/full_surface_ab.py heuristic-detection --setting I --split val \
        --out out/full_surface

``HeuristicAgent.FULL_SURFACE_RULE``: a PutDown the env refused with "no room for X on S"
(it searched all of S) gives S up for X at once, instead of walking to the next viewpoint of S
and trying again. Plays the episodes of ``--episodes`` (``standard``, as ``eval``; seed = the
episode's index) once with the rule off (the heuristic teams' rule before it became the
default) and once on, writes each as ``OUT/off/episodes.jsonl`` and ``OUT/on/episodes.jsonl``
(``maniskill-tidy compare`` reads them), and prints on - off, paired. The train or val split:
the rule was chosen here; the leaderboard's rows were re-run on test under it.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

_worker: dict = {}


def _init(cfg) -> None:
    from maniskill_tidy.eval.runner import make_env
    from maniskill_tidy.policies import make_team

    _worker.update(cfg=cfg, env=make_env(cfg), team=make_team(cfg.policy))
    return lambda: _worker["env"].close()


def _play(job: tuple[int, bool]) -> dict:
    from maniskill_tidy.eval.runner import run_episode
    from maniskill_tidy.policies.heuristic import HeuristicAgent

    index, rule = job
    default = HeuristicAgent.FULL_SURFACE_RULE
    HeuristicAgent.FULL_SURFACE_RULE = rule  # agents are made fresh for every episode
    try:
        return run_episode(_worker["env"], _worker["team"], index, index).to_dict()
    finally:
        HeuristicAgent.FULL_SURFACE_RULE = default


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("policy", help="a heuristic team: heuristic-none, -detection, -broadcast, ...")
    p.add_argument("--setting", default="I", choices=["I", "II"])
    p.add_argument("--split", default="val", choices=["train", "val"])
    p.add_argument("--episodes", default="standard", help="standard, all or a number")
    p.add_argument("--dataset", default="data/tidy120")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args()
    from tqdm import tqdm

    from maniskill_tidy.common.parallel import run_jobs
    from maniskill_tidy.envs.episodes import EpisodeSet
    from maniskill_tidy.eval.metrics import METRICS, EpisodeRecord, paired_difference
    from maniskill_tidy.eval.runner import RunConfig, episode_spec, select
    from maniskill_tidy.policies import POLICIES
    from maniskill_tidy.policies.heuristic import HeuristicTeam
    from maniskill_tidy.tasks.teams import team as parse_team

    team = POLICIES.get(args.policy)
    if team is None or not issubclass(team, HeuristicTeam):
        heuristic = sorted(n for n, t in POLICIES.items() if issubclass(t, HeuristicTeam))
        p.error(f"policy {args.policy!r}: expected a heuristic team, one of {heuristic}")
    try:
        spec = episode_spec(args.episodes)
    except ValueError as err:
        p.error(str(err))
    if not Path(args.dataset).is_dir():
        p.error(f"--dataset {args.dataset}: not found; expected a folder made by `generate`")
    cfg = RunConfig(args.policy, args.setting, args.split, args.dataset)
    # as eval does: the smallest setting that fits the team gives the starts (SA: Setting I's)
    members = parse_team(getattr(team, "team_override", None) or args.setting)
    starts = EpisodeSet(args.dataset, args.split, "all", None, members).episodes
    chosen = select([e.start for e in starts], spec)
    jobs = [(i, rule) for rule in (False, True) for i in chosen]
    played: dict[bool, list[dict]] = {False: [], True: []}
    with tqdm(total=len(jobs), desc=f"{args.policy} off, then on", unit="episode") as bar:
        for (_, rule), record in run_jobs(jobs, _play, args.workers, init=_init,
                                          initargs=(cfg,), ordered=True):  # fmt: skip
            played[rule].append(record)
            bar.update(1)
    for rule, name in ((False, "off"), (True, "on")):
        folder = args.out / name
        folder.mkdir(parents=True, exist_ok=True)
        tmp = folder / "episodes.jsonl.tmp"
        tmp.write_text("".join(json.dumps(r) + "\n" for r in played[rule]))
        tmp.replace(folder / "episodes.jsonl")
    d = paired_difference(*([EpisodeRecord(**r) for r in played[rule]] for rule in (True, False)))
    print(f"{args.policy}, Setting {args.setting}, {args.split}: the rule on - off over "
          f"{d['episodes']} episodes (95 % paired interval)")  # fmt: skip
    for m in METRICS:
        x = d[m]
        print(f"{m:>8} {x['difference']:+8.3f} [{x['ci95'][0]:+.3f}, {x['ci95'][1]:+.3f}]  "
              f"{x['better']} better, {x['worse']} worse")  # fmt: skip


if __name__ == "__main__":
    main()
