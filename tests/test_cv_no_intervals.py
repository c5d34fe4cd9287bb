"""``lookfeel cv --n-boot 0``: every number without an interval, as ``evaluate --set n_boot=0``
and ``reproduce --n-boot 0`` give theirs.

QA: ``lookfeel cv ... --n-boot 0`` trained every fold, then failed in its summary with
``IndexError: too many indices for array``, and every rerun the same way. Now the numbers keep
their values, every interval is null in ``cv.json`` (strict JSON), and ``cv.md`` prints the
numbers alone and says no interval was drawn, in ``reproduce``'s words; a negative n_boot is
refused before anything is trained.
"""

from __future__ import annotations

import math
import re
import warnings
from pathlib import Path

import pytest

from lookfeel.cli import main
from lookfeel.config import ConfigError, RunConfig, load_config
from lookfeel.crossval import cross_validate, format_cv_summary
from lookfeel.crossval.summary import _summarise

from ._tiny import write_tiny_dataset
from .test_crossval import OVERRIDES, TINY, _probe_runs, _strict_json

NO_INTERVAL = "no interval (--n-boot 0: none was drawn)"
"""What ``reproduce --n-boot 0`` says of its cells, and ``cv.md`` now of its own."""


def test_cli_cv_with_n_boot_0_scores_without_intervals_and_rescores_its_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    """A folder scored with intervals (--n-boot 20), summarised again with --n-boot 0 from its
    kept runs, then scored again from its checkpoints (--tta): each time exit 0, the numbers
    alone in cv.md, null intervals in cv.json."""
    data = write_tiny_dataset(tmp_path / "data", fabrics=7, drapes=3)
    out = tmp_path / "cv"
    args = ["cv", "--config", str(TINY), "--data", str(data), "--out", str(out)]
    args += ["--only-folds", "0"]
    for o in OVERRIDES:
        args += ["--set", o]
    assert main([*args, "--n-boot", "20"]) == 0
    before = _strict_json(out / "cv.json")["pairs"]["depth_to_depth"]["model_top1"]
    low, high = before["ci95"]
    assert 0.0 <= low <= before["mean"] <= high <= 1.0
    capsys.readouterr()

    for again, said in (([], "done before, kept"), (["--tta"], "trained before, scoring again")):
        assert main([*args, "--n-boot", "0", *again]) == 0
        printed = capsys.readouterr().out
        assert f"seed 0 fold 0: {said}" in printed
        summary = _strict_json(out / "cv.json")
        assert summary["n_boot"] == 0
        pair = summary["pairs"]["depth_to_depth"]
        for key in ("model_top1", "model_top3", "raw_pixels_top1", "raw_pixels_top3"):
            assert pair[key]["ci95"] == [None, None], key
            assert 0.0 <= pair[key]["mean"] <= 1.0, key
        for row in summary["properties"]["depth"]["model"].values():
            for score in ("r2", "spearman", "chance_r2", "chance_spearman"):
                assert row["pooled"][score]["ci95"] == [None, None]
        md = (out / "cv.md").read_text(encoding="utf-8")
        assert md in printed  # what cv prints is cv.md
        assert "; mean over runs, no interval (--n-boot 0: none was drawn)." in md
        assert f"of every fold at once, {NO_INTERVAL}." in md
        # 3 held out: top-3 is n/a; no bracket, no nan, no "too few to say much" line.
        m, r = pair["model_top1"]["mean"], pair["raw_pixels_top1"]["mean"]
        assert f"| depth_to_depth | {m:.3f} | n/a | {r:.3f} | n/a | 0.333 / 1.000 |" in md
        assert "95% interval" not in md and "nan" not in md.lower()
        assert "they say little" not in md
        assert not re.search(r"\| -?\d\.\d+ \[", md)  # no cell "0.500 [..."
    assert summary["tta"] is True


def test_cv_refuses_a_negative_n_boot_before_anything_is_written(tmp_path: Path):
    """Before the folds are made: one line naming n_boot, nothing logged, no folder made."""
    config = load_config(RunConfig, TINY, OVERRIDES)
    logs: list[str] = []
    with pytest.raises(ConfigError, match=r"^n_boot: bootstrap resamples must be >= 0 .*got -1"):
        cross_validate(config, tmp_path / "none", tmp_path / "cv", n_boot=-1, log=logs.append)
    assert logs == [] and not (tmp_path / "cv").exists()


def test_n_boot_0_classes_and_probes_have_null_intervals_and_say_so():
    """The class table and the probes, of hand-made runs: the accuracy alone (with its
    macro-F1), the probe scores alone, the sentences saying no interval was drawn, and numpy
    silent."""
    runs, _, _ = _probe_runs(seeds=(0,))
    for i, run in enumerate(runs):
        truth = [0, 1, 1, 0]
        guess = {"model": [0, 1, 0, 0], "probe": [1, 1, 1, 0], "raw_pixels": [0, 0, 0, 0]}
        run["classes"] = {
            "touch": {
                "hardness": {
                    "classes": ["soft", "hard"],
                    "truth": truth,
                    "query_fabric": [10 * i + 1, 10 * i + 1, 10 * i + 2, 10 * i + 3],
                    "object_truth": [0, 1],
                    "object": [10 * i + 1, 10 * i + 2],
                    "model_pooled": [0, 1],
                    "majority": [1, 1, 1, 1],
                    **guess,
                }
            }
        }
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        summary = _summarise(runs, list(runs[0]["pairs"]), 0)
        summary |= {"folds": [0, 1, 2], "seeds": [0], "fold_size": 10, "presses": 1}
        md = format_cv_summary(summary | {"n_boot": 0})
    model = summary["classes"]["touch"]["hardness"]["model"]
    assert model["accuracy"] == pytest.approx(0.75)
    assert all(math.isnan(v) for v in model["ci95"])
    stiff = summary["properties"]["depth"]["model"]["stiffness"]["pooled"]
    assert stiff["r2"]["mean"] > 0.9 and all(math.isnan(v) for v in stiff["r2"]["ci95"])
    assert f"Classes from touch: accuracy / macro-F1, {NO_INTERVAL}, each the mean" in md
    assert "| hardness | 0.750 / 0.73 | 1.000 / 1.00 | 0.750 / 0.73 | 0.500 / 0.33 " in md
    assert f"| stiffness | {stiff['r2']['mean']:.2f} | " in md
    rows = [line for line in md.splitlines() if line.startswith(("| stiffness", "| hardness"))]
    assert len(rows) == 3 and not any("[" in line for line in rows)  # R², Spearman, classes
    assert "nan" not in md.lower() and "95% interval" not in md
    # The same runs with intervals drawn: brackets, as before.
    drawn = format_cv_summary(
        _summarise(runs, list(runs[0]["pairs"]), 20)
        | {"folds": [0, 1, 2], "seeds": [0], "fold_size": 10, "presses": 1, "n_boot": 20}
    )
    assert "accuracy [95% interval, resampling held-out fabrics] / macro-F1" in drawn
    assert NO_INTERVAL not in drawn
