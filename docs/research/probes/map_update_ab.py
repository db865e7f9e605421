"""The semantic map's update, old against new, on the same frames (issue 48's safety net).

    python docs/research/probes/map_update_ab.py [--ref COMMIT] [--episodes 1] [--repeat 3]

Plays heuristic-none on Setting I test episodes and keeps every second frame of every agent;
then fuses them into a map made by ``perception/semantic_map.py`` as it is at ``--ref`` (read
with ``git show``, loaded beside today's module) and into one made by today's, and compares
the whole map state after every frame byte for byte (voxels, explored, top-down channels, the
last frame's points and ids, the movable voxels). Then times both on the same frames, in turns,
and prints the ratio. A speed change to the map must report "identical states N/N".

The reference map runs on the reference commit's own ``map_kernels.py`` where it has one
(loaded beside today's, compiled into a temporary directory), and on today's other modules:
compare against the last commit (the default), or against one before the kernels (82e28be,
the numpy map every committed record was made with).
"""

from __future__ import annotations

import argparse
import hashlib
import importlib.util
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from maniskill_tidy.eval.episode import play_episode
from maniskill_tidy.eval.runner import RunConfig, make_env, select
from maniskill_tidy.perception import semantic_map as today
from maniskill_tidy.policies import make_team
from maniskill_tidy.policies.base import PublicInfo

REPO = Path(__file__).resolve().parents[3]


class Frames:
    """An episode observer that keeps every second observation of every agent."""

    def start(self, env, team, channel) -> None:
        self.house, self.instances = env.house, PublicInfo.of(env, 0).instances
        self.frames: list[dict] = []

    def observed(self, t, obs, info) -> None:
        if t % 2 == 0:
            self.frames.append({a: {k: np.array(v) for k, v in o.items()} for a, o in obs.items()})


def reference_module(commit: str):
    def show(path: str) -> str | None:
        out = subprocess.run(["git", "-C", str(REPO), "show", f"{commit}:{path}"],
                             capture_output=True, text=True)  # fmt: skip
        return out.stdout if out.returncode == 0 else None

    folder = Path(tempfile.mkdtemp())
    source = show("maniskill_tidy/perception/semantic_map.py")
    if source is None:
        raise SystemExit(f"map_update_ab.py: commit {commit!r} has no semantic_map.py")
    kernels = show("maniskill_tidy/perception/map_kernels.py")
    if kernels is not None:  # numba caches a module it can import by name: put it on the path
        (folder / "map_kernels_ref.py").write_text(kernels)
        sys.path.insert(0, str(folder))
        source = source.replace(
            "from maniskill_tidy.perception import map_kernels as kernels",
            "import map_kernels_ref as kernels",
        )
    path = folder / "semantic_map_ref.py"
    path.write_text(source)
    spec = importlib.util.spec_from_file_location("semantic_map_ref", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules["semantic_map_ref"] = module
    spec.loader.exec_module(module)
    return module


def fuse(module, episodes: list[Frames], digest: bool) -> tuple[list[str], float]:
    states, seconds = [], 0.0
    for ep in episodes:
        for agent in ep.frames[0]:
            m = module.SemanticMap(ep.house, ep.instances, module.MapConfig(stride=2))
            for frame in ep.frames:
                start = time.perf_counter()
                m.update(frame[agent])
                seconds += time.perf_counter() - start
                if digest:
                    h = hashlib.sha256()
                    last = m.last_frame
                    state = (m.voxels, m.explored, m.top_down(), last.points, last.seg,
                             last.camera, m._movable_voxels)  # fmt: skip
                    for a in state:
                        h.update(str(a.dtype).encode() + np.ascontiguousarray(a).tobytes())
                    states.append(h.hexdigest())
    return states, seconds


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--ref", default="HEAD", help="the commit whose map is the reference")
    p.add_argument("--episodes", type=int, default=1)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--dataset", default="data/tidy120")
    args = p.parse_args()

    cfg = RunConfig("heuristic-none", "I", "test", args.dataset, args.episodes)
    env, team = make_env(cfg), make_team("heuristic-none")
    played = []
    for i in select([e.start for e in env.unwrapped.episodes.episodes], args.episodes):
        frames = Frames()
        play_episode(env, team, i, i, [frames])
        played.append(frames)
    env.close()
    ref = reference_module(args.ref)
    old, _ = fuse(ref, played, True)
    new, _ = fuse(today, played, True)
    same = sum(a == b for a, b in zip(old, new, strict=True))
    print(f"identical states {same}/{len(old)}")
    t_old = t_new = 0.0
    for _ in range(args.repeat):
        t_old += fuse(ref, played, False)[1]
        t_new += fuse(today, played, False)[1]
    n = args.repeat * len(old)
    print(f"{args.ref}: {1e3 * t_old / n:.2f} ms per update; today: {1e3 * t_new / n:.2f} ms; "
          f"today / {args.ref} {t_new / t_old:.2f}")  # fmt: skip


if __name__ == "__main__":
    main()
