"""Which episodes an env plays: a dataset split, filtered by task kind, for a team.

An episode is a meta-task with one of its start configurations: id ``"<task id>/start_<j>"``,
e.g. ``"house_00010/task_3/start_2"``. Without a dataset the env plays the small default dataset
shipped in the package (12 houses, seed 0, made by
``maniskill-tidy generate --houses 12 --seed 0``).
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from maniskill_tidy.common.memory import collector_paused
from maniskill_tidy.houses.schema import House
from maniskill_tidy.tasks.dataset import load_dataset
from maniskill_tidy.tasks.metatask import MetaTask
from maniskill_tidy.tasks.teams import SETTINGS, Capability, setting_team

TASK_TYPES = ("all", "single", "cross")


def default_dataset() -> Path:
    return Path(str(resources.files("maniskill_tidy.tasks") / "data" / "default"))


@dataclass(frozen=True)
class Episode:
    task: MetaTask
    start: int
    starts: list[dict]  # one per agent: cell, position, rotation

    @property
    def id(self) -> str:
        return f"{self.task.id}/start_{self.start}"

    @property
    def house_id(self) -> str:
        return self.task.house_id


def starts_setting(setting: str | None, team: tuple[Capability, ...]) -> str:
    """The dataset's start configurations a team uses: its preset, or the smallest that fits."""
    if setting is not None:
        return setting
    for name, members in sorted(SETTINGS.items(), key=lambda kv: len(kv[1])):
        if len(members) >= len(team):
            return name
    raise ValueError(
        f"a team of {len(team)} agents is larger than any setting in the dataset "
        f"(at most {max(len(m) for m in SETTINGS.values())} agents have start positions)"
    )


class EpisodeSet:
    def __init__(
        self,
        dataset: str | Path | None,
        split: str,
        task_type: str,
        setting: str | None,
        team: tuple[Capability, ...],
    ) -> None:
        if task_type not in TASK_TYPES:
            raise ValueError(f"task_type {task_type!r} is not one of {TASK_TYPES}")
        self.root = Path(dataset) if dataset is not None else default_dataset()
        data = load_dataset(self.root, split)
        self.houses: dict[str, House] = data.houses
        self.dataset_hash: str = data.manifest["dataset_hash"]
        self.setting = starts_setting(setting, team)
        tasks = [t for t in data.tasks if task_type == "all" or t.kind.lower() == task_type]
        self.episodes: list[Episode] = []
        with collector_paused():  # thousands of episodes (common/memory.py)
            self._add(tasks, team)
        if not self.episodes:
            raise ValueError(f"dataset {self.root} split {split!r} has no {task_type} tasks")
        self._index = {e.id: i for i, e in enumerate(self.episodes)}

    def _add(self, tasks: list[MetaTask], team: tuple[Capability, ...]) -> None:
        for task in tasks:
            if self.setting not in task.starts:
                raise ValueError(
                    f"dataset {self.root} has no starts for setting {self.setting!r} "
                    f"(it has {sorted(task.starts)})"
                )
            for j, starts in enumerate(task.starts[self.setting]):
                if len(starts) < len(team):
                    raise ValueError(
                        f"dataset {self.root}: {task.id} start {j} places {len(starts)} agents, "
                        f"the team has {len(team)}"
                    )
                self.episodes.append(Episode(task, j, starts[: len(team)]))

    @classmethod
    def for_setting(
        cls, dataset: str | Path | None, split: str, setting: str | list, task_type: str = "all"
    ) -> EpisodeSet:
        """The episodes ``gym.make(ENV_ID, setting=setting, ...)`` plays, without building its
        scene (seconds of SAPIEN set-up a command needs only to list them)."""
        return cls(dataset, split, task_type, *setting_team(setting))

    def __len__(self) -> int:
        return len(self.episodes)

    def get(self, key: int | str) -> Episode:
        if isinstance(key, str):
            if key not in self._index:
                raise KeyError(f"no episode {key!r}; ids look like {self.episodes[0].id!r}")
            return self.episodes[self._index[key]]
        if not 0 <= int(key) < len(self.episodes):
            raise IndexError(f"episode index {key} out of range [0, {len(self.episodes)})")
        return self.episodes[int(key)]
