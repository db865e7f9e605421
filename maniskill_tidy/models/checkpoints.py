"""Saving and loading trained models: the decision team, the perception model, QMIX, the
object-memory pointer and the pixels track's segmenter (its weights and the int8 graph agents run).

Training writes these files, evaluation reads them; both sides import this module, so a team
never reaches up into ``training/`` to load its weights. Weights are stored in fp16 next to
their config; loading returns float32 modules in eval mode.

A checkpoint is checked before it is used: ``card.json`` beside ``model.pt`` records the
file's sha256 (``weights_sha256``), and a file that does not match it, or that torch cannot
read, is refused in one line (:class:`CheckpointError`) before anything is written.
"""

from __future__ import annotations

import hashlib
import io
import json
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import torch

from maniskill_tidy.common.agent_files import WHERE
from maniskill_tidy.common.files import file_sha256, write_atomic
from maniskill_tidy.knowledge import load_catalog
from maniskill_tidy.knowledge.word_vectors import load_word_vectors
from maniskill_tidy.models.decision import DecisionConfig, TeamDecision
from maniskill_tidy.models.memory_pointer import MemoryPointer
from maniskill_tidy.models.qmix import QmixTeamModel

if TYPE_CHECKING:
    from maniskill_tidy.models.perception import PerceptionModel
    from maniskill_tidy.models.segmenter import Segmenter

WEIGHTS = "model.pt"
CARD = "card.json"
INT8 = "model.int8.onnx"  # a segmenter's graph as agents run it (``models/segmenter.py``)


class CheckpointError(ValueError):
    """A checkpoint that is missing, unreadable or not the one its card describes."""


def half_state(model: torch.nn.Module) -> dict:
    """The weights as they ship: floating tensors rounded to fp16."""
    return {k: (v.half() if v.is_floating_point() else v) for k, v in model.state_dict().items()}


def float_state(state: dict) -> dict:
    return {k: (v.float() if v.is_floating_point() else v) for k, v in state.items()}


def save(folder: Path, payload: dict, config: dict | None = None) -> None:
    """``payload`` (with its fp16 ``state``) as ``model.pt``, and ``config`` as config.json,
    atomically."""
    folder = Path(folder)
    buf = io.BytesIO()
    torch.save(payload, buf)
    write_atomic(folder / WEIGHTS, buf.getvalue())
    if config is not None:
        write_atomic(folder / "config.json", json.dumps(config, indent=1).encode())


def weights_digest(*folders: Path) -> str:
    """A fingerprint of the weights in ``folders``' ``model.pt`` files (16 hex digits): the
    tensors, not the files, so that a retraining that reproduces them keeps it. Eval runs record
    it and refuse to resume with other weights."""
    return state_digest(torch.load(Path(f) / WEIGHTS, weights_only=False)["state"] for f in folders)


def state_digest(states) -> str:
    """The fingerprint of :func:`weights_digest` over state dicts (16 hex digits)."""
    digest = hashlib.sha256()
    for state in states:
        for key in sorted(state):
            digest.update(key.encode())
            digest.update(state[key].detach().cpu().contiguous().numpy().tobytes())
    return digest.hexdigest()[:16]


def weights_sha256(folder: Path) -> str:
    """What a card records of the weights it describes."""
    return file_sha256(Path(folder) / WEIGHTS)


def _commands(hints: tuple[str, ...]) -> str:
    """One line naming every command a user may run instead ("`a`", "`a` (or `b`)"),
    whichever of them the caller's checkpoint comes from."""
    first, *others = hints
    return f"`{first}`" + "".join(f" (or `{o}`)" for o in others)


def verify(folder: Path, train_hint: str, *others: str) -> None:
    """Refuse a missing, damaged or substituted ``model.pt`` in one line, before any work;
    ``train_hint``: the command that trains it, ``others``: any other that also does."""
    path = Path(folder) / WEIGHTS
    train_hints = (train_hint, *others)
    hint_text = _commands(train_hints)
    if not path.is_file():
        raise CheckpointError(f"{path} not found ({WHERE}); train it with {hint_text}")
    card = Path(folder) / CARD
    expected = json.loads(card.read_text()).get("weights_sha256") if card.is_file() else None
    if expected is None:  # no card to compare with: at least torch must read it
        _load(path, *train_hints)
    elif file_sha256(path) != expected:
        raise CheckpointError(
            f"{path}: sha256 differs from its card ({card.name} weights_sha256 "
            f"{expected[:12]}...): the file is damaged or not the trained one; retrain with "
            f"{hint_text} or restore it"
        )


def _load(path: Path, *train_hints: str) -> dict:
    try:
        return torch.load(path, weights_only=False)
    except Exception as err:  # torch raises several kinds for a damaged zip
        raise CheckpointError(
            f"{path}: not a readable checkpoint ({type(err).__name__}); expected a file "
            f"written by {_commands(train_hints)}"
        ) from None


def read(folder: Path, train_hint: str, *others: str) -> dict:
    """The saved payload, after checking the file against its card (hints as :func:`verify`'s)."""
    verify(folder, train_hint, *others)
    return _load(Path(folder) / WEIGHTS, train_hint, *others)


def for_agents(model: torch.nn.Module) -> torch.nn.Module:
    """``model`` with its convolution weights stored channels-last, for a team's batch-of-one
    steps. Their inputs are already channels-last (permuted from H x W x C), so oneDNN takes
    the same kernel either way; with matching weights it no longer reorders them on every call
    (about 0.15 ms per encoder call, ``docs/research/probes/team_split.py``; the same bits:
    ``tests/test_perception_models.py``)."""
    return model.to(memory_format=torch.channels_last)


# ----------------------------------------------------------------- the decision team
def save_decision(model: TeamDecision, folder: Path, extra: dict) -> None:
    payload = {"config": asdict(model.cfg), "agents": len(model.agents), "state": half_state(model)}
    payload |= extra
    save(folder, payload, payload | {"state": None})


def load_decision(folder: Path) -> tuple[TeamDecision, dict]:
    """A trained team model and what was saved with it."""
    saved = read(folder, "maniskill-tidy train CONFIG --setting S")
    model = TeamDecision(DecisionConfig(**saved["config"]), saved["agents"])
    model.load_state_dict(float_state(saved["state"]))
    return model.eval(), saved


# ----------------------------------------------------------------------- perception
def type_vectors() -> torch.Tensor:
    """(K, word dim): the GloVe vectors of the catalog's categories, in channel order."""
    vectors = load_word_vectors()
    return torch.from_numpy(np.stack([vectors[c] for c in load_catalog().categories]))


def save_perception(model: PerceptionModel, folder: Path) -> None:
    payload = {"config": asdict(model.cfg), "nodes": list(model.nodes), "state": half_state(model)}
    save(folder, payload, asdict(model.cfg))


def load_perception(folder: Path) -> PerceptionModel:
    """A trained perception model, ready for inference; its knowledge graph is rebuilt from
    the saved GCN buffers, so the train houses are not needed."""
    # here, not at the top: the perception model pulls in torch_geometric (seconds), which
    # every team that imports this module would pay for, scripted ones included
    from maniskill_tidy.models.knowledge_graph import KnowledgeGraph
    from maniskill_tidy.models.perception import PerceptionConfig, PerceptionModel

    # the shipped perception is v1's; the command's default look is v2
    saved = read(folder, "maniskill-tidy train perception --env HeteroTidy-v1", "make train")
    state = saved["state"]
    graph = KnowledgeGraph(
        tuple(saved["nodes"]),
        state["gcn.edge_index"],
        state["gcn.edge_weight"].float(),
        state["gcn.features"].float(),
    )
    model = PerceptionModel(PerceptionConfig(**saved["config"]), type_vectors(), graph)
    model.load_state_dict(float_state(state))
    return model.eval()


# ----------------------------------------------------------------------------- QMIX
def save_qmix(model: QmixTeamModel, folder: Path, extra: dict) -> None:
    save(folder, {"agents": model.n, "feature": model.feature, "state": half_state(model), **extra})


def load_qmix(folder: Path) -> tuple[QmixTeamModel, dict]:
    saved = read(folder, "maniskill-tidy train agents/qmix.yaml --setting S")
    model = QmixTeamModel(saved["agents"], saved["feature"])
    model.load_state_dict(float_state(saved["state"]))
    return model.eval(), saved


def save_memory(model: MemoryPointer, folder: Path, sizes: dict, extra: dict) -> None:
    """``sizes``: the pointer's constructor arguments (kinds, receptacles, numeric, context,
    dim, heads), so that loading needs nothing else."""
    save(folder, {"sizes": sizes, "state": half_state(model), **extra}, sizes)


def load_memory(folder: Path) -> tuple[MemoryPointer, dict]:
    saved = read(folder, "maniskill-tidy train agents/memory.yaml --setting S")
    return memory_pointer(saved), saved


def memory_pointer(saved: dict) -> MemoryPointer:
    """The pointer of a saved payload (``sizes`` and fp16 ``state``), in eval mode."""
    model = MemoryPointer(type_vectors(), **saved["sizes"])
    model.load_state_dict(float_state(saved["state"]))
    return model.eval()


def save_segmenter(model, folder: Path) -> None:
    save(folder, {"config": model.config(), "state": half_state(model)})


def load_segmenter(folder: Path) -> tuple[Segmenter, dict]:
    """The pixels track's segmenter (``models/segmenter.py``, in eval mode) and its card
    (``{}`` without one); refused in one line when the card names another class table than
    this code's (the object types changed since it was trained)."""
    from maniskill_tidy.models.segmenter import Segmenter
    from maniskill_tidy.perception.seg_classes import seg_classes

    saved = read(folder, "maniskill-tidy train-segmenter")
    card_path = Path(folder) / CARD
    card = json.loads(card_path.read_text()) if card_path.is_file() else {}
    digest, ours = card.get("config", {}).get("classes"), seg_classes().digest
    if digest is not None and digest != ours:
        raise CheckpointError(f"{folder}: trained on another class table ({digest}, this code's "
                              f"is {ours}): the object types changed; render and train it again "
                              "(make segmenter-data train-segmenter)")  # fmt: skip
    cfg = saved["config"]
    model = Segmenter(cfg["classes"], tuple(cfg["widths"]), cfg.get("stem", 0), cfg.get("head", 0),
                      cfg.get("relief", False))  # fmt: skip
    model.load_state_dict(float_state(saved["state"]))
    return model.eval(), card


def save_segmenter_int8(folder: Path, graph: bytes) -> str:
    """The int8 graph agents run beside the weights (atomically); its sha256, for the card."""
    write_atomic(Path(folder) / INT8, graph)
    return file_sha256(Path(folder) / INT8)


def served_sha256(folder: Path) -> str:
    """The sha256 a pixels run records of what its agents run, after checking the files: the
    int8 graph's when the card names one (``int8.sha256``), else the weights'."""
    verify(folder, "make train-segmenter")
    card_path = Path(folder) / CARD
    int8 = json.loads(card_path.read_text()).get("int8") if card_path.is_file() else None
    if not int8:
        return weights_sha256(folder)
    path = Path(folder) / INT8
    if not path.is_file() or file_sha256(path) != int8["sha256"]:
        state = "missing" if not path.is_file() else "sha256 differs from its card's int8.sha256"
        raise CheckpointError(f"{path}: {state}; make it again with `maniskill-tidy "
                              f"quantize-segmenter --segmenter {folder}`")  # fmt: skip
    return int8["sha256"]


def served_segmenter(folder: Path, threads: int = 1):
    """What agents run of a segmenter (:class:`models.segmenter.Runtime` on ``threads``), the
    sha256 its runs record (:func:`served_sha256`) and its card: the int8 graph the card names,
    else the fp16 weights exported as they load."""
    from maniskill_tidy.models.segmenter import Runtime

    sha = served_sha256(folder)
    model, card = load_segmenter(folder)
    if card.get("int8"):
        return Runtime((Path(folder) / INT8).read_bytes(), threads), sha, card
    return Runtime(model, threads), sha, card
