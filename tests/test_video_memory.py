"""Press videos larger than a GelSight Mini's: reading one costs about its images and one
float32 reference frame, not a float32 copy of every frame it reads (a 4K phone video took 1.7
GB in ``data check``), and gives the same bytes however it is read.

The videos are built here with PyAV: `tests._video`'s press drawn small, each frame enlarged
by FFmpeg's scaler as it is encoded (no large array is made to write one).
"""

from __future__ import annotations

import tracemalloc
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from lookfeel.data import video as video_module
from lookfeel.data.video import Press, difference_image, read_press, read_video, view_frames

av = pytest.importorskip("av")

from ._video import PRESS, object_press  # noqa: E402

W, H, T = 1280, 720, 24
"""A 720p press video: a frame is 2.8 MB of RGB, 11 MB of float32."""
FLOAT_FRAME = W * H * 3 * 4


def write_large(path: Path, t: int = T) -> Path:
    """A press (`tests._video.PRESS`: frames 5-9, deepest at 7) of ``t`` frames at W x H."""
    frames = object_press(2, PRESS, t=t, seed=3)
    with av.open(str(path), mode="w") as c:
        s = c.add_stream("mpeg4", rate=10)
        s.width, s.height, s.pix_fmt = W, H, "yuv420p"
        s.bit_rate = 4_000_000
        for f in frames:
            big = av.VideoFrame.from_ndarray(f, format="rgb24").reformat(W, H, "yuv420p")
            for packet in s.encode(big):
                c.mux(packet)
        for packet in s.encode():
            c.mux(packet)
    return path


@pytest.fixture(scope="module")
def large(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_large(tmp_path_factory.mktemp("large") / "press.mov")


@pytest.fixture(scope="module")
def frames(large: Path) -> np.ndarray:
    return read_video(large)


def _traced_peak(read: Callable[[], Press]) -> tuple[Press, int]:
    """What ``read()`` returns, and the peak of the memory traced while it ran (numpy's arrays
    are traced; FFmpeg's decoded frames are not), less what was traced before."""
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
        out = read()
        peak = tracemalloc.get_traced_memory()[1] - before
    finally:
        tracemalloc.stop()
    return out, peak


def test_reading_a_large_press_holds_one_float_frame_not_every_frame_read(large: Path):
    data = large.read_bytes()
    press, peak = _traced_peak(lambda: read_press(large, data=data))
    assert press.span.peak == 7 and press.images.shape == (1, H, W, 3)
    # The reference (one float32 frame), the image, a frame being converted and a band of
    # float rows: 1.4 float32 frames (15 MB). Averaging the 5 reference frames as a list of
    # float32 copies, then stacked, took 11 (122 MB).
    assert peak < 2 * FLOAT_FRAME, peak / FLOAT_FRAME


def test_the_views_of_a_large_press_cost_their_images_not_more(large: Path):
    data = large.read_bytes()

    def read() -> Press:
        return read_press(large, data=data, choose=lambda span: view_frames(span, 4))

    press, peak = _traced_peak(read)
    images = press.images
    assert images.shape == (5, H, W, 3)
    # Its 5 images (14 MB), the reference (11 MB) and little more (1.1 float32 frames in
    # all beside the images), not every frame wanted held as RGB and float32, then stacked
    # into a second copy of the images (9.8).
    assert peak < images.nbytes + 2 * FLOAT_FRAME, (peak - images.nbytes) / FLOAT_FRAME


@pytest.mark.parametrize("keep", [True, False], ids=["held", "decoded-again"])
def test_a_large_press_reads_the_same_bytes_as_from_every_frame(large, frames, monkeypatch, keep):
    """The reference is the float32 mean of the reference frames and each image their
    `difference_image` exactly, whether the frames were held from the scan or decoded again."""
    monkeypatch.setattr(video_module, "_KEEP_DECODED_BYTES", 1 << 30 if keep else 0)
    for subtract in (True, False):
        press = read_press(
            large, choose=lambda span: view_frames(span, 3), subtract_reference=subtract
        )
        a, b = press.span.reference
        reference = np.mean([f.astype(np.float32) for f in frames[a:b]], axis=0)
        assert press.reference.dtype == np.float32
        assert press.reference.tobytes() == reference.astype(np.float32).tobytes()
        for i, image in zip(press.indices, press.images, strict=True):
            expected = difference_image(frames[i], reference) if subtract else frames[i]
            assert np.array_equal(image, expected), i


def test_a_frame_chosen_among_the_reference_frames_waits_for_the_whole_reference(large, frames):
    press = read_press(large, choose=lambda span: [span.peak, 1, span.reference[0], span.peak])
    a, b = press.span.reference
    assert a <= 1 < b
    reference = np.mean([f.astype(np.float32) for f in frames[a:b]], axis=0)
    for i, image in zip(press.indices, press.images, strict=True):
        assert np.array_equal(image, difference_image(frames[i], reference)), i


def test_a_difference_image_in_bands_of_rows_is_the_whole_frame_s(monkeypatch):
    rng = np.random.default_rng(0)
    frame = rng.integers(0, 256, (37, 23, 3), dtype=np.uint8)
    reference = rng.uniform(0, 255, (37, 23, 3)).astype(np.float32)
    whole = np.clip(np.rint((frame.astype(np.float32) - reference) * 8 + 128), 0, 255)
    monkeypatch.setattr(video_module, "_BAND_VALUES", 5 * 23 * 3)  # bands of 5 rows, the last of 2
    assert np.array_equal(difference_image(frame, reference, 8.0), whole.astype(np.uint8))
    # a reference that broadcasts (one colour, or a frame of one row) is taken whole
    colour = np.array([100, 120, 140], np.float32)
    expected = np.clip(np.rint((frame - colour) * 8 + 128), 0, 255).astype(np.uint8)
    assert np.array_equal(difference_image(frame, colour), expected)
    row = reference[:1]
    assert np.array_equal(difference_image(frame, row), difference_image(frame, row.repeat(37, 0)))
