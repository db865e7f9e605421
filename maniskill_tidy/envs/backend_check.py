"""Do two render backends show the agents the same? Lavapipe (CPU) against CUDA, step by step.

The expert plays an episode on one env; a twin env in its own process (SAPIEN allows one
renderer per process), the same house and episode on the other backend, is stepped with the
same actions. Each step compares, per agent, what decides outcomes:
the instances covering at least ``MIN_PIXELS`` pixels of the segmentation (PickUp, PutDown and
the detectors all use that rule), the share of pixels whose instance agrees, the depth where both
see the same instance, and each action's outcome (failure reason, held object). Once an outcome
differs the two episodes diverge, so the first such step is reported and later ones are counted
apart.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.envs.hetero_tidy import default_render_backend, pixel_counts

BACKENDS = ("cpu", "gpu")


@dataclass
class BackendComparison:
    backends: tuple[str, str]
    episodes: int = 0
    agent_steps: int = 0
    visible_differs: int = 0  # agent-steps whose >= MIN_PIXELS instance sets differ
    outcome_differs: int = 0  # agent-steps whose action outcome or held object differs
    first_divergence: list[str] = field(default_factory=list)  # "episode step agent: what"
    pixel_agreement: list[float] = field(default_factory=list)
    depth_median_abs: list[float] = field(default_factory=list)  # metres, where ids agree

    def summary(self) -> dict:
        agree = np.asarray(self.pixel_agreement or [1.0])
        depth = np.asarray(self.depth_median_abs or [0.0])
        return {
            **{k: v for k, v in asdict(self).items() if k not in ("pixel_agreement",
                                                                   "depth_median_abs")},
            "pixel_agreement_mean": float(agree.mean()),
            "pixel_agreement_min": float(agree.min()),
            "depth_median_abs_max_m": float(depth.max()),
        }  # fmt: skip


def _visible(seg: np.ndarray) -> set[int]:
    return {int(i) for i, n in pixel_counts(seg).items() if i and n >= MIN_PIXELS}


def _serve_twin(conn, backend: str, kwargs: dict) -> None:
    """The twin env, alone in its process (one SAPIEN renderer per process): answers
    ("reset", (index, seed)) and ("step", actions) with what the comparison reads."""
    import gymnasium as gym

    import maniskill_tidy  # noqa: F401  (registers the env)
    from maniskill_tidy.parallel import die_with_parent

    die_with_parent()
    env = gym.make("HeteroTidy-v1", render_backend=backend, **kwargs)
    keys = ("segmentation", "depth", "held")
    try:
        while (msg := conn.recv()) is not None:
            what, arg = msg
            if what == "reset":
                obs, info = env.reset(seed=arg[1], options={"episode": arg[0]})
            else:
                obs, _, _, _, info = env.step(arg)
            view = {n: {k: o[k] for k in keys} for n, o in obs.items()}
            conn.send((view, {"failed": dict(info.get("failed", {}))}))
    finally:
        env.close()


class Twin:
    """The other backend's env in a child process."""

    def __init__(self, backend: str, kwargs: dict) -> None:
        from multiprocessing import get_context

        ctx = get_context("spawn")
        self.conn, child = ctx.Pipe()
        self.process = ctx.Process(target=_serve_twin, args=(child, backend, kwargs), daemon=True)
        self.process.start()

    def call(self, what: str, arg) -> tuple[dict, dict]:
        self.conn.send((what, arg))
        return self.conn.recv()

    def close(self) -> None:
        self.conn.send(None)
        self.process.join(timeout=60)


class TwinObserver:
    """Steps ``twin`` with the actions the team chose on the observed env, and compares."""

    def __init__(self, twin: Twin, index: int, seed: int, result: BackendComparison) -> None:
        self.twin, self.index, self.seed, self.result = twin, index, seed, result
        self.obs: dict = {}
        self.info: dict = {}
        self.diverged = False

    def start(self, env, team, channel) -> None:
        self.episode = env.episode.id
        self.obs, self.info = self.twin.call("reset", (self.index, self.seed))

    def observed(self, t: int, obs: dict, info: dict) -> None:
        r = self.result
        for name, o in obs.items():
            mine = self.obs[name]
            r.agent_steps += 1
            seg_a, seg_b = o["segmentation"], mine["segmentation"]
            same = seg_a == seg_b
            r.pixel_agreement.append(float(same.mean()))
            if same.any():
                r.depth_median_abs.append(
                    float(np.median(np.abs(o["depth"][same] - mine["depth"][same])))
                )
            what = []
            visible_a, visible_b = _visible(seg_a), _visible(seg_b)
            if visible_a != visible_b:
                r.visible_differs += 1
                what.append(f"visible {sorted(visible_a ^ visible_b)}")
            fail_a = info.get("failed", {}).get(name, "")
            fail_b = self.info.get("failed", {}).get(name, "")
            if fail_a != fail_b or int(o["held"]) != int(mine["held"]):
                r.outcome_differs += 1
                held = (int(o["held"]), int(mine["held"]))
                what.append(f"outcome {fail_a!r}/{held[0]} vs {fail_b!r}/{held[1]}")
            if what and not self.diverged and any(w.startswith("outcome") for w in what):
                self.diverged = True
                r.first_divergence.append(f"{self.episode} step {t} {name}: {'; '.join(what)}")

    def decided(self, t: int, actions: dict, labels: dict) -> None:
        self.obs, self.info = self.twin.call("step", actions)


def compare_backends(
    backends: tuple[str, str] = BACKENDS,
    setting: str = "I",
    dataset: str | None = None,
    split: str = "test",
    episodes: int = 3,
    progress: bool = True,
) -> BackendComparison:
    import gymnasium as gym
    from tqdm import tqdm

    import maniskill_tidy  # noqa: F401  (registers the env)
    from maniskill_tidy.eval.episode import play_episode
    from maniskill_tidy.eval.runner import select
    from maniskill_tidy.policies import make_team

    bad = [b for b in backends if b not in BACKENDS]
    if len(backends) != 2 or bad:
        raise ValueError(f"--backends {','.join(backends)}: expected two of {', '.join(BACKENDS)}")
    if "gpu" in backends and default_render_backend() != "gpu":
        raise ValueError(
            "--backends gpu: SAPIEN finds no CUDA device here; run this on a machine with a GPU "
            "(--backends cpu,cpu checks lavapipe against itself)"
        )
    kwargs = {"setting": setting, "dataset": dataset, "split": split,
              "obs_mode": "rgb+depth+segmentation", "reward_mode": "none"}  # fmt: skip
    twin = Twin(backends[1], kwargs)
    env = gym.make("HeteroTidy-v1", render_backend=backends[0], **kwargs)
    result = BackendComparison(tuple(backends))
    try:
        starts = [e.start for e in env.unwrapped.episodes.episodes]
        chosen = select(starts, episodes)
        for i in tqdm(chosen, desc="episodes on both backends", disable=not progress):
            play_episode(env, make_team("expert"), i, i, [TwinObserver(twin, i, i, result)])
            result.episodes += 1
    finally:
        env.close()
        twin.close()
    return result
