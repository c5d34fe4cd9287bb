"""benchmarks/bench_synth_fidelity.py: what the synthetic world's labels teach about real drapes."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from benchmarks.bench_synth_fidelity import ridge_transfer, spearman_with_ci, zero_shot_properties

from lookfeel.config import RunConfig, load_config
from lookfeel.train import train

from ._tiny import write_tiny_dataset

TINY = Path(__file__).resolve().parents[1] / "configs" / "tiny.yaml"


def test_rank_correlation_and_its_interval_on_known_orders() -> None:
    truth = np.arange(20, dtype=float)
    same = spearman_with_ci(truth**3, truth)  # any increasing map keeps the order
    assert same["spearman"] == 1.0 and same["ci95"] == [1.0, 1.0] and same["fabrics"] == 20
    assert spearman_with_ci(-truth, truth)["spearman"] == -1.0
    noisy = spearman_with_ci(truth + np.random.default_rng(0).normal(0, 4, 20), truth)
    low, high = noisy["ci95"]
    assert 0 < low < noisy["spearman"] < high <= 1  # a real interval around a real estimate
    # Unknown labels are left out; too few fabrics or a constant side give no estimate.
    with_nan = spearman_with_ci(np.r_[truth, 5.0], np.r_[truth, np.nan])
    assert with_nan["spearman"] == 1.0 and with_nan["fabrics"] == 20
    assert math.isnan(spearman_with_ci(truth[:2], truth[:2])["spearman"])
    assert math.isnan(spearman_with_ci(np.ones(20), truth)["spearman"])


def test_a_ridge_fitted_on_one_world_carries_its_order_to_another() -> None:
    rng = np.random.default_rng(0)
    t_src, t_tgt = rng.uniform(0, 1, 60), rng.uniform(0, 1, 30)
    # Feature 0 follows the label; feature 1 is noise. The target world adds an offset to
    # every feature (another scale of pixels), which moves the predictions but not their order.
    x_src = np.c_[t_src, rng.normal(0, 1, 60)]
    x_tgt = np.c_[t_tgt, rng.normal(0, 1, 30)] + 5.0
    y_src = 2 * t_src + 1
    y_src[:5] = np.nan  # unknown labels are not fitted
    pred = ridge_transfer(x_src, y_src, x_tgt)
    assert pred.shape == (30,)
    assert spearman_with_ci(pred, t_tgt)["spearman"] > 0.95


@pytest.mark.filterwarnings("ignore")
def test_zero_shot_properties_scores_each_shared_label_three_ways(tmp_path: Path) -> None:
    world = write_tiny_dataset(tmp_path / "world", fabrics=6, drapes=2)
    real = write_tiny_dataset(tmp_path / "real", fabrics=6, drapes=2)
    config = load_config(
        RunConfig,
        TINY,
        ["train.views=[depth,depth]", "train.split=none", "train.steps=2", "train.val_every=0",
         "model.num_properties=auto"],
    )  # fmt: skip
    run = train(config, world, tmp_path / "run")
    out = zero_shot_properties(run.last_checkpoint, world, real)
    assert out["real_fabrics"] == 6 and out["synthetic_fabrics"] == 6
    assert set(out["labels"]) == {"thickness_mm", "density", "stiffness", "stretchiness"}
    for label, entry in out["labels"].items():
        assert set(entry) == {"head", "embedding_ridge", "raw_pixels_ridge"}, label
        for scored in entry.values():
            rho = scored["spearman"]
            assert math.isnan(rho) or -1.0 <= rho <= 1.0
    assert out["labels"]["density"]["head"]["fabrics"] == 5  # fabric 2's density is unknown
    # The two folders are drawn alike, so raw pixels fitted on one rank the other's thickness
    # (0.5 x the fabric's id) exactly as the world's.
    assert out["labels"]["thickness_mm"]["raw_pixels_ridge"]["spearman"] > 0.9
