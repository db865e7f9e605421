"""A scripted look-around: one agent turns on the spot at a few camera tilts, mapping as it goes.

It is how ``maniskill-tidy show-map``, the map tests and the map bench produce a map without a
policy. The other agents stop on the first step, so the env is left mid-episode.
"""

from __future__ import annotations

from collections.abc import Callable

from maniskill_tidy.envs.actions import HORIZON_RANGE, LOOK, TURN, Action
from maniskill_tidy.perception.semantic_map import MapConfig, SemanticMap

LOOK_AROUND_HORIZONS = (0, 30)  # degrees: level, then down at the floor near the agent


def look_around(
    env,
    agent: str,
    obs: dict,
    horizons: tuple[int, ...] = LOOK_AROUND_HORIZONS,
    config: MapConfig | None = None,
    on_frame: Callable[[dict, SemanticMap], None] | None = None,
) -> SemanticMap:
    """Map ``agent``'s surroundings from ``obs`` (the last observation) on: at each horizon a
    full turn of 360 / TURN frames. ``env`` is the unwrapped HeteroTidy env."""
    names = [a.name for a in env.agents]
    if agent not in names:
        raise KeyError(f"no agent {agent!r} in this team; it has {names}")
    for h in horizons:
        if h % LOOK or not HORIZON_RANGE[0] <= h <= HORIZON_RANGE[1]:
            raise ValueError(
                f"horizon {h} is not reachable: use multiples of {LOOK} in {HORIZON_RANGE}"
            )
    state = env.agents[names.index(agent)]
    semantic = SemanticMap(env.house, env.instances, config)
    others = {n: int(Action.Stop) for n in names if n != agent}

    def step(action: Action) -> dict:
        nonlocal others
        result = env.step({agent: int(action), **others})[0]
        others = {}
        return result[agent]

    frame = obs[agent]
    for horizon in horizons:
        while state.horizon != horizon:
            frame = step(Action.LookDown if state.horizon < horizon else Action.LookUp)
        for _ in range(360 // TURN):
            semantic.update(frame)
            if on_frame is not None:
                on_frame(frame, semantic)
            frame = step(Action.RotateRight)
    return semantic
