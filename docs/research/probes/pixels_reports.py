"""How one episode's reports travel in a team of heuristic agents: for each manipulator, each
step a report (an object a teammate saw) reaches its memory, is dismissed (looked for from a
cell and not found) or a job changes. Shows whether an object seen only by a teammate that
cannot pick up is lost to a dismissed report, on ground truth or through the pixels pipeline.

    .venv/bin/python docs/research/probes/pixels_reports.py house_00110/task_0/start_0 \\
        --policy memory --segmentation ground-truth
"""

from __future__ import annotations

import argparse

import numpy as np
import pixels_probe


def entries(reports) -> set[tuple]:
    return {(r.type, tuple(np.round(r.xy, 2))) for r in reports}


class ReportTrace:
    """An episode observer printing each manipulator's report and job changes."""

    def start(self, env, team, channel) -> None:
        self.before: dict[str, tuple] = {}

    def executing(self, agents) -> None:
        self.agents = agents

    def decided(self, t, actions, labels) -> None:
        for name, agent in self.agents.items():
            inner = getattr(agent, "inner", agent)  # a pixels agent's team agent
            if not inner.manipulator:
                continue
            reports, dismissed = entries(inner.reports), entries(inner.dismissed)
            job = inner.job and (inner.job.kind, inner.job.target)
            old_reports, old_dismissed, old_job = self.before.get(name, (set(), set(), None))
            for r in sorted(reports - old_reports):
                print(f"{t:4d} {name}: report {r}")
            for r in sorted(dismissed - old_dismissed):
                print(f"{t:4d} {name}: dismissed {r} from cell {inner.state.cell}")
            if job != old_job:
                print(f"{t:4d} {name}: job {job}")
            self.before[name] = (reports, dismissed, job)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("episode", help="an episode id, e.g. house_00110/task_0/start_0")
    ap.add_argument("--policy", default="memory")
    ap.add_argument("--dataset", default="data/tidy120")
    ap.add_argument("--segmentation", default="learned")
    ap.add_argument("--labels", choices=("segmenter", "renderer"), default="segmenter")
    args = ap.parse_args()
    extra = [pixels_probe.TruthLabels()] if args.labels == "renderer" else []
    record = pixels_probe.play_one(ap, args.episode, [*extra, ReportTrace()], args.policy,
                                   "test", args.dataset, args.segmentation)  # fmt: skip
    print(f"{record.episode}: success {record.success}, placed {record.reasonable}")


if __name__ == "__main__":
    main()
