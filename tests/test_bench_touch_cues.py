"""benchmarks/bench_touch_cues.py: the contact statistics of a press, and the probe on them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from benchmarks.bench_touch_cues import PEAK_NAMES, POINTS, features, probe

from tests._video import PRESS, object_press, write_video


def test_a_deeper_press_changes_the_gel_more(tmp_path: Path) -> None:
    shallow = {i: 0.4 * d for i, d in PRESS.items()}
    a = write_video(tmp_path / "cork_0.mov", object_press(3, shallow, t=14))
    b = write_video(tmp_path / "cork_1.mov", object_press(3, PRESS, t=14))
    (_, fa), (_, fb) = features(str(a)), features(str(b))
    assert fa is not None and fb is not None
    assert fa["peak"].shape == (len(PEAK_NAMES),)
    peak = dict(zip(PEAK_NAMES, fb["peak"], strict=True))
    shallow_peak = dict(zip(PEAK_NAMES, fa["peak"], strict=True))
    assert peak["change p90"] > 1.5 * shallow_peak["change p90"]
    assert peak["change p99"] > 1.5 * shallow_peak["change p99"]
    assert peak["log mean change"] > shallow_peak["log mean change"]
    # The course is each curve over the loading, divided by its value at the deepest frame.
    assert fb["course"].shape == (2 * POINTS + 2,)
    assert fb["course"][POINTS - 1] == pytest.approx(1.0, abs=1e-3)
    assert fb["course"][2 * POINTS - 1] == pytest.approx(1.0, abs=1e-3)


def test_a_video_without_contact_has_no_features(tmp_path: Path) -> None:
    path = write_video(tmp_path / "foam_0.mov", object_press(0, {}, t=14))
    assert features(str(path)) == (str(path), None)


def test_probe_is_object_disjoint_and_beside_the_majority() -> None:
    rng = np.random.default_rng(0)
    objects = np.repeat([f"o{k}" for k in range(20)], 4)
    y = np.repeat(np.arange(20) % 3, 4)
    y[y == 2] = 0  # classes 0 and 1, 14 and 6 objects
    telling = (y + 0.1 * rng.standard_normal(len(y)))[:, None]
    assert probe(telling, y, objects, partitions=2)["accuracy"] == 1.0
    # A number that says nothing: the probe falls back to the training folds' majority class.
    blind = probe(np.zeros((len(y), 1)), y, objects, partitions=2)
    assert blind["accuracy"] == blind["majority"] < 1.0


def test_the_release_follows_the_unloading(tmp_path: Path) -> None:
    # The same loading, then let go at once or over four frames.
    quick = {5: 0.4, 6: 0.7, 7: 1.0}
    slow = {5: 0.4, 6: 0.7, 7: 1.0, 8: 0.9, 9: 0.75, 10: 0.6, 11: 0.45}
    a = write_video(tmp_path / "cork_0.mov", object_press(3, quick, t=16))
    b = write_video(tmp_path / "cork_1.mov", object_press(3, slow, t=16))
    (_, fa), (_, fb) = features(str(a)), features(str(b))
    assert fa is not None and fb is not None
    assert fa["release"].shape == fb["release"].shape == (2 * POINTS + 2,)
    # Each curve starts at the deepest frame (1.0); the log frames of the unloading come after.
    assert fb["release"][0] == pytest.approx(1.0, abs=1e-3)
    assert fb["release"][POINTS] == pytest.approx(1.0, abs=1e-3)
    assert fb["release"][-2] > fa["release"][-2] + 1.0
    # Both end out of contact, and across the release the slow one holds more of its change.
    for f in (fa, fb):
        assert f["release"][2 * POINTS - 1] < 0.3
    area_a, area_b = fa["release"][:POINTS], fb["release"][:POINTS]
    assert area_b.mean() > area_a.mean() + 0.15
    # The loading is the same in both.
    np.testing.assert_allclose(fa["course"][:-1], fb["course"][:-1], atol=0.05)
