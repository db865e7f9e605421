"""Agent configs (``agents/*.yaml``): what a learned team is, how it was trained, how it acts.

Every config is read by one loader, :func:`read_config`, so ``base: OTHER.yaml`` works in
all of them (QMIX's included); :func:`load_config` returns the right dataclass. Training and
evaluation both read configs from here: a team never imports the trainer to find its model.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, fields
from pathlib import Path

import yaml

from maniskill_tidy.common.agent_files import WHERE, resolve
from maniskill_tidy.envs.registration import ENV_ID
from maniskill_tidy.knowledge import ROOM_TYPES, load_catalog
from maniskill_tidy.models.communication import SCHEMES
from maniskill_tidy.models.decision import DecisionConfig


@dataclass(frozen=True)
class TrainSettings:
    epochs: int = 30
    batch: int = 8  # episodes
    lr: float = 1e-3
    seed: int = 0
    hard_fraction: float = 0.5
    patience: int = 6  # epochs without a better val score before stopping
    # "loss": the inference-mode val loss. "accuracy": the mean over heads of val accuracy
    # above the most frequent label; the summed loss can rise on the rare object and
    # receptacle heads, which grow over-confident, while the sub-goal heads still improve.
    select: str = "loss"


@dataclass(frozen=True)
class ActSettings:
    """How the learned team turns the heads into actions (``policies/learned.py``)."""

    # None: the argmax of ope (the paper's decoding). A probability p: operate whenever an
    # operation's probability exceeds p and the operation is possible now. PickUp is one step
    # per pick in the demonstrations, so its probability rarely wins the argmax even where
    # the model ranks those steps well (measured on val: docs/models.md, "Where it stands").
    ope_threshold: float | None = None
    # Sample the sub-goal's dx, dy and drot from their heads (seeded per agent) instead of the
    # argmax: the teacher's moves are spread over many cells, and the argmax of each axis
    # alone names one fixed cell that an agent walks to, or stays at, step after step.
    sample_subgoal: bool = False
    # With sample_subgoal: draw from softmax(logits / T). Below 1 the draws stay nearer the
    # likeliest cell (towards the argmax as T -> 0), above 1 they spread out.
    subgoal_temperature: float = 1.0
    # SA(Oracle) (paper Section 6.3): the misplaced objects' locations are given at reset. With
    # nothing in hand the agent walks to the nearest one it has not picked up instead of
    # exploring, and knows which objects in view are misplaced; the same trained model decides
    # everything else. Its rows are marked privileged: it reads the task.
    oracle: bool = False
    # Play at another cadence than the model was trained for (None: its own,
    # DecisionConfig.decide_every): what a model trained to decide every step does when it may
    # decide only every k steps (agents/experiments/hangrcom-every4-untrained.yaml).
    decide_every: int | None = None


@dataclass(frozen=True)
class AgentConfig:
    """An agent config file (``agents/*.yaml``), checked on load."""

    name: str
    out: str  # where the trained model goes (a ``setting_S`` folder per setting)
    perception: str = "agents/perception/knowledge"
    dataset: str = "data/tidy120"
    demos: str = "data/demos"
    work: str = "data/decision"
    workers: int = 2
    train_demos: dict = field(default_factory=lambda: {"starts": 1, "tasks": 5})
    val_demos: dict = field(default_factory=lambda: {"starts": 1, "tasks": 2})
    model: dict = field(default_factory=dict)
    train: dict = field(default_factory=dict)
    act: dict = field(default_factory=dict)
    notes: str = ""  # printed in the model card (e.g. why this many demonstrations)
    # a team of its own, played in every setting (SA: [[1, 1, 1]], one manipulator); its
    # teacher must play with the same team, and it is trained with --setting I
    team: list | None = None
    # demos roots whose train rows (same setting) join this config's own: DAgger aggregates the
    # student's labelled rollouts with the teacher's trajectories; made by the config that owns them
    also_train: list = field(default_factory=list)

    @classmethod
    def load(cls, path: Path) -> AgentConfig:
        path = Path(path)
        cfg = cls(**_checked_keys(path, read_config(path), cls))
        for section, klass in (
            ("model", DecisionConfig), ("train", TrainSettings), ("act", ActSettings),
        ):  # fmt: skip
            names = {f.name for f in fields(klass)}
            bad = sorted(set(getattr(cfg, section)) - names)
            if bad:
                raise ValueError(f"{path}: unknown {section} keys {bad}; expected {sorted(names)}")
        cfg.acting()  # checks the act section's values
        scheme = cfg.model.get("communication", "hangrcom")
        if scheme not in SCHEMES:
            raise ValueError(
                f"{path}: model communication {scheme!r}: expected one of {list(SCHEMES)}"
            )
        if cfg.model.get("goal_map") and not cfg.model.get("layout"):
            raise ValueError(f"{path}: model goal_map needs layout: true (the goal is its channel)")
        for section in ("train_demos", "val_demos"):
            keys = {"starts", "tasks", "houses", "teacher", "student"}
            bad = sorted(set(getattr(cfg, section)) - keys)
            if bad:
                raise ValueError(f"{path}: unknown {section} keys {bad}")
        return cfg

    def decision(self) -> DecisionConfig:
        catalog = load_catalog()
        d = DecisionConfig(
            categories=len(catalog.categories), objects=len(catalog.pickupable),
            receptacles=len(catalog.receptacles), rooms=len(ROOM_TYPES), **self.model,
        )  # fmt: skip
        _check_cadence("model", d.decide_every)
        return d

    def acting(self) -> ActSettings:
        a = ActSettings(**self.act)
        if a.ope_threshold is not None and not 0 < a.ope_threshold < 1:
            raise ValueError(f"act ope_threshold {a.ope_threshold!r}: expected a probability")
        if not a.subgoal_temperature > 0:
            raise ValueError(
                f"act subgoal_temperature {a.subgoal_temperature!r}: expected a number above 0"
            )
        if a.decide_every is not None:
            _check_cadence("act", a.decide_every)
        return a

    def settings(self) -> TrainSettings:
        s = TrainSettings(**self.train)
        if s.select not in ("loss", "accuracy"):
            raise ValueError(f"train select {s.select!r}: expected 'loss' or 'accuracy'")
        return s


def _check_cadence(section: str, k: object) -> None:
    """``decide_every`` (a sub-goal step every k env steps) must be a whole number of steps."""
    if isinstance(k, bool) or not isinstance(k, int) or k < 1:
        raise ValueError(f"{section} decide_every {k!r}: expected an integer >= 1")


def read_config(path: Path, seen: tuple[Path, ...] = ()) -> dict:
    """A config's mapping; ``base: OTHER.yaml`` (relative to it) inherits OTHER's keys, the
    sections (model, train, act, ...) merged key by key, so that a variant states only what it
    changes."""
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such agent config (a YAML file under agents/; "
                                f"{WHERE})")  # fmt: skip
    try:
        raw = yaml.safe_load(path.read_text()) or {}
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        problem = getattr(e, "problem", None) or type(e).__name__
        raise ValueError(f"{path}: not valid YAML ({problem}{where})") from None
    if not isinstance(raw, dict):
        raise ValueError(f"{path}: expected a mapping of settings, got {type(raw).__name__}")
    if "base" not in raw:
        return raw
    base_path = (path.parent / str(raw.pop("base"))).resolve()
    if base_path in seen:
        raise ValueError(f"{path}: its base {base_path} inherits from itself")
    merged = read_config(base_path, (*seen, path.resolve()))
    for key, value in raw.items():
        both = isinstance(value, dict) and isinstance(merged.get(key), dict)
        merged[key] = {**merged[key], **value} if both else value
    return merged


@dataclass(frozen=True)
class QmixConfig:
    name: str
    out: str
    trainer: str = "qmix"
    perception: str = "agents/perception/knowledge"
    dataset: str = "data/tidy120"
    work: str = "data/qmix"
    episodes: int = 60  # the budget: training episodes
    max_steps: int = 300
    seed: int = 0
    gamma: float = 0.99
    lr: float = 5e-4
    batch: int = 4  # episodes per update
    buffer: int = 40  # the last episodes sampled from
    updates: int = 4  # TD updates after each episode
    target_every: int = 5  # episodes between copies to the target networks
    epsilon: dict = field(default_factory=lambda: {"start": 1.0, "end": 0.05, "episodes": 40})
    reward: dict = field(default_factory=lambda: {"placed": 1.0, "picked": 0.2, "step": -0.001})
    val_episodes: int = 4  # greedy episodes on val for the card
    notes: str = ""

    @classmethod
    def load(cls, path: Path) -> QmixConfig:
        path = Path(path)
        cfg = cls(**_checked_keys(path, read_config(path), cls))
        if set(cfg.epsilon) != {"start", "end", "episodes"}:
            raise ValueError(f"{path}: epsilon needs start, end and episodes, got {cfg.epsilon}")
        if set(cfg.reward) != {"placed", "picked", "step"}:
            raise ValueError(f"{path}: reward needs placed, picked and step, got {cfg.reward}")
        if cfg.episodes < 1 or cfg.batch < 1:
            raise ValueError(f"{path}: episodes and batch must be at least 1")
        return cfg

    def exploration(self, episode: int) -> float:
        e = self.epsilon
        frac = min(episode / max(e["episodes"], 1), 1.0)
        return float(e["start"] + frac * (e["end"] - e["start"]))


@dataclass(frozen=True)
class MemoryConfig:
    """The object-memory team (``policies/memory.py``): a pointer over remembered objects and
    other jobs, trained by behaviour cloning on a camera-only heuristic team's own choices."""

    name: str
    out: str
    trainer: str = "memory"
    # whose job choices are imitated; the team sends that team's messages (so: its pattern)
    teacher: str = "heuristic-detection"
    dataset: str = "data/tidy120"
    work: str = "data/memory"
    workers: int = 2
    env: str = "HeteroTidy-v1"  # the look the teacher plays in
    train_demos: dict = field(default_factory=lambda: {"starts": 1, "tasks": 3})
    val_demos: dict = field(default_factory=lambda: {"starts": 1, "tasks": 1})
    model: dict = field(default_factory=lambda: {"dim": 64, "heads": 4})
    train: dict = field(default_factory=dict)  # epochs, batch, lr, seed, patience
    val_episodes: int = 20  # closed-loop val episodes for the card, the student's and teacher's
    # explore candidates per decision: the heuristic's cell to search, and above 1 the first
    # unsearched cell of up to explore - 1 other rooms, with two numbers about each room
    # (policies/memory_candidates.py): where to search becomes the pointer's choice
    explore: int = 1
    # after cloning, PPO on the team's return at job boundaries (training/memory_reinforce.py);
    # empty: behaviour cloning only
    reinforce: dict = field(default_factory=dict)
    # or, after cloning, policy improvement from forked episodes (training/memory_forks.py)
    forks: dict = field(default_factory=dict)
    # HanGrCom links carrying memory entries instead of the teacher's messages, with the
    # pointer of another config's folder (policies/memory_links.py, training/memory_links.py);
    # empty: the teacher's messages
    links: dict = field(default_factory=dict)
    notes: str = ""

    TEACHERS = ("heuristic-none", "heuristic-detection", "heuristic-broadcast")
    MAX_EXPLORE = 6
    TRAIN_KEYS = ("epochs", "batch", "lr", "seed", "patience")
    REINFORCE = {
        "iterations": 24,  # rounds of rollouts and updates
        "episodes": 24,  # train episodes played per round (drawn from the whole train split)
        "epochs": 4,  # passes over a round's decisions
        "batch": 512,
        "lr": 3e-4,
        "critic_lr": 1e-3,
        "clip": 0.2,  # PPO's ratio clip
        "kl": 0.05,  # weight of KL(cloned pointer || pointer): stay near the teacher's rule
        "temperature": 2.0,  # divides the scores of the policy that is drawn from and improved
        "gamma": 0.99,  # discount per env step
        "bonus": 1.0,  # team reward for success, beside 1 / k per object put where it belongs
        "seed": 0,
        "val_every": 4,  # rounds between greedy val runs (which select the weights)
        "val_episodes": 40,
    }

    LINKS = {
        "pointer": "agents/memory",  # the trained pointer the team plays with (its folder)
        "entries": 4,  # memory entries a link carries at most
        "hidden": 32,  # the summary's hidden layer
        "key": 8,  # query and key values
        "mu": 0.2,  # the paper's thresholds: a link where T_ij > mu ...
        "delta": 0.8,  # ... from an agent that asks, T_ii < delta
        "epochs": 40,
        "batch": 256,
        "lr": 3e-3,
        "seed": 0,
        "patience": 8,
    }

    FORKS = {
        "iterations": 6,  # rounds of bases, forks and an update (policy iteration)
        "episodes": 16,  # train episodes played with the best choices per round (the bases)
        "forks": 3,  # decisions per base played again with another choice
        "epochs": 20,  # passes over every pair so far
        "batch": 64,
        "lr": 3e-4,
        "kl": 0.1,  # weight of KL(cloned pointer || pointer) on the round's decisions
        "temperature": 2.0,  # divides the scores the other choice is drawn from
        "gamma": 0.99,  # discount per env step
        "bonus": 1.0,  # team reward for success, beside 1 / k per object put where it belongs
        "seed": 0,
        "val_episodes": "standard",  # the clone and the last round, paired (eval's choice)
    }

    @classmethod
    def load(cls, path: Path) -> MemoryConfig:
        path = Path(path)
        cfg = cls(**_checked_keys(path, read_config(path), cls))
        if cfg.teacher not in cls.TEACHERS:
            raise ValueError(f"{path}: teacher {cfg.teacher!r}: expected one of {cls.TEACHERS}")
        bad = sorted(set(cfg.model) - {"dim", "heads"}) + sorted(
            set(cfg.train) - set(cls.TRAIN_KEYS)
        )
        if bad:
            raise ValueError(f"{path}: unknown model or train keys {bad}; expected dim, heads "
                             f"and {list(cls.TRAIN_KEYS)}")  # fmt: skip
        for section in ("train_demos", "val_demos"):
            extra = sorted(set(getattr(cfg, section)) - {"starts", "tasks", "houses"})
            if extra:
                raise ValueError(f"{path}: unknown {section} keys {extra}")
        for section, known in (("reinforce", cls.REINFORCE), ("forks", cls.FORKS),
                               ("links", cls.LINKS)):  # fmt: skip
            extra = sorted(set(getattr(cfg, section)) - set(known))
            if extra:
                raise ValueError(f"{path}: unknown {section} keys {extra}; expected some of "
                                 f"{sorted(known)}")  # fmt: skip
        if cfg.reinforce and cfg.forks:
            raise ValueError(f"{path}: both reinforce and forks; expected at most one stage "
                             "after cloning")  # fmt: skip
        if cfg.links and (cfg.reinforce or cfg.forks):
            raise ValueError(f"{path}: links with reinforce or forks; links train on a "
                             "trained pointer (links.pointer), nothing else")  # fmt: skip
        if not (type(cfg.explore) is int and 1 <= cfg.explore <= cls.MAX_EXPLORE):
            raise ValueError(f"{path}: explore {cfg.explore!r}; expected a whole number from 1 "
                             f"to {cls.MAX_EXPLORE}")  # fmt: skip
        return cfg

    def settings(self) -> dict:
        return {"epochs": 30, "batch": 256, "lr": 1e-3, "seed": 0, "patience": 6, **self.train}

    def forks_settings(self) -> dict:
        """The forks' settings (defaults filled in); empty when the config asks for none."""
        return {**self.FORKS, **self.forks} if self.forks else {}

    def links_settings(self) -> dict:
        """The links' settings (defaults filled in); empty when the config asks for none."""
        return {**self.LINKS, **self.links} if self.links else {}

    def reinforce_settings(self) -> dict:
        """PPO's settings (defaults filled in); empty when the config asks for none."""
        return {**self.REINFORCE, **self.reinforce} if self.reinforce else {}


def _checked_keys(path: Path, raw: dict, cls) -> dict:
    """``raw`` if it names only ``cls``'s fields and has a name and an output folder."""
    known = {f.name for f in fields(cls)}
    unknown = sorted(set(raw) - known)
    if unknown:
        raise ValueError(f"{path}: unknown keys {unknown}; expected some of {sorted(known)}")
    for key in ("name", "out"):
        if key not in raw:
            raise ValueError(f"{path}: missing {key!r}")
    return raw


def trainer_of(path: Path) -> str:
    """Which trainer a config is for: "qmix", "memory", or "decision" (the paper's model)."""
    return read_config(Path(path)).get("trainer", "decision") if Path(path).is_file() else ""


def is_qmix_config(path: Path) -> bool:
    return trainer_of(path) == "qmix"


def load_config(path: Path) -> AgentConfig | QmixConfig | MemoryConfig:
    """Any agent config: QMIX's (``trainer: qmix``), the object-memory team's (``trainer:
    memory``) or a hierarchical-decision team's."""
    kind = trainer_of(path)
    if kind == "qmix":
        return QmixConfig.load(path)
    return MemoryConfig.load(path) if kind == "memory" else AgentConfig.load(path)


def perception_look(folder: str | Path) -> str:
    """The look a learned perception's views were rendered in: its card's ``config.env``, or
    v1 for cards from before looks existed. A team reading RGB through it plays there by
    default (``Team.look``): weights trained on one look's pixels measure the look change in
    the other, not the team."""
    card = Path(resolve(folder)) / "card.json"
    if not card.is_file():
        return ENV_ID
    return json.loads(card.read_text()).get("config", {}).get("env", ENV_ID)


class PerceptionLook:
    """A learned team's ``Team.look``, read from its perception's card when asked (on the
    class or an instance), not when the module is imported."""

    def __init__(self, folder: str | Path) -> None:
        self.folder = folder

    def __get__(self, obj: object, owner: type | None = None) -> str:
        return perception_look(self.folder)
