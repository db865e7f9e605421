"""Training the object-memory team's links (``policies/memory_links.py``).

``maniskill-tidy train CONFIG --setting S`` for a config with ``links``:

1. the trained pointer of ``links.pointer`` is copied into the config's folder (checked
   against its card): the team plays it unchanged;
2. the team plays train and val episodes without messages (``recording_links``), each agent
   keeping a snapshot of its memory every step; one shard per house (``house_jobs``:
   parallel, resumable), ``DIR/links/setting_S/SPLIT/house_NNNNN.npz`` with per team step
   ``sf`` (N x len(SUMMARY)), ``present`` (N) and ``useful`` (N x N);
3. labels, read by the trainer from every agent's snapshot of the same step (centralised
   training): ``useful[i, j]`` when A_i is a manipulator and A_j remembers a misplaced object
   that A_i neither knows of nor has a report of (``SAME_OBJECT``) and that A_j has not told
   A_i of. Episodes played without messages make every teammate's object news, so there are
   positives to learn from; the summary says how much a teammate has not been told, so the
   rule carries over to play with links;
4. query and key (``models/memory_links.py``) fitted to the labels' rows of T, the epoch of
   best val loss kept; val also gets the hard handshake's link precision and recall;
5. the card plays the first ``val_episodes`` val episodes with the team and its teacher.
"""

from __future__ import annotations

import copy
import io
import json
import shutil
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from maniskill_tidy.common.files import write_atomic
from maniskill_tidy.envs.episodes import EpisodeSet
from maniskill_tidy.models.checkpoints import half_state, read, save, weights_sha256
from maniskill_tidy.models.hangrcom import hard_links
from maniskill_tidy.models.memory_links import MemoryLinks, link_loss, target_rows
from maniskill_tidy.policies.agent_config import MemoryConfig
from maniskill_tidy.policies.heuristic import SAME_OBJECT
from maniskill_tidy.policies.memory_links import SUMMARY
from maniskill_tidy.training.decision_data import DemoConfig, select_episodes
from maniskill_tidy.training.house_jobs import (
    check_same_config,
    run_house_jobs,
    shards_digest,
    total_seconds,
)

FORMAT_VERSION = 1
ARRAYS = ("sf", "present", "useful", "episode", "t")
_worker: dict = {}


def useful_links(names: list[str], snaps: list[dict | None]) -> np.ndarray:
    """``useful[i, j]`` of one team step from every agent's snapshot (None: not playing)."""
    n = len(names)
    useful = np.zeros((n, n), dtype=bool)
    for i, si in enumerate(snaps):
        if si is None or not si["manipulator"]:
            continue
        for j, sj in enumerate(snaps):
            if j == i or sj is None:
                continue
            told = sj["told"].get(names[i], set())
            useful[i, j] = any(
                oid not in si["known"] and oid not in told
                and not any(t == typ and np.hypot(x - rx, y - ry) < SAME_OBJECT
                            for t, rx, ry in si["reports"])
                for oid, (typ, x, y) in sj["misplaced"].items()
            )  # fmt: skip
    return useful


def _init(cfg: MemoryConfig, config: str, setting: str, split: str):
    from maniskill_tidy.eval.runner import RunConfig, make_env

    env = make_env(RunConfig(cfg.teacher, setting, split, cfg.dataset, env=cfg.env))
    _worker.update(env=env, config=config)
    return env.close


def _house_steps(job: tuple[str, list[int], str]) -> tuple[str, bytes]:
    from maniskill_tidy.eval.episode import play_episode
    from maniskill_tidy.policies.memory import memory_team_class

    house, indices, shard = job
    team = memory_team_class(_worker["config"])(recording_links=True)
    rows: dict[str, list] = {k: [] for k in ARRAYS}
    episodes = []
    started = time.perf_counter()
    for i in indices:
        team.made.clear()
        record = play_episode(_worker["env"], team, i, i)  # seed = index, as an eval run's
        episodes.append({"episode": record.episode, "success": record.success,
                         "length": record.length})  # fmt: skip
        names = [a.name for a in team.made]
        by_t = [{s["t"]: s for s in a.snapshots} for a in team.made]
        for t in sorted(set().union(*by_t)):
            snaps = [b.get(t) for b in by_t]
            rows["sf"].append([s["sf"] if s else np.zeros(len(SUMMARY), np.float32)
                               for s in snaps])  # fmt: skip
            rows["present"].append([s is not None for s in snaps])
            rows["useful"].append(useful_links(names, snaps))
            rows["episode"].append(len(episodes) - 1)
            rows["t"].append(t)
    buf = io.BytesIO()
    np.savez_compressed(buf, **{k: np.asarray(v) for k, v in rows.items()},
                        episodes=json.dumps(episodes),
                        seconds=np.array(time.perf_counter() - started))  # fmt: skip
    return shard, buf.getvalue()


def build_link_data(config: Path, setting: str, split: str, progress: bool = True) -> Path:
    """Play and record ``split`` without messages (resumable per house); its folder."""
    from maniskill_tidy.common.provenance import code_version
    from maniskill_tidy.policies.memory import MemoryTeam

    cfg = MemoryConfig.load(config)
    demos = cfg.train_demos if split == "train" else cfg.val_demos
    select = DemoConfig(setting=setting, split=split, starts=demos.get("starts", 1),
                        tasks=demos.get("tasks"), houses=demos.get("houses"))  # fmt: skip
    episodes = EpisodeSet.for_setting(cfg.dataset, split, setting)
    by_house = select_episodes(episodes.episodes, select)
    directory = Path(cfg.work) / "links" / f"setting_{setting}" / split
    pointer = weights_sha256(Path(cfg.links_settings()["pointer"]) / f"setting_{setting}")
    want = {"format_version": FORMAT_VERSION, "dataset_hash": episodes.dataset_hash,
            "env": cfg.env, "pointer_sha256": pointer, "teacher_rules": MemoryTeam.rules,
            "starts": select.starts, "tasks": select.tasks, "houses": select.houses,
            "summary": list(SUMMARY)}  # fmt: skip
    check_same_config(directory / "manifest.json", want)
    directory.mkdir(parents=True, exist_ok=True)
    jobs = [(h, idx, str(directory / f"{h}.npz")) for h, idx in by_house.items()
            if not (directory / f"{h}.npz").exists()]  # fmt: skip
    bar = tqdm(total=len(by_house), initial=len(by_house) - len(jobs), unit="house",
               desc=f"memory snapshots {setting} {split}", disable=not progress)  # fmt: skip
    seconds = run_house_jobs(jobs, _init, (cfg, str(config), setting, split), _house_steps,
                             cfg.workers, bar)  # fmt: skip
    data = load_link_steps(directory)
    present = data["present"]
    manifest = {
        **want,
        "houses_done": len(list(directory.glob("house_*.npz"))),
        "steps": int(len(present)),
        "agent_steps": int(present.sum()),
        "useful_share": round(float(data["useful"].any(-1).sum() / max(present.sum(), 1)), 4),
        "data_hash": shards_digest(directory, "house_*.npz"),
        "seconds": total_seconds(directory / "manifest.json", seconds),
        "code_version": code_version(),
    }
    write_atomic(directory / "manifest.json", json.dumps(manifest, indent=1).encode())
    return directory


def load_link_steps(directory: Path) -> dict[str, np.ndarray]:
    parts: dict[str, list] = {k: [] for k in ARRAYS}
    offset = 0
    for shard in sorted(Path(directory).glob("house_*.npz")):
        with np.load(shard) as z:
            if len(z["t"]):
                for k in ARRAYS:
                    parts[k].append(z[k] + offset if k == "episode" else z[k])
            offset += len(json.loads(str(z["episodes"])))
    return {k: np.concatenate(v) for k, v in parts.items()}


def link_metrics(model: MemoryLinks, data: dict, mu: float, delta: float) -> dict:
    """Val loss, and the hard handshake against the labels: the share of agent steps that
    ask, and the links' precision and recall."""
    sf, present = torch.from_numpy(data["sf"]), torch.from_numpy(data["present"])
    useful = torch.from_numpy(data["useful"])
    with torch.no_grad():
        t = model.rows(sf, present)
        loss = link_loss(t, target_rows(useful, present), present.float())
        links, _, _ = hard_links(t, present, mu, delta)
    hits = (links & useful).sum().item()
    return {"loss": float(loss), "asks": float(links.any(-1).sum() / present.sum()),
            "precision": hits / max(int(links.sum()), 1),
            "recall": hits / max(int(useful.sum()), 1),
            "useful_share": float(useful.any(-1).sum() / present.sum())}  # fmt: skip


def copy_pointer(cfg: MemoryConfig, setting: str) -> Path:
    """The pointer of ``links.pointer`` for ``setting``, checked, into the config's folder."""
    source = Path(cfg.links_settings()["pointer"]) / f"setting_{setting}"
    read(source, f"maniskill-tidy train {source.parent}.yaml --setting {setting}")
    folder = Path(cfg.out) / f"setting_{setting}"
    folder.mkdir(parents=True, exist_ok=True)
    had = folder / "card.json"
    card = json.loads(had.read_text()) if had.is_file() else {}
    if not (folder / "model.pt").is_file() or card.get("pointer_sha256") != weights_sha256(source):
        shutil.copyfile(source / "model.pt", folder / "model.pt.tmp")
        (folder / "model.pt.tmp").replace(folder / "model.pt")
        card = {"name": cfg.name, "pointer_from": str(source),
                "pointer_sha256": weights_sha256(source),
                "weights_sha256": weights_sha256(folder)}  # fmt: skip
        write_atomic(folder / "card.json", json.dumps(card, indent=1).encode())
    return source


def train_links(cfg: MemoryConfig, config: Path, setting: str, progress: bool = True) -> dict:
    """Copy the pointer, record, fit the links, validate; write the model and its card."""
    from maniskill_tidy.common.provenance import code_version
    from maniskill_tidy.training.memory_trainer import closed_loop

    s = cfg.links_settings()
    source = copy_pointer(cfg, setting)
    pointer = read(source, "")
    dirs = {split: build_link_data(config, setting, split, progress) for split in ("train", "val")}
    train, val = (load_link_steps(dirs[split]) for split in ("train", "val"))
    manifests = {k: json.loads((d / "manifest.json").read_text()) for k, d in dirs.items()}
    torch.manual_seed(s["seed"])
    sizes = {"features": len(SUMMARY), "hidden": s["hidden"], "key": s["key"]}
    model = MemoryLinks(**sizes)
    optimiser = torch.optim.Adam(model.parameters(), lr=s["lr"])
    sf, present = torch.from_numpy(train["sf"]), torch.from_numpy(train["present"])
    wanted = target_rows(torch.from_numpy(train["useful"]), present)
    best, best_state, best_epoch, curve, seconds = None, None, 0, [], 0.0
    bar = tqdm(range(s["epochs"]), desc=f"memory links {setting}", unit="epoch",
               disable=not progress)  # fmt: skip
    for epoch in bar:
        started = time.perf_counter()
        model.train()
        losses = []
        for idx in torch.randperm(len(sf)).split(s["batch"]):
            loss = link_loss(model.rows(sf[idx], present[idx]), wanted[idx],
                             present[idx].float())  # fmt: skip
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            losses.append(loss.item())
        model.eval()
        v = link_metrics(model, val, s["mu"], s["delta"])
        seconds += time.perf_counter() - started
        curve.append({"epoch": epoch + 1, "train_loss": float(np.mean(losses)), **{
            f"val_{k}": round(x, 4) for k, x in v.items()}})  # fmt: skip
        if best is None or v["loss"] < best["loss"]:
            best, best_state, best_epoch = v, copy.deepcopy(model.state_dict()), epoch + 1
        bar.set_postfix(val_loss=f"{v['loss']:.3f}", recall=f"{v['recall']:.2f}")
        if epoch + 1 - best_epoch >= s["patience"]:
            break
    model.load_state_dict(best_state)
    folder = Path(cfg.out) / f"setting_{setting}"
    links = {"sizes": sizes, "state": half_state(model)}
    save(folder, {**pointer, "name": cfg.name, "links": links}, {**pointer["sizes"], **s})
    card = {
        "name": cfg.name, "setting": setting, "config": str(config), "settings": asdict(cfg),
        "links": s, "pointer_from": str(source), "pointer_sha256": weights_sha256(source),
        "data": manifests, "epochs": len(curve), "best_epoch": best_epoch,
        "train_seconds": round(seconds, 1), "curve": curve, "val": best,
        "parameters": sum(p.numel() for p in model.parameters()),
        "weights_sha256": weights_sha256(folder),
    }  # fmt: skip
    write_atomic(folder / "card.json", json.dumps(card, indent=1).encode())
    card["closed_loop"] = closed_loop(cfg, config, setting, progress)
    card["code_version"] = code_version()
    write_atomic(folder / "card.json", json.dumps(card, indent=1).encode())
    write_atomic(folder / "MODEL_CARD.md", links_card(card).encode())
    plot_links_curve(card, folder / "curve.png")
    return card


def plot_links_curve(card: dict, out: Path) -> Path:
    """Loss, and the hard handshake's links against the val labels, per epoch."""
    import matplotlib.pyplot as plt

    from maniskill_tidy.common.plotting import save_figure

    curve = card["curve"]
    epochs = [c["epoch"] for c in curve]
    fig, (a, b) = plt.subplots(1, 2, figsize=(8, 3))
    a.plot(epochs, [c["train_loss"] for c in curve], label="train")
    a.plot(epochs, [c["val_loss"] for c in curve], label="val")
    a.set(xlabel="epoch", ylabel="cross-entropy", title="rows of T against the labels")
    a.legend()
    for key, label in (("val_precision", "precision"), ("val_recall", "recall"),
                       ("val_asks", "agent steps that ask")):  # fmt: skip
        b.plot(epochs, [c[key] for c in curve], label=label)
    b.axvline(card["best_epoch"], color="grey", ls=":")
    b.set(xlabel="epoch", ylim=(0, 1), title="val: the hard handshake's links")
    b.legend()
    fig.suptitle(f"{card['name']}, Setting {card['setting']}")
    return save_figure(fig, out, dpi=100)


def links_card(card: dict) -> str:
    v, loop, data = card["val"], card.get("closed_loop", {}), card["data"]
    lines = [
        f"# {card['name']}, Setting {card['setting']}: memory entries over HanGrCom links",
        "",
        "The object-memory team's pointer, copied unchanged from "
        f"`{card['pointer_from']}` (sha256 {card['pointer_sha256'][:12]}...), with learned "
        "query and key generators (`models/memory_links.py`) deciding who asks whom for "
        "memory entries (`policies/memory_links.py`). Stand-ins as for the object-memory "
        "team: ground-truth segmentation for the detector, D for the misplaced-object "
        "detector.",
        "",
        "## Data (played without messages; labels from every agent's memory, centralised)",
        "",
        "| split | steps | agent steps | share of agent steps with a useful teammate | "
        "data hash | seconds |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for split, m in data.items():
        lines.append(f"| {split} | {m['steps']} | {m['agent_steps']} | {m['useful_share']:.3f} "
                     f"| {m['data_hash'][:12]} | {m['seconds']:.0f} |")  # fmt: skip
    lines += [
        "",
        f"## Training: {card['epochs']} epochs, {card['train_seconds']:.1f} s, best epoch "
        f"{card['best_epoch']} (val loss), {card['parameters']} parameters",
        "",
        f"Val (hard handshake, mu {card['links']['mu']}, delta {card['links']['delta']}): "
        f"loss {v['loss']:.3f}; {v['asks']:.3f} of agent steps ask; link precision "
        f"{v['precision']:.3f}, recall {v['recall']:.3f} (useful teammate in "
        f"{v['useful_share']:.3f} of agent steps).",
    ]
    if loop:
        lines += ["", "## Closed loop, first val episodes", "",
                  "| team | episodes | Success | %PS | %FM | #PL | ACm |",
                  "| --- | --- | --- | --- | --- | --- | --- |"]  # fmt: skip
        for who, m in loop.items():
            lines.append(f"| {who} | {m['episodes']} | {m['Success']:.3f} | {m['%PS']:.3f} | "
                         f"{m['%FM']:.3f} | {m['#PL']:.1f} | {m['ACm']:.1f} |")  # fmt: skip
    lines += ["", f"Code version: {card.get('code_version', '?')}", ""]
    return "\n".join(lines)
