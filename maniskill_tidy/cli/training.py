"""Commands that make demonstrations and train the learned models."""

from __future__ import annotations

import argparse
from pathlib import Path

from maniskill_tidy.cli.options import env_option, ray_option

TRAIN_DEFAULTS = {"dataset": "data/tidy120", "out": None, "work": None, "seed": 0,
                  "workers": 2, "env": None, "visual_widths": None,
                  "scene_widths": None}  # fmt: skip
# `train perception`'s folders by look: v1's are the shipped perception the learned teams read
PERCEPTION_FOLDERS = {"HeteroTidy-v1": ("agents/perception", "data/perception"),
                      "HeteroTidy-v2": ("agents/perception-v2", "data/perception-v2")}  # fmt: skip


def widths(option: str, text: str | None, count: int = 4) -> dict:
    """``--visual-widths 16,32,48,64`` as TrainConfig's field (nothing: the shipped widths)."""
    if text is None:
        return {}
    try:
        values = tuple(int(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != count or min(values) < 1:
        example = ",".join(str(16 * (i + 1)) for i in range(count))
        words = {4: "four", 5: "five"}.get(count, str(count))
        raise ValueError(f"--{option} {text!r}: expected {words} positive channel counts, e.g. "
                         f"{example}")  # fmt: skip
    return {option.replace("-", "_"): values}


def _demos(args: argparse.Namespace) -> int:
    from maniskill_tidy.envs.registration import DEFAULT_ENV

    if args.features:
        from maniskill_tidy.policies.agent_config import AgentConfig, perception_look
        from maniskill_tidy.training.decision_data import DemoConfig, build_demo_features

        # features are the learned perception's: rendered in the look it was trained on
        args.env = args.env or perception_look(AgentConfig.perception)

        out = Path(args.out or "data/demos")
        cfg = DemoConfig(args.setting, args.split, args.starts, args.tasks_per_house,
                         args.houses, args.seed, args.teacher, args.student, args.env)  # fmt: skip
        m = build_demo_features(out, args.dataset, cfg, workers=args.workers, ray=args.ray)
        folder = out / f"setting_{args.setting}" / args.split
        print(
            f"{m['trajectories']} trajectories ({m['rows']} agent-steps, "
            f"{m['bytes'] / 1e6:.0f} MB, {cfg.student or cfg.teacher} success "
            f"{m['teacher_success']:.3f}) "
            f"in {folder}"
        )
        return 0
    if args.ray:
        raise ValueError("--ray spreads the rendering of --features; add --features")
    from maniskill_tidy.training.demonstrations import write_demonstrations

    args.out = args.out or "data/trajectories"
    args.env = args.env or DEFAULT_ENV
    m = write_demonstrations(
        Path(args.out), args.dataset, args.split, args.setting, tasks=args.tasks, seed=args.seed,
        env_id=args.env,
    )  # fmt: skip
    print(
        f"wrote {m['trajectories']} trajectories ({m['steps']} steps, expert success "
        f"{m['expert_success']:.3f}) to {Path(args.out) / f'setting_{args.setting}' / args.split}"
    )
    return 0


def _segmenter_data(args: argparse.Namespace) -> int:
    from maniskill_tidy.training.segmenter_data import SegDataConfig, build_segmenter_data

    if args.every < 1 or args.max_steps < 1:
        raise ValueError(f"--every {args.every}, --max-steps {args.max_steps}: expected >= 1")
    for split in args.splits.split(","):
        if split not in ("train", "val", "test"):
            raise ValueError(f"--splits {args.splits!r}: expected train, val and/or test")
        cfg = SegDataConfig(args.dataset, split, args.env, args.every, args.max_steps,
                            args.houses)  # fmt: skip
        m = build_segmenter_data(cfg, Path(args.out) / split, workers=args.workers)
        print(
            f"{split}: {m['frames']} frames of {m['houses_done']} houses in "
            f"{Path(args.out) / split} (data hash {m['data_hash'][:12]}, {m['seconds']:.0f} s)"
        )
    return 0


def _train_segmenter(args: argparse.Namespace) -> int:
    from maniskill_tidy.training.segmenter_trainer import SegTrainConfig, rescore, train_segmenter

    if args.rescore:
        card = rescore(args.out, args.data)
        v, t = card["val"], card["test"]
        print(f"{args.out}: scored again: val mask AP50 {v['AP50']:.3f}; test mask AP "
              f"{t['AP']:.3f}, AP50 {t['AP50']:.3f}; agent threshold "
              f"{card['agent_threshold']['threshold']:.3f}")  # fmt: skip
        return 0
    if not 0 <= args.weight_power <= 1:
        raise ValueError(f"--weight-power {args.weight_power}: expected 0 (unweighted) to 1")
    if args.objectness < 0:
        raise ValueError(f"--objectness {args.objectness}: expected 0 (none) or a positive weight")
    if not 0 <= args.focus <= 1:
        raise ValueError(f"--focus {args.focus}: expected a share of the crops, 0 to 1")
    if not 1 <= args.zoom <= 4:
        raise ValueError(f"--zoom {args.zoom}: expected 1 (none) to 4")
    if args.stem < 0 or args.head < 0:
        raise ValueError(f"--stem {args.stem}, --head {args.head}: expected 0 (none) or a "
                         "number of channels")  # fmt: skip
    if not 0 < args.lr <= 0.1:
        raise ValueError(f"--lr {args.lr}: expected a learning rate in (0, 0.1]")
    if args.init and not (Path(args.init) / "card.json").is_file():
        raise FileNotFoundError(f"--init {args.init}: no card.json; expected a segmenter "
                                "trained by `maniskill-tidy train-segmenter`")  # fmt: skip
    if args.epochs < 1 or args.batch < 1 or not 16 <= args.crop <= 224 or args.crop % 2:
        raise ValueError(f"--epochs {args.epochs}, --batch {args.batch}, --crop {args.crop}: "
                         "expected at least 1, at least 1, an even size in 16..224")  # fmt: skip
    extra = widths("widths", args.widths, count=5) if args.widths else {}
    cfg = SegTrainConfig(args.data, args.out, epochs=args.epochs, batch=args.batch,
                         crop=args.crop, seed=args.seed, stem=args.stem, head=args.head,
                         zoom=args.zoom, relief=args.relief, focus=args.focus,
                         weight_power=args.weight_power, lr=args.lr, init=args.init,
                         objectness=args.objectness, extra=tuple(args.extra), **extra)  # fmt: skip
    card = train_segmenter(cfg)
    t, v = card["test"], card["val"]
    print(f"{args.out}: best epoch {card['best_epoch']} of {args.epochs} "
          f"({card['train_seconds']:.0f} s); val mask AP50 {v['AP50']:.3f}; test mask AP "
          f"{t['AP']:.3f}, AP50 {t['AP50']:.3f} over {t['truth']} pickupable objects")  # fmt: skip
    return 0


def _quantize_segmenter(args: argparse.Namespace) -> int:
    from maniskill_tidy.training.segmenter_trainer import quantize

    card = quantize(args.segmenter, args.data)
    v, t, f = card["val"], card["test"], card["int8"]["fp16_torch"]
    print(f"{args.segmenter}/{card['int8']['file']} (sha256 {card['int8']['sha256'][:12]}): val "
          f"mask AP50 {v['AP50']:.3f} (fp16 torch {f['val']['AP50']:.3f}); test AP "
          f"{t['AP']:.3f}, AP50 {t['AP50']:.3f} (fp16 torch {f['test']['AP50']:.3f}); agent "
          f"threshold {card['agent_threshold']['threshold']:.3f}")  # fmt: skip
    return 0


def _segmenter_cross_look(args: argparse.Namespace) -> int:
    from maniskill_tidy.common.agent_files import resolve
    from maniskill_tidy.training.segmenter_cross_look import cross_look, write_table

    rows = cross_look([resolve(s) for s in args.segmenters], Path(args.data), args.split)
    js, md = write_table(rows, Path(args.out))
    print(md.read_text(), end="")
    print(f"wrote {js} and {md}")
    return 0


def _train(args: argparse.Namespace) -> int:
    from maniskill_tidy.policies.agent_config import trainer_of
    from maniskill_tidy.training.qmix_trainer import train_qmix

    if args.what != "perception":  # an agent config says where its model goes: eval reads it
        given = [f"--{k.replace('_', '-')}" for k in TRAIN_DEFAULTS if getattr(args, k) is not None]
        if given:
            raise ValueError(
                f"{' '.join(given)} apply to `train perception`; an agent config sets them "
                f"itself (out, dataset, work, workers, train.seed): write a config with "
                f"`base: {args.what}` and the values to change"
            )
    for key, default in TRAIN_DEFAULTS.items():
        if getattr(args, key) is None:
            setattr(args, key, default)
    if args.what == "perception":
        from maniskill_tidy.envs.registration import DEFAULT_ENV

        args.env = args.env or DEFAULT_ENV
        out, work = PERCEPTION_FOLDERS[args.env]
        args.out, args.work = args.out or out, args.work or work
    if trainer_of(Path(args.what)) == "memory":
        from maniskill_tidy.training.memory_trainer import train_memory

        card = train_memory(Path(args.what), args.setting)
        loop = card.get("closed_loop", {})
        if "links" in card:
            v = card["val"]
            print(f"{card['name']} Setting {args.setting}: links' val loss {v['loss']:.3f}, "
                  f"precision {v['precision']:.3f}, recall {v['recall']:.3f} (best epoch "
                  f"{card['best_epoch']}); closed loop on val, Success "
                  + ", ".join(f"{who} {m['Success']:.3f}" for who, m in loop.items()))  # fmt: skip
            return 0
        print(
            f"{card['name']} Setting {args.setting}: val accuracy {card['val']['balanced']:.3f} "
            "(mean over kinds of choice) "
            f"(best epoch {card['best_epoch']}); closed loop on val, Success "
            + ", ".join(f"{who} {m['Success']:.3f}" for who, m in loop.items())
        )
        return 0
    if trainer_of(Path(args.what)) == "qmix":
        card = train_qmix(Path(args.what), args.setting)
        print(
            f"{card['name']} Setting {args.setting}: {card['episodes']} episodes, "
            f"{card['env_steps']} env steps in {card['train_seconds']:.0f} s; val success "
            f"{card['val'].get('success', float('nan')):.2f}"
        )
        return 0
    if args.what != "perception":
        from maniskill_tidy.training.decision_trainer import train_decision

        card = train_decision(Path(args.what), args.setting)
        acc = card["val_inference_mode"]["accuracy"]
        print(
            f"{card['name']} Setting {args.setting}: trained in {card['train_seconds']:.0f} s "
            f"(best epoch {card['best_epoch']}); val accuracy "
            + ", ".join(f"{h} {a:.3f}" for h, a in acc.items() if a is not None)
        )
        return 0
    from maniskill_tidy.tasks.dataset import read_manifest
    from maniskill_tidy.training.perception_trainer import TrainConfig, train_perception

    cfg = TrainConfig(
        seed=args.seed, env=args.env, **widths("visual-widths", args.visual_widths),
        **widths("scene-widths", args.scene_widths),
    )  # fmt: skip
    read_manifest(Path(args.dataset))  # a one-line error if it is not a dataset
    cards = train_perception(
        Path(args.dataset), Path(args.out), Path(args.work), cfg, workers=args.workers
    )
    for variant, card in cards.items():
        val = card["val"]
        print(
            f"{args.out}/{variant}: trained in {card['train_seconds']:.0f} s; val room accuracy "
            f"{val['room']['accuracy']:.3f}, detector F1 {val['detector']['f1']:.3f}, "
            f"receptacle top-1 {val['receptacle']['top1_reasonable_in_house']:.3f}"
        )
    return 0


def _perception_report(args: argparse.Namespace) -> int:
    from maniskill_tidy.training.perception_report import beside, report

    print(report(Path(args.agents), Path(args.dataset), args.split, Path(args.work), args.workers))
    if args.beside:
        print(beside(Path(args.agents), [Path(a) for a in args.beside], args.split))
    return 0


def add_commands(sub: argparse._SubParsersAction) -> None:
    dm = sub.add_parser("demos", help="expert demonstrations (sub-tasks, sub-goals) for a split")
    dm.add_argument("--dataset", help="dataset directory (default: the env's shipped dataset)")
    dm.add_argument("--setting", default="I")
    dm.add_argument("--split", default="train", choices=("train", "val", "test"))
    dm.add_argument("--tasks", type=int, help="only the first N meta-tasks (5 starts each)")
    dm.add_argument("--seed", type=int, default=0)
    dm.add_argument("--out", help="default data/trajectories, or data/demos with --features")
    dm.add_argument(
        "--features", action="store_true",
        help="render every camera and store each agent's model inputs per step (for training)",
    )  # fmt: skip
    dm.add_argument("--starts", type=int, default=1, help="with --features: starts per meta-task")
    dm.add_argument("--tasks-per-house", type=int, help="with --features: meta-tasks per house")
    dm.add_argument("--houses", type=int, help="with --features: only the first N houses")
    dm.add_argument("--workers", type=int, default=2, help="with --features: rendering processes")
    ray_option(dm)
    dm.add_argument(
        "--teacher", default="expert",
        help="with --features: the team whose labels are imitated (expert or a heuristic-... team)",
    )  # fmt: skip
    dm.add_argument(
        "--student",
        help="with --features: DAgger; this team (a policy or agent config) plays and the "
        "teacher labels the states it reaches",
    )
    env_option(dm, by_team=True)
    dm.set_defaults(func=_demos)

    sd = sub.add_parser(
        "segmenter-data",
        help="frames with the renderer's masks and types, for the pixels track's segmenter",
    )
    sd.add_argument("--dataset", default="data/tidy120")
    sd.add_argument("--splits", default="train,val,test")
    sd.add_argument("--out", required=True, help="a folder per split is made in it")
    sd.add_argument("--every", type=int, default=6, help="keep frames every N env steps")
    sd.add_argument("--max-steps", type=int, default=120, help="steps played per episode")
    sd.add_argument("--houses", type=int, help="only the first N houses of each split")
    sd.add_argument("--workers", type=int, default=2)
    env_option(sd)
    sd.set_defaults(func=_segmenter_data)

    ts = sub.add_parser(
        "train-segmenter", help="the pixels track's segmenter, on segmenter-data's frames (CPU)"
    )
    ts.add_argument("--data", required=True, help="segmenter-data's folder (train/, val/, test/)")
    ts.add_argument("--out", required=True, help="e.g. agents/segmenter-v2")
    ts.add_argument("--epochs", type=int, default=16)
    ts.add_argument("--batch", type=int, default=16)
    ts.add_argument("--crop", type=int, default=128, help="training crops, px (frames are 224)")
    ts.add_argument("--widths", help="channels of the five levels (24,32,32,48,64)")
    ts.add_argument("--seed", type=int, default=0)
    ts.add_argument("--stem", type=int, default=0,
                    help="channels of a full-resolution convolution before the first stride "
                    "(0: none)")  # fmt: skip
    ts.add_argument(
        "--zoom",
        type=float,
        default=1.0,
        help="half the training crops blown up by up to this factor (1: none)",
    )
    ts.add_argument(
        "--head",
        type=int,
        default=0,
        help="channels of a hidden 1 x 1 layer before the class logits (0: none)",
    )
    ts.add_argument(
        "--focus",
        type=float,
        default=0.5,
        help="share of the training crops centred on a pickupable object",
    )
    ts.add_argument("--relief", action="store_true",
                    help="the depth's local relief (depth less its mean around) as input "
                    "channels beside RGB-D")  # fmt: skip
    ts.add_argument("--weight-power", type=float, default=0.75,
                    help="class weights 1 / frequency ** this (0: unweighted)")  # fmt: skip
    ts.add_argument("--objectness", type=float, default=0.0,
                    help="weight of a Dice loss on which pixels are pickupable objects beside "
                    "the cross-entropy (0: none)")  # fmt: skip
    ts.add_argument("--lr", type=float, default=2e-3, help="peak learning rate (one cycle)")
    ts.add_argument("--init", help="a trained segmenter's folder whose weights start this run "
                    "(same widths, stem, head and relief)")  # fmt: skip
    ts.add_argument("--extra", nargs="+", default=[], metavar="FRAMES",
                    help="more train frames: segmenter-data folders rendered from the houses of "
                    "a dataset generated with another seed (e.g. `segmenter-data --splits train "
                    "--out data/segmenter-extra/HeteroTidy-v2`'s train/)")  # fmt: skip
    ts.add_argument("--rescore", action="store_true",
                    help="score the trained segmenter in --out again on --data's val and test "
                    "frames (its card's val, test and agent threshold)")  # fmt: skip
    ts.set_defaults(func=_train_segmenter)

    qs = sub.add_parser(
        "quantize-segmenter",
        help="the int8 graph agents run beside a trained segmenter (train-segmenter makes it "
        "too), its card scored through it",
    )  # fmt: skip
    qs.add_argument("--segmenter", required=True,
                    help="a trained segmenter, e.g. agents/segmenter-v2")  # fmt: skip
    qs.add_argument("--data", required=True,
                    help="the segmenter-data folder it was trained on (val calibrates and "
                    "selects, test reports)")  # fmt: skip
    qs.set_defaults(func=_quantize_segmenter)

    cl = sub.add_parser(
        "segmenter-cross-look",
        help="every segmenter scored on every look's test frames (the cross-look table)",
    )
    cl.add_argument(
        "--segmenters", nargs="+", default=["agents/segmenter-v1", "agents/segmenter-v2"]
    )
    cl.add_argument("--data", default="data/segmenter", help="segmenter-data's looks' folders")
    cl.add_argument("--split", default="test", choices=["val", "test"])
    cl.add_argument("--out", default="eval/segmenter_cross_look",
                    help="writes OUT.json and OUT.md")  # fmt: skip
    cl.set_defaults(func=_segmenter_cross_look)

    tr = sub.add_parser(
        "train", help="train learned modules: the paper's, QMIX, the object-memory team (CPU)"
    )
    tr.add_argument(
        "what", help="`perception`, or an agent config (agents/hangrcom.yaml, agents/memory.yaml)"
    )
    tr.add_argument("--setting", default="I", help="with an agent config: I or II")
    tr.add_argument("--dataset", help="perception: dataset directory (data/tidy120)")
    tr.add_argument(
        "--out",
        help="perception: agent folder to write (agents/perception-v2; in v1 the "
        "shipped agents/perception)",
    )
    tr.add_argument(
        "--work",
        help="perception: views and resumable checkpoints, not shipped "
        "(data/perception-v2; in v1 data/perception)",
    )
    tr.add_argument("--seed", type=int, help="perception: seed (0)")
    tr.add_argument(
        "--env",
        choices=("HeteroTidy-v1", "HeteroTidy-v2"),
        help="perception: the look the views are rendered in (HeteroTidy-v2; the learned "
        "teams read agents/perception, trained in HeteroTidy-v1)",
    )
    tr.add_argument("--workers", type=int, help="perception: processes rendering the views (2)")
    tr.add_argument(
        "--visual-widths",
        help="perception: channels of the visual encoder's four convolutions (32,64,96,128)",
    )
    tr.add_argument(
        "--scene-widths",
        help="perception: channels of the scene encoder's four convolutions (32,64,64,128)",
    )
    tr.set_defaults(func=_train)

    pr = sub.add_parser(
        "perception-report", help="perception figures of the shipped checkpoints, and a PNG"
    )
    pr.add_argument("--agents", default="agents/perception", help="agent folder")
    pr.add_argument("--dataset", default="data/tidy120", help="dataset the agents were trained on")
    pr.add_argument("--split", default="test", choices=("val", "test"))
    pr.add_argument("--work", default="data/perception", help="where the split's views are kept")
    pr.add_argument("--workers", type=int, default=2)
    pr.add_argument(
        "--beside", action="append", metavar="AGENTS",
        help="also a table of the figures of these agent folders (their own reports) beside "
        "these (repeatable): v1's perception beside v2's",
    )  # fmt: skip
    pr.set_defaults(func=_perception_report)
