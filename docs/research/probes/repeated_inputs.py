"""How often a learned agent's perception sees the same inputs as at its previous step (issue 48).

    python docs/research/probes/repeated_inputs.py [--policy hangrcom] [--episodes 3] [--setting I]

A frozen model's output could be reused, bit for bit, where its inputs repeat; this counts, over
Setting I test episodes, the share of agent-steps whose resized RGB, seen-category shares, map
crop and detections equal the same agent's at its previous step. Nothing is written.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import threading
from collections import Counter

from maniskill_tidy.eval.episode import play_episode
from maniskill_tidy.eval.runner import RunConfig, make_env, select
from maniskill_tidy.models.perception import PerceptionModel
from maniskill_tidy.policies import make_team
from maniskill_tidy.policies.learned import LearnedAgent


def main() -> None:
    # the agents think in this process, where the measuring wrappers are
    os.environ["TIDY_AGENT_PROCESSES"] = "0"
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--policy", default="hangrcom")
    p.add_argument("--episodes", type=int, default=3)
    p.add_argument("--setting", default="I", choices=("I", "II"))
    p.add_argument("--dataset", default="data/tidy120")
    args = p.parse_args()

    local, last, repeats = threading.local(), {}, Counter()
    observe, step_features = LearnedAgent.observe, PerceptionModel.step_features

    def observing(self, view):
        local.agent = self.name
        return observe(self, view)

    def counted(self, rgb, seen, crop, det_row, det_type, det_rest, det_numeric):
        inputs = {"rgb": rgb, "seen": seen, "crop": crop, "detections": det_numeric}
        digest = {k: hashlib.sha1(v.numpy().tobytes()).digest() for k, v in inputs.items()}
        before = last.get(local.agent)
        repeats["agent-steps"] += 1
        if before is not None:
            for k in digest:
                repeats[k] += digest[k] == before[k]
            repeats["all four"] += digest == before
        last[local.agent] = digest
        return step_features(self, rgb, seen, crop, det_row, det_type, det_rest, det_numeric)

    LearnedAgent.observe, PerceptionModel.step_features = observing, counted
    cfg = RunConfig(args.policy, args.setting, "test", args.dataset, args.episodes)
    env, team = make_env(cfg), make_team(args.policy)
    for i in select([e.start for e in env.unwrapped.episodes.episodes], args.episodes):
        last.clear()
        play_episode(env, team, i, i)
    env.close()
    n = repeats.pop("agent-steps")
    print(f"{args.policy}, {n} agent-steps; share equal to the agent's previous step:")
    for k in ("rgb", "seen", "crop", "detections", "all four"):
        print(f"  {k:12s} {repeats[k] / n:.3f}")


if __name__ == "__main__":
    main()
