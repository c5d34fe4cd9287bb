"""Shared test set-up: two threads, seeded RNGs, tiny configs and tiny datasets on tmp_path."""

from __future__ import annotations

import hashlib
import random
from pathlib import Path

import numpy as np
import pytest
import torch

from lookfeel.config import DataConfig

from ._library import tiny_run
from ._tiny import write_tiny_dataset

torch.set_num_threads(2)

REAL_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "gelfabric"


@pytest.fixture(autouse=True)
def _seeded() -> None:
    random.seed(0)
    np.random.seed(0)
    torch.manual_seed(0)


@pytest.fixture
def tiny_config() -> DataConfig:
    """16-px images, two decoding threads: fast enough for unit tests."""
    return DataConfig(image_size=16, workers=2)


@pytest.fixture
def tiny_dataset(tmp_path: Path) -> Path:
    """Six fabrics with depth, colour and touch (fold and flat presses) and labels.csv."""
    return write_tiny_dataset(tmp_path / "tiny")


@pytest.fixture(scope="session")
def run() -> tuple[Path, Path]:
    """(dataset, checkpoint) of `tests._library.tiny_run`, shared read-only by every test."""
    return tiny_run()


@pytest.fixture(scope="session")
def leaky_depth(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Rendered drapes whose room identifies the fabric (a planted capture-session leak): 6
    fabrics x 3 drapes at 32 px (`tests._scene.write_scene_dataset`), shared read-only."""
    from ._scene import write_scene_dataset

    return write_scene_dataset(tmp_path_factory.mktemp("leaky") / "data", 6, 3, 32, 20.0, 0.3)


@pytest.fixture
def real_data() -> Path:
    """The shared real GelFabric depth data; the test skips when it is absent."""
    if not (REAL_DATA / "depth").is_dir():
        pytest.skip(f"real GelFabric data not found at {REAL_DATA}")
    return REAL_DATA


def tree_digest(root: Path) -> dict[str, str]:
    """Path -> sha1 of every file under root (to prove nothing was modified)."""
    return {
        str(p.relative_to(root)): hashlib.sha1(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*"))
        if p.is_file()
    }
