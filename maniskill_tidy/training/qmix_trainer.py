"""QMIX training (the paper's QMIX baseline): ``maniskill-tidy train agents/qmix.yaml --setting I``.

A pymarl-style loop on the train split, every camera rendered:

1. the team plays one episode with epsilon-greedy exploration over each agent's legal actions
   (``policies/qmix_team.py``); the episode's observations, actions, legal masks and team
   rewards are written to the work folder (one file per episode, append-only);
2. a few TD updates on batches of whole episodes from the last ``buffer`` episodes: the
   agents' Q-networks unrolled over the episode, the chosen actions' values mixed into Q_tot
   (``models/qmix.py``), target ``r + gamma * Q_tot'(s', argmax_a Q(s', a))`` from target
   networks (double Q), copied every ``target_every`` episodes. The last step of an episode
   (success, every agent stopped, or the step limit) is treated as terminal;
3. checkpoint (weights, target, optimiser, generators, learning curve) atomically: a rerun
   resumes at the next episode.

The team reward (documented in the model card): ``placed`` per misplaced object newly in a
reasonable place, ``picked`` per object picked up for the first time, ``step`` every step. The
budget is the number of training episodes (``episodes``); the env steps they took are in the
card and the curve. The simulator's counters are read for the reward only: centralised
training, decentralised execution (the agents never see it).
"""

from __future__ import annotations

import copy
import io
import json
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from maniskill_tidy.common.files import write_atomic
from maniskill_tidy.models.checkpoints import save_qmix, weights_sha256
from maniskill_tidy.models.qmix import OBS, QmixTeamModel
from maniskill_tidy.policies.agent_config import QmixConfig
from maniskill_tidy.tasks.teams import SETTINGS


# ----------------------------------------------------------------------------- episodes
class TeamReward:
    """An episode observer: the team reward of every step, from the env's counters."""

    def __init__(self, weights: dict) -> None:
        self.w = weights

    def start(self, env, team, channel) -> None:
        self.rewards: list[float] = []
        self.placed, self.picked = 0, 0
        self.success = False

    def log_step(self, t, obs, actions, info, channel, labels) -> None:
        placed, picked = int(info["n_reasonable"]), len(info["picked"])
        w = self.w
        gain = w["placed"] * (placed - self.placed) + w["picked"] * (picked - self.picked)
        self.rewards.append(gain + w["step"])
        self.placed, self.picked = placed, picked
        self.success = bool(info["success"])


def episode_arrays(steps, rewards: list[float], agents: int) -> dict[str, torch.Tensor]:
    """One episode's tensors: obs (T, N, OBS) fp16, actions (T, N) (-1 absent), legal
    (T, N, 11), present (T, N), reward (T)."""
    from maniskill_tidy.models.qmix import ACTIONS

    t = len(rewards)
    obs = torch.zeros(t, agents, OBS, dtype=torch.float16)
    actions = torch.full((t, agents), -1, dtype=torch.long)
    legal = torch.zeros(t, agents, ACTIONS, dtype=torch.bool)
    for step, by_agent in steps.obs.items():
        for i, (o, a, ok) in by_agent.items():
            obs[step, i], actions[step, i], legal[step, i] = o.half(), a, torch.from_numpy(ok)
    return {"obs": obs, "actions": actions, "legal": legal, "present": actions >= 0,
            "reward": torch.tensor(rewards, dtype=torch.float32)}  # fmt: skip


def collate(episodes: list[dict]) -> dict[str, torch.Tensor]:
    """Pad episodes to the longest; ``valid`` (B, T) marks real steps."""
    t = max(len(e["reward"]) for e in episodes)
    out: dict[str, list] = {k: [] for k in (*episodes[0], "valid")}
    for e in episodes:
        pad = t - len(e["reward"])
        for k, v in e.items():
            fill = -1 if k == "actions" else 0
            out[k].append(torch.cat([v, torch.full((pad, *v.shape[1:]), fill, dtype=v.dtype)]))
        out["valid"].append(torch.arange(t) < len(e["reward"]))
    return {k: torch.stack(v) for k, v in out.items()}


def td_loss(model: QmixTeamModel, target: QmixTeamModel, b: dict, gamma: float) -> torch.Tensor:
    """Mean squared TD error of Q_tot over the valid steps (double Q, terminal at the end)."""
    obs, present = b["obs"].float(), b["present"]
    q = model.q_values(obs, present)
    chosen = q.gather(-1, b["actions"].clamp(min=0).unsqueeze(-1)).squeeze(-1)
    q_tot = model.mix(chosen, obs, present)
    with torch.no_grad():
        best = q.masked_fill(~b["legal"], -torch.inf).argmax(-1)
        tq = target.q_values(obs, present).gather(-1, best.unsqueeze(-1)).squeeze(-1)
        t_tot = target.mix(tq, obs, present)
        nxt = torch.cat([t_tot[:, 1:], torch.zeros_like(t_tot[:, :1])], dim=1)
        nxt = nxt * torch.cat([b["valid"][:, 1:], torch.zeros_like(b["valid"][:, :1])], 1)
        y = b["reward"] + gamma * nxt
    valid = b["valid"].float()
    return (((q_tot - y) ** 2) * valid).sum() / valid.sum()


# ----------------------------------------------------------------------------- training
def train_qmix(config: Path, setting: str, progress: bool = True, env=None) -> dict:
    """Train (resumable), then write the model, its card and learning curve; returns the card.
    ``env``: a train-split env of the setting to reuse (made from the config when None)."""
    from maniskill_tidy.eval.episode import play_episode
    from maniskill_tidy.eval.runner import RunConfig, make_env
    from maniskill_tidy.models.checkpoints import load_perception
    from maniskill_tidy.policies.qmix_team import QmixTeam, Steps

    cfg = QmixConfig.load(config)
    if setting not in SETTINGS:
        raise ValueError(f"unknown setting {setting!r}; expected one of {sorted(SETTINGS)}")
    agents = len(SETTINGS[setting])
    work = Path(cfg.work) / f"setting_{setting}"
    (work / "episodes").mkdir(parents=True, exist_ok=True)
    torch.manual_seed(cfg.seed)
    model = QmixTeamModel(agents)
    target = copy.deepcopy(model)
    optimiser = torch.optim.Adam(model.parameters(), lr=cfg.lr)
    rng = np.random.default_rng(cfg.seed)
    key = json.dumps({k: v for k, v in asdict(cfg).items() if k not in ("episodes", "notes")})
    ckpt = work / f"{cfg.name}.ckpt"
    state = _resume(ckpt, key, model, target, optimiser, rng)
    perception = load_perception(Path(cfg.perception))
    own_env = env is None
    if own_env:
        env = make_env(RunConfig("qmix", setting, "train", cfg.dataset))
    env.unwrapped.max_steps = cfg.max_steps
    n_train = len(env.unwrapped.episodes.episodes)
    buffer: dict[int, dict] = {}
    for k in range(max(0, state["episode"] - cfg.buffer), state["episode"]):
        buffer[k] = torch.load(work / "episodes" / f"ep_{k:05d}.pt")
    bar = tqdm(total=cfg.episodes, initial=state["episode"], desc=f"qmix {setting}",
               unit="episode", disable=not progress)  # fmt: skip
    try:
        while state["episode"] < cfg.episodes:
            k = state["episode"]
            started = time.perf_counter()
            steps, reward = Steps(), TeamReward(cfg.reward)
            team = QmixTeam(model, cfg.exploration(k), perception, steps)
            index = int(rng.integers(n_train))
            model.eval()
            record = play_episode(env, team, index, cfg.seed + k, [reward])
            episode = episode_arrays(steps, reward.rewards, agents)
            buf = io.BytesIO()
            torch.save(episode, buf)
            write_atomic(work / "episodes" / f"ep_{k:05d}.pt", buf.getvalue())
            buffer[k] = episode
            buffer.pop(k - cfg.buffer, None)
            losses = _td_updates(model, target, optimiser, buffer, rng, cfg)
            if (k + 1) % cfg.target_every == 0:
                target.load_state_dict(model.state_dict())
            state["episode"] = k + 1
            state["env_steps"] += record.length
            state["seconds"] += time.perf_counter() - started
            state["curve"].append({
                "episode": k + 1, "return": float(sum(reward.rewards)), "success": reward.success,
                "placed": reward.placed, "length": record.length, "loss": float(np.mean(losses)),
                "epsilon": cfg.exploration(k), "env_steps": state["env_steps"],
            })  # fmt: skip
            _checkpoint(ckpt, key, model, target, optimiser, rng, state)
            bar.update(1)
            bar.set_postfix(ret=f"{state['curve'][-1]['return']:.2f}",
                            eps=f"{cfg.exploration(k):.2f}")  # fmt: skip
    finally:
        bar.close()
        if own_env:
            env.close()
    model.eval()
    return _write_model(cfg, config, setting, model, perception, state)


def _resume(ckpt: Path, key: str, model, target, optimiser, rng) -> dict:
    """The training state of a checkpoint of the same settings, loaded into the model, its
    target, the optimiser and the generators; a fresh state otherwise."""
    state = {"episode": 0, "curve": [], "seconds": 0.0, "env_steps": 0}
    if ckpt.is_file():
        saved = torch.load(ckpt, weights_only=False)
        if saved["settings"] == key:
            model.load_state_dict(saved["model"])
            target.load_state_dict(saved["target"])
            optimiser.load_state_dict(saved["optimiser"])
            rng.bit_generator.state = saved["rng"]
            torch.set_rng_state(saved["torch_rng"])
            state = saved["state"]
    return state


def _checkpoint(ckpt: Path, key: str, model, target, optimiser, rng, state: dict) -> None:
    buf = io.BytesIO()
    torch.save({"model": model.state_dict(), "target": target.state_dict(),
                "optimiser": optimiser.state_dict(), "rng": rng.bit_generator.state,
                "torch_rng": torch.get_rng_state(), "state": state, "settings": key},
               buf)  # fmt: skip
    write_atomic(ckpt, buf.getvalue())


def _td_updates(model, target, optimiser, buffer: dict, rng, cfg: QmixConfig) -> list[float]:
    """``cfg.updates`` TD steps on batches of whole episodes from the buffer."""
    model.train()
    losses = []
    for _ in range(cfg.updates):
        keys = sorted(buffer)
        pick = rng.choice(keys, size=min(cfg.batch, len(keys)), replace=False)
        loss = td_loss(model, target, collate([buffer[int(j)] for j in pick]), cfg.gamma)
        optimiser.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 10.0)
        optimiser.step()
        losses.append(loss.item())
    return losses


def _write_model(cfg: QmixConfig, config: Path, setting: str, model, perception, state) -> dict:
    """The weights, the card (validated greedily on val) and the learning curve."""
    from maniskill_tidy.common.provenance import code_version

    folder = Path(cfg.out) / f"setting_{setting}"
    save_qmix(model, folder, {"name": cfg.name, "perception": cfg.perception})
    card = {
        "name": cfg.name, "setting": setting, "config": str(config), "settings": asdict(cfg),
        "episodes": state["episode"], "env_steps": state["env_steps"],
        "train_seconds": round(state["seconds"], 1), "curve": state["curve"],
        "parameters_per_agent": sum(p.numel() for p in model.agents[0].parameters()),
        "mixer_parameters": sum(p.numel() for p in model.mixer.parameters()),
        "val": validate(cfg, setting, model, perception), "code_version": code_version(),
        "weights_sha256": weights_sha256(folder),
    }  # fmt: skip
    write_atomic(folder / "card.json", json.dumps(card, indent=1).encode())
    write_atomic(folder / "MODEL_CARD.md", qmix_card(card).encode())
    plot_curve(card, folder / "curve.png")
    return card


def validate(cfg: QmixConfig, setting: str, model: QmixTeamModel, perception) -> dict:
    """Greedy episodes on val (the first ``val_episodes``): success and placed objects."""
    from maniskill_tidy.eval.episode import play_episode
    from maniskill_tidy.eval.runner import RunConfig, make_env
    from maniskill_tidy.policies.qmix_team import QmixTeam

    if cfg.val_episodes < 1:
        return {}
    env = make_env(RunConfig("qmix", setting, "val", cfg.dataset))
    try:
        rows = []
        for i in range(cfg.val_episodes):
            reward = TeamReward(cfg.reward)
            record = play_episode(env, QmixTeam(model, 0.0, perception), i, i, [reward])
            rows.append({"success": record.success, "placed": reward.placed,
                         "length": record.length,
                         "return": float(sum(reward.rewards))})  # fmt: skip
    finally:
        env.close()
    return {"episodes": rows, "success": float(np.mean([r["success"] for r in rows])),
            "placed": float(np.mean([r["placed"] for r in rows]))}  # fmt: skip


def qmix_card(card: dict) -> str:
    s, val = card["settings"], card["val"]
    lines = [
        f"# {card['name']}, Setting {card['setting']}",
        "",
        "QMIX (the paper's baseline): per-agent recurrent Q-networks over the frozen perception "
        "features fused with the teammates' 256-d state features, mixed by TorchRL's QMixer "
        f"(`maniskill-tidy train {card['config']} --setting {card['setting']}`).",
        "",
        f"- budget: {card['episodes']} training episodes, {card['env_steps']} env steps on the "
        f"train split (at most {s['max_steps']} steps each), {card['train_seconds']:.0f} s on "
        "2 CPU cores, every camera rendered",
        f"- team reward: {s['reward']['placed']} per misplaced object newly in a reasonable "
        f"place, {s['reward']['picked']} per object first picked up, {s['reward']['step']} "
        "per step",
        f"- exploration: epsilon from {s['epsilon']['start']} to {s['epsilon']['end']} over "
        f"{s['epsilon']['episodes']} episodes, over each agent's legal actions",
        f"- TD: gamma {s['gamma']}, Adam lr {s['lr']}, {s['updates']} updates of "
        f"{s['batch']} episodes after each episode from the last {s['buffer']}, target copied "
        f"every {s['target_every']} episodes, double Q",
        f"- {card['parameters_per_agent']:,} parameters per agent, mixer "
        f"{card['mixer_parameters']:,}",
    ]
    if val:
        lines.append(
            f"- val ({len(val['episodes'])} greedy episodes): success {val['success']:.2f}, "
            f"objects placed per episode {val['placed']:.2f}"
        )
    lines += ["", "![learning curve](curve.png)", ""]
    return "\n".join(lines)


def plot_curve(card: dict, out: Path) -> Path:
    import matplotlib.pyplot as plt

    from maniskill_tidy.common.plotting import save_figure

    curve = card["curve"]
    x = [c["env_steps"] for c in curve]
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    for ax, key, label in zip(
        axes, ("return", "placed", "loss"),
        ("team return per episode", "objects placed per episode", "TD loss"), strict=True,
    ):  # fmt: skip
        y = np.array([c[key] for c in curve], dtype=float)
        ax.plot(x, y, ".", alpha=0.4)
        if len(y) >= 5:
            w = np.ones(5) / 5
            ax.plot(x[4:], np.convolve(y, w, mode="valid"), "-", label="mean of 5")
            ax.legend(fontsize=8)
        ax.set(xlabel="env steps", title=label)
        ax.grid(alpha=0.3)
    fig.suptitle(f"QMIX, Setting {card['setting']}")
    return save_figure(fig, out)
