"""The leak check of large press videos: each press costs its frames and one float32 frame, not
full-size float32 copies of its three images (a 4K press took 1.2 GB in ``data check``), and its
pooled images are those of pooling the whole images.

The 720p press is `tests.test_video_memory`'s (`write_large`).
"""

from __future__ import annotations

import shutil
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from lookfeel.config import DataConfig
from lookfeel.data import leakage as leakage_module
from lookfeel.data import scan
from lookfeel.data import video as video_module
from lookfeel.data.leakage import LeakageReport, leakage_report
from lookfeel.data.video import difference_image, read_press

pytest.importorskip("av")

from ._video import PRESS, object_press, write_video
from .test_data_leakage import _write_presses
from .test_video_memory import FLOAT_FRAME, write_large


def test_the_leak_check_of_a_large_press_holds_about_one_float_frame(tmp_path: Path):
    """Three 720p presses (fabric 1 twice, fabric 2 once), scored one at a time."""
    touch = tmp_path / "touch"
    touch.mkdir()
    first = write_large(touch / "F0001_fold_100.mov")
    shutil.copy(first, touch / "F0001_fold_101.mov")
    shutil.copy(first, touch / "F0002_fold_200.mov")
    catalog = scan(tmp_path)
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
        report = leakage_report(catalog, n_boot=20, workers=1)
        peak = tracemalloc.get_traced_memory()[1] - before
    finally:
        tracemalloc.stop()
    (m,) = report.modalities
    assert m.press_videos and m.n_items == 3 and m.pooled_shape == (36, 64) and m.pool == 20
    # Reading a press (its image and float32 no-contact frame, 1.4 float32 frames at most:
    # test_video_memory), then its three images made and pooled a band of rows at a time.
    # Made whole, each a float32 copy (the pressed frame's twice), then pooled: 4.5 (50 MB).
    assert peak < 2 * FLOAT_FRAME, peak / FLOAT_FRAME


def _whole(press, gain: float, shape: tuple[int, int], k: int) -> list[np.ndarray]:
    """The three images of a press made whole, then resized and pooled, as they were."""
    images, reference = press.images, press.reference
    diff = [difference_image(f, reference, gain) for f in images]
    made = [
        images.astype(np.float32).mean(axis=0),
        np.mean(np.stack(diff), axis=0, dtype=np.float32),
        reference.astype(np.float32),
    ]
    return [leakage_module._pool(leakage_module._resize(a, shape), k) for a in made]


@pytest.mark.parametrize("frames", [1, 3])
def test_a_press_pooled_in_bands_of_rows_is_the_whole_images_pooled(tmp_path, monkeypatch, frames):
    video = write_video(tmp_path / "press.mp4", object_press(2, PRESS, 16, seed=4))
    press = read_press(video, frames=frames, subtract_reference=False)
    assert press.images.shape == (frames, 48, 64, 3)
    gain = DataConfig().video_gain
    # Bands of 2 pooling windows of 5 rows (the last band of 1, the 3 ragged rows dropped);
    # a press of another size, resized whole; pooling by 1; one band for the whole image.
    monkeypatch.setattr(video_module, "_BAND_VALUES", 10 * 64 * 3)
    for shape, k in [((48, 64), 5), ((40, 50), 4), ((48, 64), 1), ((48, 64), 16), ((48, 64), 60)]:
        got = leakage_module._pool_press(press, gain, shape, k)
        for a, b in zip(got, _whole(press, gain, shape, k), strict=True):
            assert a.dtype == np.float32 and a.shape == b.shape, (shape, k, a.shape, b.shape)
            assert a.tobytes() == b.tobytes(), (shape, k)


def test_the_leak_report_of_presses_is_the_same_in_bands(tmp_path: Path, monkeypatch):
    catalog = scan(_write_presses(tmp_path / "presses", sessions=True))

    def report() -> LeakageReport:
        return leakage_report(catalog, n_boot=50, pool=3)

    whole = report().to_dict()
    monkeypatch.setattr(video_module, "_BAND_VALUES", 1)  # a pooling window of rows a band
    banded = report().to_dict()
    assert banded["modalities"]["touch"]["pooled_shape"] == [16, 21]
    assert banded["modalities"] == whole["modalities"]
