"""Do two render backends show the agents the same? Lavapipe (CPU) against CUDA, step by step.

The expert plays an episode on one env; a twin env in its own process (SAPIEN allows one
renderer per process), the same house and episode on the other backend, is stepped with the
same actions. Each step compares, per agent, what decides outcomes:
the instances covering at least ``MIN_PIXELS`` pixels of the segmentation (PickUp, PutDown and
the detectors all use that rule), the share of pixels whose instance agrees, the depth where both
see the same instance, and each action's outcome (failure reason, held object). Once an outcome
differs the two episodes diverge, so the first such step is reported and later ones are counted
apart.

Where the two backends are not on one machine (a GPU node without lavapipe, a laptop without a
GPU), ``record_trace`` keeps what the comparison reads, step by step, in a folder, and
``compare_with_trace`` replays the recorded actions on another machine's backend and compares
with the record: the same counts, with depth rounded to millimetres on both sides (the trace
stores it so). Physics runs on the CPU on both, so a difference is the renderer's.
"""

from __future__ import annotations

import json
import platform
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from maniskill_tidy.envs.actions import MIN_PIXELS, Targeted
from maniskill_tidy.envs.hetero_tidy import default_render_backend, pixel_counts

BACKENDS = ("cpu", "gpu")
TRACE_META = "trace.json"
KEYS = ("segmentation", "depth", "held")


@dataclass
class BackendComparison:
    backends: tuple[str, str]
    episodes: int = 0
    agent_steps: int = 0
    visible_differs: int = 0  # agent-steps whose >= MIN_PIXELS instance sets differ
    outcome_differs: int = 0  # agent-steps whose action outcome or held object differs
    first_divergence: list[str] = field(default_factory=list)  # "episode step agent: what"
    pixels_differ: int = 0  # pixels whose instance differs, over all agent-steps
    pixels_differ_on_edges: int = 0  # of those, pixels on an instance edge in either image
    pixels_differ_robots: int = 0  # of those, pixels where two robots' bodies coincide
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
            "edge_share": self.pixels_differ_on_edges / max(self.pixels_differ, 1),
            "robots_share": self.pixels_differ_robots / max(self.pixels_differ, 1),
        }  # fmt: skip


def _edges(seg: np.ndarray) -> np.ndarray:
    """Pixels with a 4-neighbour of another instance: where rasterisers may round apart."""
    edge = np.zeros(seg.shape, bool)
    rows, cols = seg[1:] != seg[:-1], seg[:, 1:] != seg[:, :-1]
    edge[1:] |= rows
    edge[:-1] |= rows
    edge[:, 1:] |= cols
    edge[:, :-1] |= cols
    return edge


def _visible(seg: np.ndarray) -> set[int]:
    return {int(i) for i, n in pixel_counts(seg).items() if i and n >= MIN_PIXELS}


def _serve_twin(conn, backend: str, kwargs: dict) -> None:
    """The twin env, alone in its process (one SAPIEN renderer per process): answers
    ("reset", (index, seed)) and ("step", actions) with what the comparison reads."""
    import gymnasium as gym

    from maniskill_tidy.common.parallel import die_with_parent

    die_with_parent()
    env = gym.make("HeteroTidy-v1", render_backend=backend, **kwargs)
    keys = KEYS
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
        instances = env.hs.instances if getattr(env, "hs", None) else {}
        self.robots = np.array([i for i, x in instances.items() if x.kind == "robot"], int)
        self.obs, self.info = self.twin.call("reset", (self.index, self.seed))

    def observed(self, t: int, obs: dict, info: dict) -> None:
        r = self.result
        for name, o in obs.items():
            mine = self.obs[name]
            r.agent_steps += 1
            seg_a, seg_b = o["segmentation"], mine["segmentation"]
            same = seg_a == seg_b
            r.pixel_agreement.append(float(same.mean()))
            if not same.all():
                r.pixels_differ += int((~same).sum())
                on_edges = ~same & (_edges(seg_a) | _edges(seg_b))
                r.pixels_differ_on_edges += int(on_edges.sum())
                robots = np.isin(seg_a, self.robots) & np.isin(seg_b, self.robots)
                r.pixels_differ_robots += int((~same & robots).sum())
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
    kwargs = _env_kwargs(setting, dataset, split)
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


def _env_kwargs(setting: str, dataset: str | None, split: str) -> dict:
    return {"setting": setting, "dataset": dataset, "split": split,
            "obs_mode": "rgb+depth+segmentation", "reward_mode": "none"}  # fmt: skip


def _action_json(a) -> int | list:
    return [int(a.action), a.target] if isinstance(a, Targeted) else int(a)


def _action(a: int | list):
    return Targeted(a[0], a[1]) if isinstance(a, list) else a


def _millimetres(depth: np.ndarray) -> np.ndarray:
    return np.round(np.asarray(depth, np.float64) * 1000).clip(0, 65535).astype(np.uint16)


def _quantized(obs: dict) -> dict:
    """What the trace keeps of an observation: depth rounded to millimetres."""
    return {n: {"segmentation": o["segmentation"], "depth": _millimetres(o["depth"]) / 1000.0,
                "held": o["held"]} for n, o in obs.items()}  # fmt: skip


class TraceRecorder:
    """An observer that keeps, per step, what ``TwinObserver`` compares and the actions taken."""

    def start(self, env, team, channel) -> None:
        self.episode, self.names = env.episode.id, list(env.agent_names)
        self.frames: list[tuple[dict, dict]] = []
        self.actions: list[dict] = []

    def observed(self, t: int, obs: dict, info: dict) -> None:
        self.frames.append(({n: {k: obs[n][k] for k in KEYS} for n in self.names},
                            dict(info.get("failed", {}))))  # fmt: skip

    def decided(self, t: int, actions: dict, labels: dict) -> None:
        self.actions.append({n: _action_json(a) for n, a in actions.items()})

    def save(self, path: Path, index: int, seed: int) -> None:
        views = [v for v, _ in self.frames]
        arrays = {
            "segmentation": np.stack([[v[n]["segmentation"] for n in self.names] for v in views]),
            "depth_mm": np.stack(
                [[_millimetres(v[n]["depth"]) for n in self.names] for v in views]
            ),  # fmt: skip
            "held": np.array([[int(v[n]["held"]) for n in self.names] for v in views]),
        }
        if arrays["segmentation"].max(initial=0) <= np.iinfo(np.int16).max:
            arrays["segmentation"] = arrays["segmentation"].astype(np.int16)
        extra = {"episode": self.episode, "index": index, "seed": seed, "agents": self.names,
                 "failed": [f for _, f in self.frames], "actions": self.actions}  # fmt: skip
        tmp = path.with_name(path.name + ".tmp.npz")
        np.savez_compressed(tmp, **arrays, meta=np.array(json.dumps(extra)))
        tmp.replace(path)


class _Recorded:
    """A twin that answers with the frames of a trace, one per call, instead of rendering."""

    def __init__(self, z) -> None:
        self.meta = json.loads(str(z["meta"]))
        self.seg, self.depth, self.held = z["segmentation"], z["depth_mm"], z["held"]
        self.t = 0

    def __len__(self) -> int:
        return len(self.seg)

    def frame(self, t: int) -> tuple[dict, dict]:
        names = self.meta["agents"]
        view = {n: {"segmentation": self.seg[t, i].astype(np.int32),
                    "depth": self.depth[t, i] / 1000.0, "held": np.array(self.held[t, i])}
                for i, n in enumerate(names)}  # fmt: skip
        return view, {"failed": self.meta["failed"][t]}

    def call(self, what: str, arg) -> tuple[dict, dict]:
        self.t = 0 if what == "reset" else self.t + 1
        return self.frame(self.t)


def _checked(backend: str | None, option: str) -> str:
    backend = backend or default_render_backend()
    if backend not in BACKENDS:
        raise ValueError(f"{option} {backend}: expected one of {', '.join(BACKENDS)}")
    if backend == "gpu" and default_render_backend() != "gpu":
        raise ValueError(f"{option} gpu: SAPIEN finds no CUDA device here (expected cpu here)")
    return backend


def _label(backend: str) -> str:
    return f"{backend} on {platform.node() or 'this machine'}"


def _dataset_hash(dataset: str | None) -> str | None:
    manifest = Path(dataset) / "manifest.json" if dataset else None
    if manifest is None or not manifest.is_file():
        return None
    return json.loads(manifest.read_text()).get("dataset_hash")


def record_trace(
    out: Path,
    backend: str | None = None,
    setting: str = "I",
    dataset: str | None = None,
    split: str = "test",
    episodes: int = 3,
    progress: bool = True,
) -> dict:
    """The expert plays ``episodes`` on this machine's ``backend``; one file per episode."""
    import gymnasium as gym
    from tqdm import tqdm

    from maniskill_tidy.eval.episode import play_episode
    from maniskill_tidy.eval.runner import select
    from maniskill_tidy.policies import make_team

    backend = _checked(backend, "--backend")
    kwargs = _env_kwargs(setting, dataset, split)
    env = gym.make("HeteroTidy-v1", render_backend=backend, **kwargs)
    out.mkdir(parents=True, exist_ok=True)
    meta = {"label": _label(backend), "backend": backend, "env": kwargs,
            "dataset_hash": _dataset_hash(dataset), "files": []}  # fmt: skip
    try:
        starts = [e.start for e in env.unwrapped.episodes.episodes]
        for i in tqdm(select(starts, episodes), desc=f"trace on {backend}", disable=not progress):
            recorder = TraceRecorder()
            play_episode(env, make_team("expert"), i, i, [recorder])
            name = f"episode_{i}.npz"
            recorder.save(out / name, i, i)
            meta["files"].append(name)
    finally:
        env.close()
    tmp = out / (TRACE_META + ".tmp")
    tmp.write_text(json.dumps(meta, indent=1))
    tmp.replace(out / TRACE_META)
    return meta


def compare_with_trace(
    trace: Path, backend: str | None = None, progress: bool = True
) -> BackendComparison:
    """Replay a trace's actions on this machine's ``backend`` and compare with what it recorded."""
    import gymnasium as gym
    from tqdm import tqdm

    if not (trace / TRACE_META).is_file():
        raise ValueError(f"--against {trace}: no {TRACE_META} there (expected a check-render "
                         "--save folder)")  # fmt: skip
    meta = json.loads((trace / TRACE_META).read_text())
    backend = _checked(backend, "--backend")
    kwargs = meta["env"]
    if meta.get("dataset_hash") and _dataset_hash(kwargs["dataset"]) != meta["dataset_hash"]:
        raise ValueError(
            f"--against {trace}: recorded on dataset hash {meta['dataset_hash']}, "
            f"but {kwargs['dataset']} here differs (expected the same dataset)"
        )
    env = gym.make("HeteroTidy-v1", render_backend=backend, **kwargs)
    result = BackendComparison((meta["label"], _label(backend)))
    try:
        for name in tqdm(meta["files"], desc=f"replay on {backend}", disable=not progress):
            with np.load(trace / name) as z:
                recorded = _Recorded(z)
            index, seed = recorded.meta["index"], recorded.meta["seed"]
            observer = TwinObserver(recorded, index, seed, result)
            obs, info = env.reset(seed=seed, options={"episode": index})
            observer.start(env.unwrapped, None, None)
            for t, actions in enumerate(recorded.meta["actions"]):
                observer.observed(t, _quantized(obs), info)
                if t + 1 == len(recorded):
                    break
                actions = {n: _action(a) for n, a in actions.items()}
                observer.decided(t, actions, {})
                obs, _, _, _, info = env.step(actions)
            result.episodes += 1
    finally:
        env.close()
    return result
