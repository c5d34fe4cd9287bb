"""benchmarks/bench_train_layout.py: the two recipes it times, in the layout asked."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import pytest
import torch
from benchmarks import bench_train_layout as bench

from lookfeel.demo import demo_world
from lookfeel.synth import generate


def test_the_configs_are_the_two_recipes_in_the_layout_asked() -> None:
    demo, full = bench._config("demo", False), bench._config("full", True)
    assert (demo.model.width, demo.data.color_size, demo.train.channels_last) == (16, None, False)
    assert (full.model.width, full.data.color_size, full.train.channels_last) == (32, 96, True)
    assert demo.train.steps == bench.STEPS["demo"] and full.train.steps == bench.STEPS["full"]


def test_a_timed_run_trains_in_its_layout(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    world = tmp_path / "world"
    generate(replace(demo_world(6, seed=0), workers=1), world, progress=False)
    monkeypatch.setattr(bench, "STEPS", {"demo": bench.WARMUP + 3, "full": bench.WARMUP + 3})
    for channels_last in (True, False):
        out = tmp_path / f"run-{channels_last}"
        rate, loss = bench._timed_run(bench._config("demo", channels_last), world, out)
        assert rate > 0 and math.isfinite(loss)
        weights = torch.load(out / "checkpoints" / "last.pt", weights_only=True)["model"]
        conv = next(v for v in weights.values() if v.dim() == 4 and v.shape[1] > 1)
        assert conv.is_contiguous(memory_format=torch.channels_last) is channels_last
