"""Agent start configurations: distinct free cells of the main navigable area, random headings.

``rotation`` is in degrees counter-clockwise from +x, one of 0, 90, 180, 270.
"""

from __future__ import annotations

import numpy as np

from maniskill_tidy.houses.navgrid import GridFrame

ROTATIONS = (0, 90, 180, 270)


def sample_starts(
    frame: GridFrame, walkable: np.ndarray, n_agents: int, rng: np.random.Generator
) -> list[dict]:
    cells = np.argwhere(walkable)
    if len(cells) < n_agents:
        raise ValueError(f"{len(cells)} free cells cannot hold {n_agents} agents")
    chosen = rng.choice(len(cells), size=n_agents, replace=False)
    return [
        {
            "cell": [int(cells[i][0]), int(cells[i][1])],
            "position": [float(frame.x[cells[i][1]]), float(frame.y[cells[i][0]])],
            "rotation": int(rng.choice(ROTATIONS)),
        }
        for i in chosen
    ]
