from pathlib import Path

import pytest

from maniskill_tidy.tasks.dataset import generate_dataset

REFERENCE = Path(__file__).resolve().parents[2] / "shared" / "reference"
DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="session")
def small_dataset(tmp_path_factory) -> Path:
    """12 houses (8/2/2), seed 3: shared by tests that only read it."""
    out = tmp_path_factory.mktemp("ds") / "small"
    generate_dataset(out, 12, seed=3, progress=False)
    return out
