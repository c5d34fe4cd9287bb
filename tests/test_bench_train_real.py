"""benchmarks/bench_train_real.py: each recipe trained as a user starts it, or skipped."""

from __future__ import annotations

from pathlib import Path

import pytest
from benchmarks import bench_train_real as bench

from lookfeel.config import RunConfig, load_config
from lookfeel.config.recipes import recipe_path


def test_the_recipes_and_their_targets_are_the_issues() -> None:
    assert bench.RECIPES["real_depth"][:2] == ("real_depth.yaml", 300.0)  # issue 12: 5 minutes
    assert bench.RECIPES["physiclear"][:2] == ("physiclear.yaml", 600.0)  # issue 13: 10 minutes
    for file, _, _ in bench.RECIPES.values():
        load_config(RunConfig, recipe_path(file))  # each is a shipped config that loads


def test_a_recipe_is_timed_in_a_fresh_run_and_one_without_data_is_skipped(
    tiny_dataset: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(bench, "RUNS", 1)
    monkeypatch.setattr(
        bench, "RECIPES", {"tiny": ("tiny.yaml", 600.0, "a test"), "gone": ("tiny.yaml", 1.0, "")}
    )
    monkeypatch.setattr(
        bench, "_roots", lambda data: {"tiny": tiny_dataset, "gone": tmp_path / "nowhere"}
    )
    result = bench.run(None)
    tiny, gone = result["recipes"]["tiny"], result["recipes"]["gone"]
    assert tiny["runs"] == 1 and tiny["seconds_all"] == [tiny["median_s"]] and tiny["median_s"] > 0
    assert (tiny["steps"], tiny["networks"], tiny["target_s"]) == (20, 1, 600.0)
    assert tiny["met"] is (tiny["median_s"] <= 600.0)
    assert gone == {
        "skipped": f"no data at {tmp_path / 'nowhere'}",
        "target_s": 1.0,
        "target_from": "",
    }
    assert result["met"] is tiny["met"]  # the skipped recipe neither meets nor fails


def test_a_failed_run_says_what_failed(tmp_path: Path) -> None:
    with pytest.raises(RuntimeError, match="lookfeel train .* failed"):
        bench._train_once(recipe_path("tiny.yaml"), tmp_path / "nowhere", tmp_path / "run")
