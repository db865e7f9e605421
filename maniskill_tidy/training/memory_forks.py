"""Policy improvement for the object-memory pointer from forked episodes (an experiment).

PPO (``training/memory_reinforce.py``) credits a drawn choice with a return that every later
drawn choice of the team moved too, and its best round on 40 val episodes was worse than the
clone on test. Here the credit is exact for one episode. The env and the team are deterministic
(same seed, same pixels), so an episode played again with the pointer's best choice everywhere
but one decision, where the agent takes another candidate, differs from the first play only by
that choice and what followed from it. The difference of the two plays' discounted team returns
(from the episode's start) is that choice's advantage over the pointer's best at that state,
under the pointer's own later choices, times ``gamma ** t`` for a decision at step t: a rollout
in the sense of Bertsekas's rollout algorithms, with no sampling noise. The sign is what the
pointer learns; the weight it gets leans towards early decisions (0.99 ** 300 is about 0.05).

Each round plays ``episodes`` train episodes with the best choices (the bases), picks ``forks``
decisions in each (with at least two candidates) and, for each, another candidate drawn from the
pointer's scores divided by ``temperature`` (so plausible ones more often), plays those forks and
keeps every pair whose returns differ. The pointer is then trained on all pairs so far to score
the better of each pair above the other (a logistic loss on the two scores, weighted by how much
better), with a KL term towards the cloned pointer on the round's decisions; the next round's
bases play the updated pointer (policy iteration). At the end the clone and the last round play
the standard val protocol with their best choices, and the last round is kept only if its
paired gain in the share of objects put where they belong has a 95 % interval above zero.

The returns are training's signal only; no agent reads them. Each round ends in an atomic
checkpoint with every pair so far, and a rerun resumes from it.
"""

from __future__ import annotations

import io
import time
from pathlib import Path

import numpy as np
import torch
from torch import nn
from tqdm import tqdm

from maniskill_tidy.common.files import write_atomic
from maniskill_tidy.models.checkpoints import float_state, type_vectors
from maniskill_tidy.models.memory_pointer import MemoryPointer
from maniskill_tidy.policies.agent_config import MemoryConfig
from maniskill_tidy.training.memory_reinforce import (
    INPUTS,
    _save_policy,
    play_jobs,
    start_stage,
    summary,
)

PAIR_KEYS = (*INPUTS, "best", "other", "gain")


def choose_forks(
    policy: MemoryPointer, base: dict, k: int, temperature: float, rng: np.random.Generator
) -> list[tuple[int, int, int]]:
    """Up to ``k`` overrides ``(agent, n, slot)`` for one base episode: decisions with at least
    two candidates, each with another candidate drawn from the tempered scores."""
    if not len(base["slot"]):  # no decision in this episode
        return []
    present = base["kind"] >= 0
    eligible = np.flatnonzero(present.sum(1) >= 2)
    if not len(eligible):
        return []
    picked = np.sort(rng.choice(eligible, min(k, len(eligible)), replace=False))
    rows = [torch.from_numpy(base[key][picked]) for key in INPUTS]
    with torch.no_grad():
        p = torch.softmax(policy(*rows) / temperature, -1).double().numpy()
    out = []
    for row, q in zip(picked, p, strict=True):
        q = np.where(present[row], q, 0.0)
        if q.sum() - q[base["slot"][row]] <= 0:  # the scores left nothing else: uniform
            q = present[row].astype(np.float64)
        q[base["slot"][row]] = 0.0
        other = int(rng.choice(len(q), p=q / q.sum()))
        out.append((int(base["agent"][row]), int(base["n"][row]), other))
    return out


def pairs_of(base: dict, forks: list[dict]) -> dict[str, np.ndarray]:
    """The decisions forked in ``base``, each with its two choices (``best``: the base's, the
    best of the pointer that played it) and the other's gain in the team's return."""
    where = {(int(a), int(n)): i for i, (a, n) in enumerate(zip(base["agent"], base["n"],
                                                               strict=True))}  # fmt: skip
    rows = [where[f["override"][:2]] for f in forks]
    out = {key: base[key][rows] for key in INPUTS}
    out["best"] = base["slot"][rows]
    out["other"] = np.array([f["override"][2] for f in forks], np.int64)
    out["gain"] = np.array([f["return"] - base["return"] for f in forks], np.float64)
    # what the benchmark's metrics see at the episode's end, undiscounted (analysis only)
    out["placed_gain"] = np.array([(f["reasonable"] - base["reasonable"]) / max(base["k"], 1)
                                   for f in forks], np.float64)  # fmt: skip
    out["success_gain"] = np.array([int(f["success"]) - int(base["success"]) for f in forks])
    return out


def preference_update(
    policy: MemoryPointer, cloned: MemoryPointer, optimiser, pairs: dict[str, torch.Tensor],
    decisions: list[torch.Tensor], f: dict, generator: torch.Generator,
) -> dict:  # fmt: skip
    """Score the better choice of each pair above the other (weighted by |gain| over its mean),
    and stay near the cloned pointer on ``decisions`` (KL in the tempered space)."""
    informative = pairs["gain"] != 0
    rows = [pairs[k][informative] for k in INPUTS]
    best, other, gain = (pairs[k][informative] for k in ("best", "other", "gain"))
    if not len(gain):
        return {"pairs": 0, "loss": 0.0, "kl_cloned": 0.0, "ranked_right": None}
    weight = gain.abs() / gain.abs().mean()
    target = (gain > 0).float()  # 1: the fork's choice was the better one
    temperature = f["temperature"]
    with torch.no_grad():
        cloned_logp = torch.log_softmax(cloned(*decisions) / temperature, -1)
    present = decisions[0] >= 0
    losses, kls = [], []
    for _ in range(f["epochs"]):
        order = torch.randperm(len(gain), generator=generator)
        kl_order = torch.randperm(len(present), generator=generator)
        n_batches = max(1, -(-len(gain) // f["batch"]))
        for idx, kidx in zip(order.tensor_split(n_batches), kl_order.tensor_split(n_batches),
                             strict=True):  # fmt: skip
            margin = _margin(policy(*(x[idx] for x in rows)), best[idx], other[idx])
            pref = nn.functional.binary_cross_entropy_with_logits(
                margin, target[idx], weight=weight[idx]
            )
            kl = margin.new_zeros(())
            if len(kidx):  # fewer decisions than batches leaves some batches none
                logp = torch.log_softmax(policy(*(x[kidx] for x in decisions)) / temperature, -1)
                mask = present[kidx]
                p = cloned_logp[kidx].exp().masked_fill(~mask, 0)
                kl = (p * (cloned_logp[kidx] - logp).masked_fill(~mask, 0)).sum(-1).mean()
            loss = pref + f["kl"] * kl
            optimiser.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(policy.parameters(), 0.5)
            optimiser.step()
            losses.append(pref.item())
            kls.append(kl.item())
    with torch.no_grad():
        right = (_margin(policy(*rows), best, other) > 0) == (gain > 0)
    return {"pairs": int(len(gain)), "loss": round(float(np.mean(losses)), 5),
            "kl_cloned": round(float(np.mean(kls)), 5),
            "ranked_right": round(float(right.float().mean()), 4)}  # fmt: skip


def _margin(scores: torch.Tensor, best: torch.Tensor, other: torch.Tensor) -> torch.Tensor:
    """How far the other choice's score is above the best one's."""
    return scores.gather(1, other[:, None])[:, 0] - scores.gather(1, best[:, None])[:, 0]


def paired_gain(a: list[dict], b: list[dict]) -> dict:
    """A - B over the episodes both played: Success and share placed, with 95 % intervals."""
    from maniskill_tidy.eval.metrics import bootstrap_ci

    by_index = {e["index"]: e for e in b}
    shared = [e for e in a if e["index"] in by_index]
    out: dict = {"episodes": len(shared)}
    for name, value in (("success", lambda e: float(e["success"])),
                        ("placed", lambda e: e["reasonable"] / max(e["k"], 1))):  # fmt: skip
        d = np.array([value(e) - value(by_index[e["index"]]) for e in shared])
        out[name] = {"difference": round(float(d.mean()), 4),
                     "ci95": [round(x, 4) for x in bootstrap_ci(d)],
                     "better": int((d > 0).sum()), "worse": int((d < 0).sum())}  # fmt: skip
    return out


def _stack(parts: list[dict]) -> dict[str, torch.Tensor]:
    out = {k: torch.from_numpy(np.concatenate([p[k] for p in parts])) for k in parts[0]}
    for k in ("best", "other"):
        if k in out:
            out[k] = out[k].long()
    if "gain" in out:
        out["gain"] = out["gain"].float()
    return out


def improve_pointer(
    cfg: MemoryConfig, config: Path, setting: str, cloned: MemoryPointer, sizes: dict,
    progress: bool = True,
) -> tuple[MemoryPointer, dict]:  # fmt: skip
    """Improve ``cloned`` from forked episodes (see the top); returns the kept weights and the
    card's part."""
    f = cfg.forks_settings()
    stage = start_stage(cfg, setting, "forks", f, cloned)
    work, train_n, val_indices = stage.work, stage.train_n, stage.val_indices
    cloned, policy, digest, key = stage.cloned, stage.policy, stage.digest, stage.key
    optimiser = torch.optim.Adam(policy.parameters(), lr=f["lr"])
    ckpt = work / "state.pt"
    state: dict = {"round": 0, "curve": [], "seconds": 0.0, "val": {}, "val_seconds": 0.0}
    pairs: list[dict] = []
    if ckpt.is_file():
        saved = torch.load(ckpt, weights_only=False)
        if saved["key"] == key:
            policy.load_state_dict(saved["policy"])
            optimiser.load_state_dict(saved["optimiser"])
            state, pairs = saved["state"], saved["pairs"]
        elif progress:
            tqdm.write(f"{ckpt}: another config's rounds; starting over")
    if state["round"] > f["iterations"]:
        raise ValueError(
            f"{work} holds {state['round']} rounds of forks, more than the config's "
            f"{f['iterations']} iterations; raise them or remove that folder"
        )

    def checkpoint() -> None:
        buf = io.BytesIO()
        torch.save({"key": key, "policy": policy.state_dict(), "optimiser": optimiser.state_dict(),
                    "state": state, "pairs": pairs}, buf)  # fmt: skip
        write_atomic(ckpt, buf.getvalue())

    returns = {"gamma": f["gamma"], "bonus": f["bonus"]}
    bar = tqdm(total=f["iterations"], initial=state["round"], desc=f"forks {setting}",
               unit="round", disable=not progress)  # fmt: skip
    with bar:
        while state["round"] < f["iterations"]:
            n = state["round"]
            started = time.perf_counter()
            state["val"].pop("last", None)  # more rounds: a new last round to judge
            path = str(work / f"policy_{n:03d}.pt")
            _save_policy(policy, sizes, Path(path))
            rng = np.random.default_rng([f["seed"], n])
            chosen = sorted(rng.choice(train_n, f["episodes"], replace=False).tolist())
            bases = play_jobs(cfg, config, setting, "train",
                              [(i, path, {**returns, "keep": True}) for i in chosen],
                              f"bases, round {n}", progress)  # fmt: skip
            jobs, owner = [], []
            for b, base in enumerate(bases):
                for override in choose_forks(policy, base, f["forks"], f["temperature"], rng):
                    jobs.append((base["index"], path, {**returns, "override": override}))
                    owner.append(b)
            forks = play_jobs(cfg, config, setting, "train", jobs, f"forks, round {n}", progress)
            new = [pairs_of(base, [fk for fk, o in zip(forks, owner, strict=True) if o == b])
                   for b, base in enumerate(bases) if b in owner]  # fmt: skip
            pairs.extend(new)
            gains = np.concatenate([p["gain"] for p in new]) if new else np.zeros(0)
            generator = torch.Generator().manual_seed(f["seed"] * 1000 + n)
            played = [{k: b[k] for k in INPUTS} for b in bases if len(b["slot"])]
            stats = {"pairs": 0}
            if pairs and played:
                decisions = _stack(played)
                stats = preference_update(policy, cloned, optimiser, _stack(pairs),
                                          [decisions[k] for k in INPUTS], f, generator)  # fmt: skip
            state["round"] += 1
            state["seconds"] += time.perf_counter() - started
            state["curve"].append({
                "round": n, **summary(bases), "forks": len(forks),
                "fork_better": int((gains > 0).sum()), "fork_worse": int((gains < 0).sum()),
                "mean_abs_gain": round(float(np.abs(gains).mean()), 5) if len(gains) else 0.0,
                **stats})  # fmt: skip
            checkpoint()
            bar.update(1)
            bar.set_postfix(better=f"{state['curve'][-1]['fork_better']}/{len(forks)}")

    # selection: the clone against the last round, paired over the val protocol
    final, clone_path = work / f"policy_{f['iterations']:03d}.pt", work / "policy_000.pt"
    _save_policy(policy, sizes, final)  # never a file an older run left
    _save_policy(cloned, sizes, clone_path)
    for who, path in (("cloned", clone_path), ("last", final)):
        if who not in state["val"]:
            started = time.perf_counter()
            played = play_jobs(cfg, config, setting, "val",
                               [(i, str(path), returns) for i in val_indices],
                               f"val, {who}", progress)  # fmt: skip
            state["val"][who] = [{k: e[k] for k in ("index", "success", "reasonable", "k")}
                                 for e in played]  # fmt: skip
            state["val_seconds"] = state.get("val_seconds", 0.0) + time.perf_counter() - started
            checkpoint()
    gain = paired_gain(state["val"]["last"], state["val"]["cloned"])
    kept = "last" if gain["placed"]["ci95"][0] > 0 else "cloned"
    model = MemoryPointer(type_vectors(), **sizes)
    model.load_state_dict(float_state(torch.load(final if kept == "last" else clone_path,
                                                 weights_only=False)["state"]))  # fmt: skip
    part = {"settings": f, "cloned_weights": digest, "rounds": state["round"],
            "seconds": round(state["seconds"], 1), "curve": state["curve"],
            "val_seconds": round(state.get("val_seconds", 0.0), 1),
            "forks_played": int(sum(len(p["gain"]) for p in pairs)),
            "val": {who: summary(v) for who, v in state["val"].items()},
            "val_gain": gain, "kept": kept}  # fmt: skip
    return model.eval(), part


def plot_forks(card: dict, out: Path) -> Path:
    """Per round: how the forks compared with the best choice, and the bases' share placed."""
    import matplotlib.pyplot as plt

    from maniskill_tidy.common.plotting import save_figure

    part = card["forks"]
    curve = part["curve"]
    rounds = [c["round"] for c in curve]
    fig, (a, b) = plt.subplots(1, 2, figsize=(8, 3))
    a.plot(rounds, [c["fork_better"] / max(c["forks"], 1) for c in curve], "o-",
           label="another choice did better")  # fmt: skip
    a.plot(rounds, [c["fork_worse"] / max(c["forks"], 1) for c in curve], "o-",
           label="the best choice did better")  # fmt: skip
    a.set(xlabel="round", ylabel="share of forks", title="forks against the pointer's best")
    a.legend()
    b.plot(rounds, [c["placed"] for c in curve], "o-", label="train bases")
    for who, style in (("cloned", ":"), ("last", "--")):
        if who in part["val"]:
            b.axhline(part["val"][who]["placed"], ls=style, color="grey", label=f"val, {who}")
    b.set(xlabel="round", ylabel="share put where it belongs", title="best choices")
    b.legend()
    fig.suptitle(f"{card['name']}, Setting {card['setting']}: forks (kept: {part['kept']})")
    return save_figure(fig, out, dpi=100)
