"""The paper's Random baseline: every agent draws uniformly from its own action space.

Stop is left out of the draw (with it, a team of three would end most episodes within a few
steps); as in the paper the episode then runs to the 300-step limit. Seeded per episode.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from maniskill_tidy.envs.actions import Action
from maniskill_tidy.policies.base import PublicInfo, Team
from maniskill_tidy.policies.channel import Channel


class RandomTeam(Team):
    name = "random"
    needs_images = False

    def reset(self, info: PublicInfo, channel: Channel, env: Any | None = None) -> None:
        self.rng = np.random.default_rng(info.seed)
        self.choices = {
            name: [a for a in Action if a != Action.Stop and (cap[1] or a < Action.Stop)]
            for name, cap in zip(info.agents, info.capabilities, strict=True)
        }

    def act(self, obs: dict[str, dict], info: dict) -> dict[str, Any]:
        return {
            name: self.choices[name][self.rng.integers(len(self.choices[name]))] for name in obs
        }
