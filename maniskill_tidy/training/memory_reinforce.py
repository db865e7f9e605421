"""PPO for the object-memory team's pointer at job boundaries, from its cloned weights.

Behaviour cloning (``training/memory_trainer.py``) gives the teacher's rule and no more. Here
the team plays train episodes with each choice of job drawn from the pointer's distribution,
its scores divided by ``temperature`` (the cloned pointer is so sure of the teacher's choice
that, drawn as it is, 2 choices in 1000 differ from it, and nothing is learned); that tempered
distribution is the policy PPO improves, and the agents evaluated take its best choice.
A choice's return is the team's reward from its step on: 1 / k for each object put where it
belongs, ``bonus`` when the episode succeeds, discounted by ``gamma`` per step; every agent's
choices share it (one team, one reward). PPO's clipped objective on advantages over a critic,
plus a KL term towards the cloned pointer, updates the weights. Every ``val_every`` rounds, and
after the last, the team plays the first ``val_episodes`` val episodes taking its best choice,
and the weights that put the largest share of objects where they belong are kept (round 0 is
the cloned pointer itself).

The reward is training's signal only: no agent reads it, and what the agents see and send is
the cloned team's. Rollouts are seeded by (seed, round, episode, agent), so a config gives the
same weights; each round ends in an atomic checkpoint, and a rerun resumes from it.
"""

from __future__ import annotations

import copy
import io
import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn
from tqdm import tqdm

from maniskill_tidy.common.files import write_atomic
from maniskill_tidy.models.checkpoints import (
    float_state,
    half_state,
    memory_pointer,
    state_digest,
    type_vectors,
)
from maniskill_tidy.models.memory_pointer import KindBias, MemoryPointer
from maniskill_tidy.policies.agent_config import MemoryConfig
from maniskill_tidy.policies.memory import MemoryTeam

INPUTS = ("kind", "type", "rest", "numeric", "context")
_worker: dict = {}


class Critic(nn.Module):
    """Training only: the team's expected return from one agent's decision (PPO's baseline);
    the pointer's encoder, its candidates averaged."""

    def __init__(self, pointer: MemoryPointer) -> None:
        super().__init__()
        self.encoder = copy.deepcopy(pointer)
        self.value = nn.Linear(pointer.score.in_features, 1)

    def forward(self, *rows: torch.Tensor) -> torch.Tensor:
        h, present = self.encoder.encode(*rows)
        m = present.float()[..., None]
        return self.value((h * m).sum(1) / m.sum(1).clamp(min=1)).squeeze(-1)


class TeamReward:
    """An episode observer: the objects put where they belong after each step."""

    def start(self, env, team, channel) -> None:
        self.placed = [0]

    def log_step(self, t, obs, actions, info, channel, labels) -> None:
        self.placed.append(int(info["n_reasonable"]))


def returns(placed: list[int], k: int, success: bool, gamma: float, bonus: float) -> np.ndarray:
    """The discounted team return from each step on (len(placed) - 1 steps)."""
    r = np.diff(np.asarray(placed, np.float64)) / max(k, 1)
    if success and len(r):
        r[-1] += bonus
    g = np.zeros(len(r) + 1)
    for t in range(len(r) - 1, -1, -1):
        g[t] = r[t] + gamma * g[t + 1]
    return g[:-1]


def _init(config: str, setting: str, split: str):
    from maniskill_tidy.eval.runner import RunConfig, make_env

    cfg = MemoryConfig.load(Path(config))
    env = make_env(RunConfig(cfg.teacher, setting, split, cfg.dataset, env=cfg.env))
    _worker.update(env=env, config=config, setting=setting, path=None)
    return env.close


def _play(job: tuple[int, str, dict]) -> dict:
    """One episode with the policy in ``path``; ``mode``: ``seed`` (drawn choices, kept with
    their returns), else the best choices, with ``override`` (one other choice) and ``keep``
    (every choice kept) for forks (``training/memory_forks.py``); ``bias``: one number per kind
    added to the scores."""
    from maniskill_tidy.eval.episode import play_episode
    from maniskill_tidy.policies.memory import memory_team_class

    index, path, mode = job
    seed = mode.get("seed")
    if _worker["path"] != path:
        _worker.update(path=path, model=memory_pointer(torch.load(path, weights_only=False)))
    override = tuple(mode["override"]) if mode.get("override") else None
    team = memory_team_class(_worker["config"])(
        sampling_seed=seed, temperature=mode.get("temperature", 1.0), override=override,
        keep_decisions=bool(mode.get("keep")),
    )  # fmt: skip
    model = _worker["model"]
    if mode.get("bias"):  # the kinds' biases (docs/research/probes/kind_bias_probe.py)
        model = KindBias(model, mode["bias"])
    team.use_pointer(_worker["setting"], model)
    reward = TeamReward()
    record = play_episode(_worker["env"], team, index, index, [reward])
    g = returns(reward.placed, record.k, record.success, mode["gamma"], mode["bonus"])
    out = {"index": index, "success": record.success, "reasonable": record.reasonable,
           "k": record.k, "length": record.length, "return": float(g[0]) if len(g) else 0.0,
           "override": override}  # fmt: skip
    if seed is None and not mode.get("keep"):
        return out
    rows: dict[str, list] = {k: [] for k in (*INPUTS, "slot", "logp", "ret", "agent", "n")}
    for agent in team.made:
        for n, (t, candidates, slot, *logp) in enumerate(agent.decisions):
            for key in INPUTS:
                rows[key].append(getattr(candidates, key))
            rows["slot"].append(slot)
            rows["logp"].append(logp[0] if logp else 0.0)
            rows["ret"].append(g[min(t, len(g) - 1)] if len(g) else 0.0)
            rows["agent"].append(agent.index)
            rows["n"].append(n)
    return out | {k: np.asarray(v) for k, v in rows.items()}


def play_jobs(
    cfg: MemoryConfig, config: Path, setting: str, split: str, jobs: list[tuple[int, str, dict]],
    desc: str, progress: bool,
) -> list[dict]:  # fmt: skip
    """``jobs`` (episode index, policy path, mode) in ``cfg.workers`` processes, in order."""
    from maniskill_tidy.common.parallel import run_jobs

    out: list[tuple[int, dict]] = []
    with tqdm(total=len(jobs), desc=desc, unit="episode", disable=not progress, leave=False) as bar:
        for i, result in run_jobs(list(enumerate(jobs)), _play_numbered, cfg.workers, init=_init,
                                  initargs=(str(config), setting, split)):  # fmt: skip
            out.append((i, result))
            bar.update(1)
    return [result for _, result in sorted(out, key=lambda x: x[0])]


def _play_numbered(job: tuple[int, tuple]) -> dict:
    return _play(job[1])


def _play_all(
    cfg: MemoryConfig, config: Path, setting: str, split: str, indices: list[int], path: Path,
    seed: int | None, r: dict, desc: str, progress: bool,
) -> list[dict]:  # fmt: skip
    mode = {"seed": seed, "temperature": r["temperature"], "gamma": r["gamma"],
            "bonus": r["bonus"]}  # fmt: skip
    jobs = [(i, str(path), mode) for i in sorted(indices)]
    return play_jobs(cfg, config, setting, split, jobs, desc, progress)


def summary(episodes: list[dict]) -> dict:
    """Success and the share of misplaced objects put where they belong, over episodes."""
    return {"episodes": len(episodes),
            "success": round(float(np.mean([e["success"] for e in episodes])), 4),
            "placed": round(float(np.mean([e["reasonable"] / max(e["k"], 1)
                                           for e in episodes])), 4)}  # fmt: skip


def _save_policy(model: MemoryPointer, sizes: dict, path: Path) -> None:
    """The weights the agents play: rounded to fp16, as ``checkpoints.save_memory`` ships them."""
    buf = io.BytesIO()
    torch.save({"sizes": sizes, "state": half_state(model)}, buf)
    write_atomic(path, buf.getvalue())


def ppo_update(
    policy: MemoryPointer, critic: Critic, cloned: MemoryPointer, optimisers,
    data: dict[str, torch.Tensor], r: dict, generator: torch.Generator,
) -> dict:  # fmt: skip
    rows, temperature = [data[k] for k in INPUTS], r["temperature"]
    with torch.no_grad():
        advantage = data["ret"] - critic(*rows)
        advantage = (advantage - advantage.mean()) / (advantage.std() + 1e-8)
        cloned_logp = torch.log_softmax(cloned(*rows) / temperature, -1)
    present = data["kind"] >= 0
    # how often a drawn choice was not the one the cloned pointer would take
    off = float((cloned_logp.argmax(-1) != data["slot"]).float().mean())
    stats: dict[str, list] = {"policy_loss": [], "kl_cloned": [], "value_loss": [], "clipped": []}
    for _ in range(r["epochs"]):
        for idx in torch.randperm(len(advantage), generator=generator).split(r["batch"]):
            logp = torch.log_softmax(policy(*(x[idx] for x in rows)) / temperature, -1)
            chosen = logp.gather(1, data["slot"][idx, None])[:, 0]
            ratio = torch.exp(chosen - data["logp"][idx])
            a = advantage[idx]
            clipped = torch.clamp(ratio, 1 - r["clip"], 1 + r["clip"])
            pg = -torch.min(ratio * a, clipped * a).mean()
            mask = present[idx]
            p = cloned_logp[idx].exp().masked_fill(~mask, 0)
            kl = (p * (cloned_logp[idx] - logp).masked_fill(~mask, 0)).sum(-1).mean()
            loss = pg + r["kl"] * kl
            optimisers[0].zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(policy.parameters(), 0.5)
            optimisers[0].step()
            value_loss = nn.functional.mse_loss(critic(*(x[idx] for x in rows)), data["ret"][idx])
            optimisers[1].zero_grad()
            value_loss.backward()
            optimisers[1].step()
            stats["policy_loss"].append(pg.item())
            stats["kl_cloned"].append(kl.item())
            stats["value_loss"].append(value_loss.item())
            stats["clipped"].append(float(((ratio - 1).abs() > r["clip"]).float().mean()))
    means = {k: round(float(np.mean(v)), 5) for k, v in stats.items()}
    return {"off_cloned": round(off, 4), **means}


def _stack(episodes: list[dict]) -> dict[str, torch.Tensor]:
    keep = [e for e in episodes if len(e["slot"])]
    out = {k: torch.from_numpy(np.concatenate([e[k] for e in keep])) for k in
           (*INPUTS, "slot", "logp", "ret")}  # fmt: skip
    out["slot"] = out["slot"].long()
    out["logp"], out["ret"] = out["logp"].float(), out["ret"].float()
    return out


@dataclass
class Stage:
    """What a stage after cloning starts from (``start_stage``)."""

    work: Path  # data/memory/setting_S/SECTION_NAME: its checkpoints
    train_n: int  # train episodes of the setting
    val_indices: list[int]  # the val episodes it plays, as eval chooses them
    cloned: MemoryPointer  # frozen
    policy: MemoryPointer  # a trainable copy
    digest: str  # the cloned weights' fingerprint
    key: str  # what a checkpoint must match to be resumed


def start_stage(
    cfg: MemoryConfig, setting: str, section: str, settings: dict, cloned: MemoryPointer
) -> Stage:
    """The set-up PPO and the forks share; more ``iterations`` continue a run, so they are
    left out of the key."""
    from maniskill_tidy.envs.episodes import EpisodeSet
    from maniskill_tidy.eval.runner import select

    work = Path(cfg.work) / f"setting_{setting}" / f"{section}_{cfg.name}"
    work.mkdir(parents=True, exist_ok=True)
    train_n = len(EpisodeSet.for_setting(cfg.dataset, "train", setting).episodes)
    val = EpisodeSet.for_setting(cfg.dataset, "val", setting).episodes
    val_indices = select([e.start for e in val], settings["val_episodes"])
    cloned = copy.deepcopy(cloned).eval()
    for p in cloned.parameters():
        p.requires_grad_(False)
    policy = copy.deepcopy(cloned).train()
    for p in policy.parameters():
        p.requires_grad_(True)
    digest = state_digest([cloned.state_dict()])
    same = {k: v for k, v in settings.items() if k != "iterations"}
    key = {section: same, "cloned": digest, "teacher": cfg.teacher, "env": cfg.env,
           "dataset": cfg.dataset}  # fmt: skip
    if MemoryTeam.rules:  # rounds played under other rules are not resumed
        key["rules"] = MemoryTeam.rules
    key = json.dumps(key)
    return Stage(work, train_n, val_indices, cloned, policy, digest, key)


def reinforce_pointer(
    cfg: MemoryConfig, config: Path, setting: str, cloned: MemoryPointer, sizes: dict,
    progress: bool = True,
) -> tuple[MemoryPointer, dict]:  # fmt: skip
    """Fine-tune ``cloned`` (see the top); returns the selected weights and the card's part."""
    r = cfg.reinforce_settings()
    stage = start_stage(cfg, setting, "reinforce", r, cloned)
    work, train_n, val_indices = stage.work, stage.train_n, stage.val_indices
    cloned, policy, digest, key = stage.cloned, stage.policy, stage.digest, stage.key
    critic = Critic(cloned)
    optimisers = (torch.optim.Adam(policy.parameters(), lr=r["lr"]),
                  torch.optim.Adam(critic.parameters(), lr=r["critic_lr"]))  # fmt: skip
    ckpt = work / "state.pt"
    state = {"round": 0, "curve": [], "val": [], "best": None, "seconds": 0.0}
    best_state = copy.deepcopy(cloned.state_dict())
    if ckpt.is_file():
        saved = torch.load(ckpt, weights_only=False)
        if saved["key"] == key:
            policy.load_state_dict(saved["policy"])
            critic.load_state_dict(saved["critic"])
            for o, s in zip(optimisers, saved["optimisers"], strict=True):
                o.load_state_dict(s)
            state, best_state = saved["state"], saved["best_state"]
    if state["round"] > r["iterations"]:
        raise ValueError(
            f"{work} holds {state['round']} PPO rounds, more than the config's "
            f"{r['iterations']} iterations; raise them or remove that folder"
        )

    def validate(round_: int, path: Path) -> None:
        played = _play_all(cfg, config, setting, "val", val_indices, path, None, r,
                           f"val, round {round_}", progress)  # fmt: skip
        # each episode kept, so that two rounds compare over the same episodes (paired)
        each = [[e["index"], int(e["success"]), e["reasonable"], e["k"]] for e in played]
        point = {"round": round_, **summary(played), "per_episode": each}
        state["val"].append(point)
        if state["best"] is None or point["placed"] > state["best"]["placed"]:
            state["best"] = point
            best_state.clear()
            best_state.update(float_state(torch.load(path, weights_only=False)["state"]))

    def checkpoint() -> None:
        buf = io.BytesIO()
        torch.save({"key": key, "policy": policy.state_dict(), "critic": critic.state_dict(),
                    "optimisers": [o.state_dict() for o in optimisers], "state": state,
                    "best_state": best_state}, buf)  # fmt: skip
        write_atomic(ckpt, buf.getvalue())

    bar = tqdm(total=r["iterations"], initial=state["round"], desc=f"PPO {setting}",
               unit="round", disable=not progress)  # fmt: skip
    with bar:
        while state["round"] < r["iterations"]:
            n = state["round"]
            started = time.perf_counter()
            path = work / f"policy_{n:03d}.pt"
            _save_policy(policy, sizes, path)
            if n % r["val_every"] == 0 and not any(v["round"] == n for v in state["val"]):
                validate(n, path)
            rng = np.random.default_rng([r["seed"], n])
            chosen = sorted(rng.choice(train_n, r["episodes"], replace=False).tolist())
            seed = r["seed"] * 1000 + n
            played = _play_all(cfg, config, setting, "train", chosen, path, seed, r,
                               f"rollouts, round {n}", progress)  # fmt: skip
            data = _stack(played)
            generator = torch.Generator().manual_seed(seed)
            stats = ppo_update(policy, critic, cloned, optimisers, data, r, generator)
            state["round"] += 1
            state["seconds"] += time.perf_counter() - started
            state["curve"].append({"round": n, **summary(played), "decisions": len(data["slot"]),
                                   "mean_return": round(float(data["ret"].mean()), 4),
                                   **stats})  # fmt: skip
            checkpoint()
            bar.update(1)
            bar.set_postfix(train_placed=f"{state['curve'][-1]['placed']:.3f}",
                            best_val=f"{state['best']['placed']:.3f}")  # fmt: skip
    final = work / f"policy_{r['iterations']:03d}.pt"
    if not any(v["round"] == r["iterations"] for v in state["val"]):
        _save_policy(policy, sizes, final)
        validate(r["iterations"], final)
        checkpoint()
    model = MemoryPointer(type_vectors(), **sizes)
    model.load_state_dict(best_state)
    part = {"settings": r, "cloned_weights": digest, "rounds": state["round"],
            "seconds": round(state["seconds"], 1), "curve": state["curve"], "val": state["val"],
            "best": state["best"], "cloned_val": state["val"][0]}  # fmt: skip
    return model.eval(), part


def plot_reinforce(card: dict, out: Path) -> Path:
    """Train episodes (drawn choices) per round, and the greedy val runs that select."""
    import matplotlib.pyplot as plt

    from maniskill_tidy.common.plotting import save_figure

    r = card["reinforce"]
    fig, (a, b) = plt.subplots(1, 2, figsize=(8, 3))
    rounds = [c["round"] for c in r["curve"]]
    a.plot(rounds, [c["placed"] for c in r["curve"]], label="train, drawn choices")
    a.plot([v["round"] for v in r["val"]], [v["placed"] for v in r["val"]], "o-",
           label="val, best choices")  # fmt: skip
    a.axvline(r["best"]["round"], color="grey", ls=":")
    a.set(xlabel="round", ylabel="share put where it belongs", title="objects placed")
    a.legend()
    b.plot(rounds, [c["kl_cloned"] for c in r["curve"]], label="KL to the cloned pointer")
    b.plot(rounds, [c["off_cloned"] for c in r["curve"]], label="drawn != cloned's best")
    b.set(xlabel="round", title="distance from the teacher's rule")
    b.legend()
    fig.suptitle(f"{card['name']}, Setting {card['setting']}: PPO")
    return save_figure(fig, out, dpi=100)
