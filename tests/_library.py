"""A tiny trained model and dataset, made once per test process, and what tests build on them."""

from __future__ import annotations

import atexit
import functools
import shutil
import tempfile
from pathlib import Path

import pytest
import torch

from lookfeel.cli import main
from lookfeel.config import RunConfig, load_config
from lookfeel.index import build_library
from lookfeel.train import TrainResult, train

from ._tiny import write_tiny_dataset

TINY = Path(__file__).resolve().parents[1] / "configs" / "tiny.yaml"


@functools.cache
def tiny_run() -> tuple[Path, Path]:
    """(dataset, checkpoint): six fabrics, the tiny config trained for 20 steps (~2 s).

    Shared read-only by every test of the process; copy before modifying either.
    """
    root = Path(tempfile.mkdtemp(prefix="lookfeel-library-"))
    atexit.register(shutil.rmtree, root, ignore_errors=True)
    data = write_tiny_dataset(root / "data", fabrics=6, drapes=3, fold_presses=3, flat_presses=1)
    config = load_config(RunConfig, TINY, ["train.val_every=0", "train.checkpoint_every=0"])
    return data, train_one_thread(config, data, root / "run").last_checkpoint


def train_one_thread(config: RunConfig, data: Path, out: Path) -> TrainResult:
    """`train` on one thread. One thread trains a tiny model as fast as two, and on a CPU
    shared with other jobs far faster (two OpenMP threads spin waiting for each other: 2 s
    becomes 30 s or more)."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        return train(config, data, out)
    finally:
        torch.set_num_threads(threads)


def tiny_library(tmp_path_factory: pytest.TempPathFactory, name: str, shard_size: int) -> Path:
    """A library of `tiny_run`'s dataset under its model, in a fresh temporary folder ``name``."""
    data, ckpt = tiny_run()
    out = tmp_path_factory.mktemp(name) / "lib"
    build_library(ckpt, data, out, shard_size=shard_size)
    return out


def evaluate_cli(ckpt: Path, data: Path, out: Path | str, *extra: str) -> int:
    """``lookfeel evaluate --checkpoint CKPT --data DATA --out OUT EXTRA...``: its exit status."""
    return main(
        ["evaluate", "--checkpoint", str(ckpt), "--data", str(data), "--out", str(out), *extra]
    )
