"""benchmarks/bench_train_layout.py: the two recipes it times, in the layout asked."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import pytest
import torch
from benchmarks import bench_train_layout as bench

from lookfeel.synth import generate


def test_the_configs_are_the_two_recipes_in_the_layout_asked() -> None:
    demo, full = bench._config("demo", False), bench._config("full", True)
    assert (demo.model.width, demo.data.color_size, demo.train.channels_last) == (16, None, False)
    assert (full.model.width, full.data.color_size, full.train.channels_last) == (32, 96, True)
    assert demo.data.touch_frames == full.data.touch_frames == (0, 1, 2)
    assert demo.train.steps == bench.STEPS["demo"] and full.train.steps == bench.STEPS["full"]


def test_the_world_holds_the_renders_both_recipes_read() -> None:
    cfg = bench.world_config(6)
    assert cfg.reprints == bench._config("full", True).data.color_reprints == 4
    assert bench._config("demo", True).data.color_reprints == 1 <= cfg.reprints


def test_a_timed_run_trains_in_its_layout(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    world = tmp_path / "world"
    generate(replace(bench.world_config(6), workers=1), world, progress=False)
    monkeypatch.setattr(bench, "STEPS", {"demo": bench.WARMUP + 3, "full": bench.WARMUP + 3})
    runs = [("demo", True), ("demo", False), ("full", True)]
    for recipe, channels_last in runs:
        out = tmp_path / f"run-{recipe}-{channels_last}"
        rate, loss = bench._timed_run(bench._config(recipe, channels_last), world, out)
        assert rate > 0 and math.isfinite(loss)
        weights = torch.load(out / "checkpoints" / "last.pt", weights_only=True)["model"]
        conv = next(v for v in weights.values() if v.dim() == 4 and v.shape[1] > 1)
        assert conv.is_contiguous(memory_format=torch.channels_last) is channels_last
