"""What the pixels-team probes share: their command line (a camera-only team, the dataset, the
segmenter, how many Setting I episodes in v2 and of which split, whose labels agents get) and
the loop that plays each episode with a fresh observer.

``--labels renderer`` feeds every agent the renderer's classes in place of the segmenter's
(:class:`TruthLabels`): a perfect segmenter, with the rest of the pixels pipeline unchanged."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Iterator

import numpy as np

from maniskill_tidy.eval.episode import play_episode
from maniskill_tidy.eval.runner import RunConfig, make_env, make_run_team, select
from maniskill_tidy.perception.seg_classes import seg_classes


def arguments(
    doc: str,
    policy: str,
    episodes: int,
    extra: Callable[[argparse.ArgumentParser], None] | None = None,
) -> argparse.Namespace:
    """The probes' common options; ``extra`` adds a probe's own."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    if extra is not None:
        extra(ap)
    ap.add_argument("--policy", default=policy)
    ap.add_argument("--dataset", default="data/tidy120")
    ap.add_argument("--segmentation", default="learned")
    ap.add_argument("--episodes", type=int, default=episodes)
    ap.add_argument("--split", default="test", choices=("train", "val", "test"),
                    help="val to choose what to change, test to report")  # fmt: skip
    ap.add_argument(
        "--labels",
        choices=("segmenter", "renderer", "renderer-objects", "renderer-types"),
        default="segmenter",
        help="what agents label their frames with (renderer: a perfect segmenter)",
    )
    return ap.parse_args()


class TruthLabels:
    """An observer that puts each agent's frame's classes (on the segmenter's half-resolution
    grid, as its training targets, every pixel fully confident) where the team's segmenter
    leaves its labels for the agent (``Segmenter.pending``), and stops the segmenter's batch.
    Still no instance id: agents make objects from classes and depth as from the segmenter's.

    ``part`` keeps the segmenter and corrects only a part of its labels: ``"objects"`` the
    pixels of pickupable objects (their class and full confidence where the renderer draws an
    object; furniture and structure as the segmenter says), ``"types"`` only the type of pixels
    both call some pickupable type (a perfect typer of what the segmenter takes for objects,
    its confidence kept)."""

    def __init__(self, part: str = "all") -> None:
        self.part = part

    def start(self, env, team, channel) -> None:
        self.classes = seg_classes()
        self.table = self.classes.lookup(env.instances)
        self.segmenter = team.segmenter
        self.truth: dict[str, np.ndarray] = {}
        if self.part == "all":
            team.prepare = lambda observations: None
        else:  # the class's own method: the team outlives each episode's observer
            team.prepare = lambda observations: self._corrected(
                type(team).prepare, team, observations
            )

    def observed(self, t, obs, info) -> None:
        for name, o in obs.items():
            seg = np.asarray(o["segmentation"]).reshape(o["rgb"].shape[:2])
            self.truth[name] = self.classes.labels(seg, self.table)[::2, ::2]
        if self.part == "all":
            ones = {n: np.ones(t.shape, np.float32) for n, t in self.truth.items()}
            self.segmenter.pending = {
                n: (np.ascontiguousarray(t), ones[n]) for n, t in self.truth.items()
            }

    def _corrected(self, prepare, team, observations) -> None:
        prepare(team, observations)
        for name, (labels, probs) in list(self.segmenter.pending.items()):
            truth = self.truth[name].reshape(labels.shape)
            labels, probs = labels.copy(), probs.copy()
            objects = self.classes.is_pickupable(truth)
            if self.part == "objects":
                fix = objects | self.classes.is_pickupable(labels)
                labels[fix] = truth[fix]
                probs[objects] = 1.0
            else:
                fix = objects & self.classes.is_pickupable(labels)
                labels[fix] = truth[fix]
            self.segmenter.pending[name] = (labels, probs)


def played(args: argparse.Namespace, observer: Callable[[], object]) -> Iterator[tuple]:
    """Each chosen episode's record and its observer, as ``eval`` chooses and plays them."""
    cfg = RunConfig(args.policy, "I", args.split, args.dataset, args.episodes,
                    env="HeteroTidy-v2", segmentation=args.segmentation)  # fmt: skip
    env, team = make_env(cfg), make_run_team(cfg)
    try:
        for i in select([e.start for e in env.unwrapped.episodes.episodes], args.episodes):
            log = observer()
            part = args.labels.removeprefix("renderer").removeprefix("-") or "all"
            extra = [TruthLabels(part)] if args.labels.startswith("renderer") else []
            yield play_episode(env, team, i, i, [*extra, log]), log
    finally:
        env.close()


def play_one(ap: argparse.ArgumentParser, episode: str, observers: list, policy: str = "memory",
             split: str = "test", dataset: str = "data/tidy120",
             segmentation: str = "learned"):  # fmt: skip
    """Play one Setting I episode of v2, named by its id, with ``observers``; its record. An id
    the split does not hold is the command line's error (``ap.error``)."""
    cfg = RunConfig(policy, "I", split, dataset, "all", env="HeteroTidy-v2",
                    segmentation=segmentation)  # fmt: skip
    env, team = make_env(cfg), make_run_team(cfg)
    try:
        ids = [e.id for e in env.unwrapped.episodes.episodes]
        if episode not in ids:
            ap.error(f"episode {episode!r} is not a Setting I {split} episode of {dataset}")
        i = ids.index(episode)
        return play_episode(env, team, i, i, observers)
    finally:
        env.close()
