"""benchmarks/bench_touch_metric.py: touch to touch by other distances on the same networks."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from benchmarks.bench_touch_metric import (
    VARIANTS,
    chamfer,
    distances,
    hub_corrected,
    measure,
    top1,
    whitening,
)

from lookfeel.metrics.distances import pairwise_distances


def _presses(rng: np.random.Generator, objects: int, presses: int) -> tuple[np.ndarray, np.ndarray]:
    """(N, 4) presses: dimension 0 tells the objects apart (1 apart, noise 0.05); dimensions
    1-3 are each press's own noise (std 5), which swamps it in plain Euclidean distance."""
    obj = np.repeat(np.arange(objects), presses)
    signal = obj[:, None] + 0.05 * rng.standard_normal((len(obj), 1))
    return np.hstack([signal, 5 * rng.standard_normal((len(obj), 3))]), obj


def test_whitening_fitted_on_training_objects_finds_what_tells_new_objects_apart():
    rng = np.random.default_rng(0)
    train, train_obj = _presses(rng, 20, 6)
    held, held_obj = _presses(rng, 12, 5)
    held_obj = held_obj + 100  # objects the whitening never saw
    plain = top1(pairwise_distances(held, held), held_obj).mean()
    scores = {}
    for shrink in (0.0, 0.3):
        white = whitening(train, train_obj, shrink)
        scores[shrink] = top1(pairwise_distances(white(held), white(held)), held_obj).mean()
    assert plain < 0.5
    assert scores[0.0] > 0.95  # the press's own noise whitened away
    assert plain + 0.05 < scores[0.3] < scores[0.0]  # shrunk toward the plain distance


def test_a_press_and_its_views_in_another_order_are_at_chamfer_distance_zero():
    rng = np.random.default_rng(1)
    views = rng.standard_normal((3, 5, 8))
    views[1] = views[0][[4, 2, 0, 1, 3]]
    d = chamfer(views)
    assert d[0, 1] == pytest.approx(0.0, abs=1e-6)
    assert d[0, 2] > 0.5
    np.testing.assert_allclose(d, d.T)


def test_the_hub_correction_prefers_the_less_crowded_of_two_near_candidates():
    dist = np.array([[1.0, 1.1]])
    out = hub_corrected(dist, np.array([0.5]), np.array([0.8, 1.2]))
    assert out[0, 1] < out[0, 0]  # the candidate near every training object counts less
    assert (out >= 0).all()


def test_the_variants_are_all_scored_and_the_first_is_the_cv_distance():
    rng = np.random.default_rng(2)
    views = rng.standard_normal((6, 3, 4))
    train, train_obj = _presses(rng, 5, 4)
    d = distances(views, rng.standard_normal((6, 10)), train, train_obj, rng.random((20, 10)))
    assert tuple(d) == VARIANTS
    mean = views.mean(1)
    np.testing.assert_allclose(d["embedding"], pairwise_distances(mean, mean))
    assert all(v.shape == (6, 6) for v in d.values())


def test_a_cv_folder_without_runs_is_one_clear_error(tmp_path: Path):
    with pytest.raises(SystemExit, match="no finished runs"):
        measure(tmp_path, tmp_path)
