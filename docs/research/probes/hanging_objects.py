"""Objects the generator hangs from a towel bar, and where they rest in the simulator (research
log, twenty-first part): how many episodes of a split hold one, and for the named episodes each
object's bottom beside the surface it was placed on and what the env's ``Manipulation.locate``
says of it.

    .venv/bin/python docs/research/probes/hanging_objects.py --dataset data/tidy120 --split val \\
        --show house_00082/task_7:Candle_0 house_00085/task_0:SprayBottle_0 \\
        house_00093/task_8:BaseballBat_0
"""

from __future__ import annotations

import argparse
from pathlib import Path

from maniskill_tidy.envs.hetero_tidy import HeteroTidyEnv
from maniskill_tidy.tasks.dataset import load_dataset


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--dataset", default="data/tidy120")
    p.add_argument("--split", default="val")
    p.add_argument("--show", nargs="*", default=[], metavar="TASK:OBJECT")
    args = p.parse_args()
    for split in dict.fromkeys([args.split, "test"]):
        episodes = list(load_dataset(Path(args.dataset), split).episodes("I"))
        hung = [mt for mt, _ in episodes if any(m.misplaced.surface == "bar" for m in mt.misplaced)]
        print(f"{split}: {len(hung)} of {len(episodes)} episodes hold an object hung on a bar")
    want = dict(s.split(":") for s in args.show)
    if not want:
        return
    env = HeteroTidyEnv(setting="I", dataset=args.dataset, split=args.split, obs_mode="none")
    for i in range(len(env.episodes)):
        ep = env.episodes.get(i)
        if ep.start != 0 or ep.task.id not in want:
            continue
        env.reset(options={"episode": i})
        oid = want[ep.task.id]
        spot = next(m.misplaced for m in ep.task.misplaced if m.object == oid)
        f = env.hs.house.furniture_by_id()[spot.receptacle]
        surface = next(s for s in f.surfaces if s.name == spot.surface)
        top = env.manipulation.surface_centre(f, surface)[2]
        bottom = env.hs.object_bottom(oid)[2]
        print(f"{ep.task.id} {oid}: on {spot.receptacle} {spot.surface} at {top:.3f} m, "
              f"bottom {bottom:.3f} m, height {env.manipulation.sizes[oid][2]:.3f} m, "
              f"locate: {env.manipulation.locate(oid).receptacle}")


if __name__ == "__main__":
    main()
