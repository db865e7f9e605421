"""The paper's metrics (Section 6.2), from per-episode records, split Single / Cross / All.

- Success: share of episodes where every misplaced object ends in a reasonable place.
- %PS (%PartialSuccess): mean over episodes of K_suc / K, objects re-placed reasonably.
- %FM (%FindMisObj): mean of K_det / K, misplaced objects detected *and picked up* by an agent.
- #PL (#PathLength): mean episode length, the largest number of steps any agent took (<= 300).
- ACm (AvgCom): mean of Total / (Len * N), message dimensions received per agent per step.
- CES: max(0, 10000 * (Suc - Suc_SA) / ACm), against the single-agent baseline's success;
  undefined (None) without communication (ACm = 0), as the paper leaves it blank.

Every metric comes with a 95 % confidence interval: the 2.5 and 97.5 percentiles of the metric
over ``BOOTSTRAP`` resamples of the episodes (drawn with replacement, seeded, so the same
records always give the same interval).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

SPLITS = ("Single", "Cross", "All")
METRICS = ("Success", "%PS", "%FM", "#PL", "ACm")
LOWER_IS_BETTER = ("#PL", "ACm")  # fewer steps; fewer messages (the paper's cost)
BOOTSTRAP = 2000  # resamples for the confidence intervals
BOOTSTRAP_SEED = 0


@dataclass(frozen=True)
class EpisodeRecord:
    """One finished episode: a line of the runner's JSONL file."""

    episode: str
    task_kind: str  # "Single" or "Cross"
    k: int  # misplaced objects
    success: bool
    reasonable: int  # K_suc
    found: int  # K_det: misplaced objects some agent picked up
    length: int  # Len: max steps over agents
    comm: int  # Total: dimensions received over the episode
    agents: int  # N
    seed: int
    seconds: float = 0.0
    failed_actions: int = 0
    # pixels runs only: each misplaced object's fate and the false pickups
    # (``eval/pixels_losses.py``); absent from the records of the ground-truth track
    pixels: dict | None = None

    def to_dict(self) -> dict:
        d = asdict(self)
        if d["pixels"] is None:
            del d["pixels"]
        return d

    @classmethod
    def from_dict(cls, d: dict) -> EpisodeRecord:
        return cls(**d)


def avg_com(r: EpisodeRecord) -> float:
    return r.comm / (max(r.length, 1) * r.agents)


def per_episode(records: list[EpisodeRecord]) -> dict[str, np.ndarray]:
    """Each metric's value per episode (every metric is a mean over episodes)."""
    return {
        "Success": np.array([float(r.success) for r in records]),
        "%PS": np.array([r.reasonable / r.k for r in records]),
        "%FM": np.array([r.found / r.k for r in records]),
        "#PL": np.array([float(r.length) for r in records]),
        "ACm": np.array([avg_com(r) for r in records]),
    }


def bootstrap_ci(values: np.ndarray, seed: int = BOOTSTRAP_SEED) -> list[float]:
    """95 % percentile interval of the mean of ``values`` over seeded resamples."""
    rng = np.random.default_rng(seed)
    means = values[rng.integers(0, len(values), (BOOTSTRAP, len(values)))].mean(axis=1)
    return [float(np.percentile(means, 2.5)), float(np.percentile(means, 97.5))]


def split_metrics(records: list[EpisodeRecord]) -> dict:
    if not records:
        return {m: None for m in METRICS} | {"episodes": 0, "ci95": {}}
    values = per_episode(records)
    out: dict = {m: float(values[m].mean()) for m in METRICS}
    out["episodes"] = len(records)
    out["ci95"] = {m: bootstrap_ci(values[m]) for m in METRICS}
    return out


def summarize(records: list[EpisodeRecord]) -> dict[str, dict]:
    """Metrics for Single, Cross and All episodes."""
    return {
        "Single": split_metrics([r for r in records if r.task_kind == "Single"]),
        "Cross": split_metrics([r for r in records if r.task_kind == "Cross"]),
        "All": split_metrics(list(records)),
    }


def run_totals(records: list[EpisodeRecord]) -> dict:
    """Counts the metrics average away: objects placed reasonably in all the episodes, and
    failed actions per episode (the actions the env refused, over every agent)."""
    n = max(len(records), 1)
    return {
        "placed": sum(r.reasonable for r in records),
        "misplaced": sum(r.k for r in records),
        "failed_per_episode": sum(r.failed_actions for r in records) / n,
        "agent_steps_per_episode": sum(r.length * r.agents for r in records) / n,
    }


def same_record(a: EpisodeRecord, b: EpisodeRecord) -> bool:
    """Two plays of one episode that agree in everything but their wall time: how close a
    student plays to its teacher, or a refactor to the code before it."""
    return replace(a, seconds=b.seconds) == b


def paired_difference(a: list[EpisodeRecord], b: list[EpisodeRecord]) -> dict:
    """Per metric, the mean of A - B over the episodes both runs played, with a 95 % interval
    from resampling those episodes (the pair kept together) and how many episodes A did better
    or worse on (fewer is better for #PL and ACm). Pairing removes the spread between
    episodes, which dominates the intervals of two separate means on tens of episodes."""
    by_id = {r.episode: r for r in b}
    shared = [r.episode for r in a if r.episode in by_id]
    if not shared:
        raise ValueError("the two runs have no episode in common; expected runs of one split")
    mine = {r.episode: r for r in a}
    ra, rb = [mine[e] for e in shared], [by_id[e] for e in shared]
    va, vb = per_episode(ra), per_episode(rb)
    pairs = list(zip(ra, rb, strict=True))
    out: dict = {"episodes": len(shared), "totals": {"A": run_totals(ra), "B": run_totals(rb)},
                 "same_success": sum(x.success == y.success for x, y in pairs),
                 "identical": sum(same_record(x, y) for x, y in pairs)}  # fmt: skip
    for m in METRICS:
        d = va[m] - vb[m]
        gain = -d if m in LOWER_IS_BETTER else d  # which way "A better" counts
        out[m] = {"difference": float(d.mean()), "ci95": bootstrap_ci(d),
                  "better": int((gain > 0).sum()), "worse": int((gain < 0).sum())}  # fmt: skip
    return out


def ces(success: float, success_sa: float, acm: float) -> float | None:
    """Communication efficiency score; None when nothing was sent."""
    if acm <= 0:
        return None
    return max(0.0, 10000.0 * (success - success_sa) / acm)
