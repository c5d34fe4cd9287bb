"""Press videos: decoding with PyAV, finding the press, the frames taken, errors, the loader.

Small videos are built here with PyAV: a few flat frames (the untouched sensor), then a blob
pressing in and out over a known span, then flat again.
"""

from __future__ import annotations

import dataclasses
import io
import warnings
from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from lookfeel.config import ConfigError, DataConfig
from lookfeel.data import ImageLoader
from lookfeel.data import images as images_module
from lookfeel.data import video as video_module
from lookfeel.data.catalog import Item
from lookfeel.data.images import PreprocessSettings
from lookfeel.data.video import (
    MIN_VIDEO_FRAMES,
    NoPressError,
    PressSpan,
    TruncatedVideoWarning,
    VideoError,
    contact_frames,
    deep_frames,
    detect_press,
    difference_image,
    frame_at,
    is_video,
    read_press,
    read_video,
    reference_frame,
    small_greyscale,
    view_frames,
)
from lookfeel.modality import Modality

av = pytest.importorskip("av")

from ._video import PRESS, object_press, write_video  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
PHYSICLEAR = [REPO.parent / "shared" / "data" / "physiclear", Path("/work/shared/data/physiclear")]

W, H, T = 64, 48, 20
START, PEAK, END = 5, 9, 13
AMPLITUDE = {5: 0.4, 6: 0.6, 7: 0.75, 8: 0.85, 9: 1.0, 10: 0.8, 11: 0.65, 12: 0.45}
"""Depth of the synthetic press per frame (others: no contact): start 5, peak 9, end 13."""


def _sensor() -> np.ndarray:
    """(H, W, 3) float32: the untouched sensor's light pattern (smooth colour gradients)."""
    y, x = np.mgrid[0:H, 0:W].astype(np.float32)
    return np.stack([90 + 60 * x / W, 100 + 50 * y / H, 150 - 40 * x / W], axis=-1)


def press_frames(
    amplitude: dict[int, float] = AMPLITUDE, t: int = T, light: dict[int, float] | None = None
) -> np.ndarray:
    """(t, H, W, 3) uint8: the sensor, with a blob pressed in to ``amplitude[i]`` at frame i,
    its light times ``light[i]`` at frame i (others: 1)."""
    y, x = np.mgrid[0:H, 0:W].astype(np.float32)
    blob = np.exp(-((x - 30) ** 2 + (y - 22) ** 2) / (2 * 7.0**2))[..., None]
    tint = np.array([70.0, 30.0, -40.0], dtype=np.float32)  # brighter (+34 luma), and coloured
    rng = np.random.default_rng(0)
    out = []
    for i in range(t):
        f = _sensor() * (light or {}).get(i, 1.0) + amplitude.get(i, 0.0) * blob * tint
        f += rng.normal(0, 0.7, (H, W, 1))
        out.append(np.clip(np.rint(f), 0, 255).astype(np.uint8))
    return np.stack(out)


@pytest.fixture(scope="module")
def videos(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("videos")
    frames = press_frames()
    return {
        suffix: write_video(root / f"press{suffix}", frames) for suffix in (".mp4", ".mov", ".avi")
    }


# ---- decoding and finding the press ---------------------------------------------------------


def test_is_video_by_suffix():
    assert is_video("a/b.MOV") and is_video("x.mp4") and is_video("x.avi")
    assert not is_video("x.png") and not is_video("mov")


@pytest.mark.parametrize("suffix", [".mp4", ".mov", ".avi"])
def test_read_video_and_detect_the_known_press(videos: dict[str, Path], suffix: str):
    frames = read_video(videos[suffix])
    assert frames.shape == (T, H, W, 3) and frames.dtype == np.uint8
    assert np.abs(frames.astype(float) - press_frames().astype(float)).mean() < 3  # lossy codec
    span = detect_press(frames, videos[suffix])
    assert abs(span.start - START) <= 1 and abs(span.peak - PEAK) <= 1 and abs(span.end - END) <= 1
    a, b = span.reference
    assert a == 0 and 3 <= b <= span.start  # the first frames, never into the press
    assert span.strength.shape == (T,) and span.strength.dtype == np.float32
    assert span.contrast > 10 * max(span.noise, 0.1)


@pytest.mark.parametrize(
    ("name", "codec", "pix_fmt"),
    [
        ("mjpeg.avi", "mjpeg", "yuvj420p"),  # full-range luma
        ("x264.mp4", "libx264", "yuv420p"),  # B-frames: decoded out of order
        ("rgb.mkv", "ffv1", "bgr0"),  # packed RGB: no luma plane
        ("grey.mkv", "ffv1", "gray"),
    ],
)
def test_other_codecs_and_pixel_formats(tmp_path: Path, name: str, codec: str, pix_fmt: str):
    path = write_video(tmp_path / name, press_frames(), codec, pix_fmt)
    small = small_greyscale(path)
    rgb = read_video(path).astype(np.float32) @ np.array([0.299, 0.587, 0.114])
    assert np.abs(small - rgb).mean() < 2.0
    span = read_press(path).span
    assert abs(span.start - START) <= 1 and abs(span.peak - PEAK) <= 1 and abs(span.end - END) <= 1


def test_small_greyscale_from_the_luma_plane_agrees_with_rgb(videos: dict[str, Path]):
    small = small_greyscale(videos[".mp4"])
    assert small.shape == (T, H, W) and small.dtype == np.float32
    rgb = read_video(videos[".mp4"]).astype(np.float32) @ np.array([0.299, 0.587, 0.114])
    assert np.abs(small - rgb).mean() < 2.0  # same grey scale (video-range luma rescaled)
    fast = detect_press(small, videos[".mp4"])
    slow = detect_press(read_video(videos[".mp4"]), videos[".mp4"])
    assert (fast.start, fast.peak, fast.end) == (slow.start, slow.peak, slow.end)


def test_read_press_takes_the_deepest_frame_minus_the_reference(videos: dict[str, Path]):
    path = videos[".mov"]
    frames = read_video(path)
    press = read_press(path, gain=2.0)
    span = press.span
    assert press.indices == (span.peak,) and press.subtracted
    ref = reference_frame(frames, span)
    assert press.reference.shape == (H, W, 3) and np.allclose(press.reference, ref, atol=1e-3)
    expected = difference_image(frames[span.peak], ref, 2.0)
    assert press.images.shape == (1, H, W, 3) and np.array_equal(press.images[0], expected)
    # the difference is grey where nothing touched, and carries the blob's tint where it did
    d = press.images[0].astype(float) - 128
    assert np.abs(d[:6, -6:]).mean() < 3
    assert d[22, 30, 0] > 100 and d[22, 30, 2] < -60
    raw = read_press(path, subtract_reference=False)
    assert np.array_equal(raw.images[0], frames[span.peak]) and not raw.subtracted


def test_read_press_frames_across_the_span(videos: dict[str, Path]):
    press = read_press(videos[".avi"], frames=5)
    span = press.span
    assert press.images.shape == (5, H, W, 3)
    assert press.indices[0] == span.start and press.indices[-1] == span.end - 1
    assert list(press.indices) == sorted(press.indices)
    mid = read_press(videos[".avi"], position=0.5)
    assert mid.indices == (frame_at(span, 0.5),)


def test_contact_frames_and_frame_at():
    span = PressSpan((0, 3), 4, 7, 12, np.zeros(14, np.float32), 1.0, 0.1, 2.0)
    assert contact_frames(span) == [7]
    assert contact_frames(span, 3) == [4, 8, 11]
    assert contact_frames(span, 8) == list(range(4, 12))
    assert frame_at(span, 0.0) == 4 and frame_at(span, 1.0) == 11 and frame_at(span, 0.5) == 8
    with pytest.raises(ValueError):
        contact_frames(span, 0)
    with pytest.raises(ValueError):
        frame_at(span, 1.5)


def test_difference_image_is_128_plus_gain_times_the_change():
    ref = np.full((2, 2, 3), 100.0, np.float32)
    frame = np.array([[[100, 101, 90]] * 2, [[0, 255, 100]] * 2], np.uint8)
    d = difference_image(frame, ref, 4.0)
    assert d.dtype == np.uint8
    assert d[0, 0].tolist() == [128, 132, 88] and d[1, 0].tolist() == [0, 255, 128]


def test_a_video_with_no_contact_is_refused(tmp_path: Path):
    path = write_video(tmp_path / "still.mp4", press_frames({}))
    with pytest.raises(VideoError, match="no contact") as e:
        read_press(path)
    assert str(path) in str(e.value) and "\n" not in str(e.value)


@pytest.mark.parametrize("gain", [0.8, 1.2])
def test_a_change_of_light_with_no_press_is_not_a_press(tmp_path: Path, gain: float):
    # The LED or the exposure steps at frame 8 and stays: every pixel of the untouched sensor
    # changes by the same factor. Read before as a press from frame 8 never released.
    frames = press_frames({}, light={i: gain for i in range(8, T)})
    path = write_video(tmp_path / "light.mp4", frames)
    with pytest.raises(NoPressError, match="no contact found: the light changed with no") as e:
        read_press(path)
    assert str(e.value).startswith(f"{path}: ") and "\n" not in str(e.value)
    assert ("brighter" if gain > 1 else "darker") in str(e.value) and "from frame 8" in str(e.value)


def test_a_press_while_the_light_changes_is_still_a_press(tmp_path: Path):
    light = {i: 1.0 - 0.02 * min(i, 10) for i in range(T)}  # the exposure drifts 20% darker
    span = read_press(write_video(tmp_path / "drift.mp4", press_frames(light=light))).span
    assert abs(span.peak - PEAK) <= 1 and abs(span.start - START) <= 1


def test_a_press_from_the_first_frame_has_no_reference():
    frames = press_frames({i: 1.0 - 0.08 * i for i in range(12)})
    with pytest.raises(VideoError, match="(no contact|first frame)") as e:
        detect_press(frames, Path("early.mov"))
    assert "no untouched frames at its start to compare against" in str(e.value)


def test_a_press_held_from_the_first_frame_is_said_to_leave_nothing_to_compare_against():
    """QA: a video pressed from its first frame and held said only "no contact found", as if
    nothing were pressed: its first frames, the reference, are pressed too."""
    frames = press_frames({i: 0.9 for i in range(T)})
    with pytest.raises(NoPressError, match=r"^held.mov: no contact found: .* or the gel was pre"):
        detect_press(frames, Path("held.mov"))
    with pytest.raises(NoPressError, match="no untouched frames at its start to compare against"):
        detect_press(press_frames({}), Path("still.mov"))  # never pressed: it says both


def test_a_too_short_video_is_refused(tmp_path: Path):
    path = write_video(tmp_path / "short.mov", press_frames({1: 1.0}, t=3))
    with pytest.raises(VideoError, match=f"too short: 3 frames; at least {MIN_VIDEO_FRAMES}") as e:
        read_press(path)
    assert str(path) in str(e.value)


# ---- QA: presses as a DIGIT / GelSight owner records them ---------------------------------------

RAMP = {**{i: min(1.0, 0.1 * (i - 4)) for i in range(5, 22)}, 22: 0.6, 23: 0.3}
"""A press pushed in over frames 5-14, held to 21 and released by 24 (of 40)."""


@pytest.mark.parametrize("cut", [7, 9])
def test_a_video_that_begins_mid_press_is_refused_not_read_backwards(tmp_path: Path, cut: int):
    """QA: a clip starting mid-press, then releasing, was accepted: its first frames (pressed)
    were taken as the untouched reference and the release as the press, so the model got an
    inverted difference image."""
    frames = object_press(1, RAMP, 40)
    whole = read_press(write_video(tmp_path / "whole.mp4", frames)).span
    assert whole.reference == (0, 5) and (whole.start, whole.end) == (7, 24)  # begins untouched
    path = write_video(tmp_path / f"from{cut}.mp4", frames[cut:])
    with pytest.raises(NoPressError) as e:
        read_press(path)
    assert str(e.value).startswith(f"{path}: the press began before the recording: the gel ")
    assert "no untouched frame to compare against" in str(e.value) and "\n" not in str(e.value)


@pytest.mark.parametrize("light", [{0: 0.85, 1: 0.85, 2: 0.95}, {0: 0.92, 1: 0.92, 2: 0.92}])
def test_a_camera_exposure_settling_in_the_first_frames_is_skipped(tmp_path: Path, light):
    """QA: a webcam's auto exposure that settles over the first 3 frames made the reference
    darker than the frames after it: a real press refused as a change of light (naming the
    frame of the press, not of the light), or a difference image far from 128 where untouched."""
    depth = {i + 3: d for i, d in PRESS.items()}  # frames 8-12, deepest at 10
    plain = read_press(write_video(tmp_path / "plain.mp4", object_press(1, depth, 20)))
    press = read_press(
        write_video(tmp_path / "settle.mp4", object_press(1, depth, 20, light=light))
    )
    span = press.span
    assert span.reference == (3, 8)  # the reference begins once the light holds
    assert (span.start, span.peak, span.end) == (plain.span.start, plain.span.peak, plain.span.end)
    assert abs(float(press.images.mean()) - float(plain.images.mean())) < 1.0
    assert span.strength.shape == (20,) and float(span.strength[:3].max()) < span.threshold


def test_a_video_with_two_presses_keeps_the_deepest_and_warns(tmp_path: Path):
    """QA: a video with two presses was used silently (the deeper one)."""
    from lookfeel.data.check import decode_problem

    depth = {5: 0.3, 6: 0.6, 7: 0.6, 8: 0.3, 15: 0.4, 16: 0.8, 17: 1.0, 18: 0.7, 19: 0.3}
    path = write_video(tmp_path / "two.mp4", object_press(1, depth, 26))
    warning = video_module.TwoPressesWarning
    with pytest.warns(warning) as caught:
        span = read_press(path).span
    assert (span.start, span.peak, span.end) == (15, 17, 20)  # the deeper press, as before
    assert len(caught) == 1 and str(caught[0].message) == (
        f"{path}: more than one press: frames 15-19 (the deepest, used) and 5-8; record one "
        "press per video to use each"
    )
    with pytest.warns(warning, match="two.mp4: more than one press"):  # `data check` shows it
        assert decode_problem(path, Modality.TOUCH).problem is None
    with warnings.catch_warnings():
        warnings.simplefilter("error", warning)
        read_press(write_video(tmp_path / "one.mp4", object_press(1, RAMP, 40)))  # one press


@pytest.mark.parametrize("t", [MIN_VIDEO_FRAMES, 7, 8])
def test_a_short_clip_with_a_clear_press_is_read_down_to_the_minimum(tmp_path: Path, t: int):
    """QA: 3 untouched frames and a clear press were refused as "nothing was pressed" under 10
    frames: the floor and noise came from the frames after the first three, mostly pressed."""
    depth = {3: 0.7, 4: 1.0, 5: 0.8, 6: 0.4}
    span = read_press(write_video(tmp_path / f"short{t}.mp4", object_press(1, depth, t))).span
    assert span.reference == (0, 3) and (span.start, span.peak, span.end) == (3, 4, min(t, 7))


def test_a_press_held_to_the_end_starts_where_contact_does(tmp_path: Path):
    """QA: 3 untouched frames then a press held to the end gave start 5, not 3: the floor (10th
    percentile after the first frames) was a pressed level."""
    depth = {i: min(1.0, 0.25 * (i - 2)) for i in range(3, 20)}
    span = read_press(write_video(tmp_path / "held.mp4", object_press(1, depth, 20))).span
    assert span.reference == (0, 3) and (span.start, span.end) == (3, 20) and span.peak >= 6


def test_read_press_says_whether_a_video_has_no_colour(tmp_path: Path):
    """QA: a grey video was converted to RGB silently; `Press.grey` says so, for `data check`
    and `predict` to warn."""
    colour = object_press(1, PRESS, 16)
    grey = np.repeat(colour.astype(np.float32) @ np.array([0.299, 0.587, 0.114]), 3, axis=-1)
    grey = np.rint(grey.reshape(colour.shape)).astype(np.uint8)
    single = read_press(write_video(tmp_path / "grey.mkv", grey, "ffv1", "gray"))
    assert single.grey and single.pixel_format == "gray" and video_module.is_single_channel("gray")
    stored = read_press(write_video(tmp_path / "grey.mp4", grey))  # grey stored as colour
    assert stored.grey and stored.pixel_format == "yuv420p"
    press = read_press(write_video(tmp_path / "colour.mp4", colour))
    assert not press.grey and press.pixel_format == "yuv420p"
    assert not video_module.is_single_channel("yuv420p")


def _png_bytes() -> bytes:
    buf = io.BytesIO()
    Image.fromarray(np.zeros((8, 8, 3), np.uint8)).save(buf, "PNG")
    return buf.getvalue()


@pytest.mark.parametrize(
    ("name", "content"),
    [
        ("half.mp4", lambda good: good[: len(good) // 2]),
        ("head.mov", lambda good: good[:600]),
        ("random.mov", lambda good: np.random.default_rng(1).bytes(4000)),
        ("image.mov", lambda good: _png_bytes()),
        ("empty.avi", lambda good: b""),
    ],
)
def test_a_corrupt_file_is_refused_naming_it(videos, tmp_path: Path, name, content):
    suffix = Path(name).suffix
    path = tmp_path / name
    path.write_bytes(content(videos[suffix].read_bytes()))
    for read in (read_press, read_video):
        with pytest.raises(VideoError, match="(cannot decode|truncated)") as e:
            read(path)
        assert str(e.value).startswith(f"{path}: ") and "\n" not in str(e.value)


def test_a_truncated_avi_is_refused(videos, tmp_path: Path):
    good = videos[".avi"].read_bytes()
    path = tmp_path / "cut.avi"
    path.write_bytes(good[: int(len(good) * 0.6)])
    with pytest.raises(VideoError, match="(truncated|cannot decode)"):
        read_press(path)


@pytest.mark.parametrize("codec", ["mpeg4", "ffv1"])
def test_a_truncated_matroska_video_warns_and_reads_what_is_there(tmp_path: Path, codec: str):
    # Matroska declares its duration but not its frames: a file cut short decoded silently.
    good = write_video(tmp_path / "whole.mkv", press_frames(t=40), codec)
    with warnings.catch_warnings():
        warnings.simplefilter("error", TruncatedVideoWarning)
        assert len(read_video(good)) == 40  # the whole file: no warning
    path = tmp_path / "cut.mkv"
    path.write_bytes(good.read_bytes()[: int(good.stat().st_size * 0.6)])
    with pytest.warns(TruncatedVideoWarning) as caught:
        frames = read_video(path)
    assert 13 <= len(frames) < 30 and len(caught) == 1
    assert str(caught[0].message).startswith(
        f"{path}: video is truncated: {len(frames)} frames ({len(frames) / 10:.2f} s) decoded of "
        "the 4.00 s (about 40 frames) it declares"
    )
    with pytest.warns(TruncatedVideoWarning, match="cut.mkv: video is truncated"):
        span = read_press(path).span  # the press (frames 5-12) is in what is left
    assert abs(span.peak - PEAK) <= 1 and span.frames == len(frames)


def test_limits_on_pixels_and_frames(videos: dict[str, Path], monkeypatch):
    with pytest.raises(VideoError, match=r"64x48 = 0\.0 megapixel frames; at most 0\.001"):
        read_video(videos[".mp4"], max_pixels=1000)
    for suffix in (".mp4", ".avi"):  # frame count declared in the header, or not
        with pytest.raises(VideoError, match="too large: (it declares 20|more than 10) frames"):
            read_press(videos[suffix], max_frames=10)
    monkeypatch.setattr(video_module, "_MAX_DECODED_PIXELS", 64 * 48 * 19)
    with pytest.raises(VideoError, match="too large: .*gigapixels in all"):
        read_press(videos[".mp4"])
    with pytest.raises(VideoError, match="is a folder, not a video file"):
        read_press(videos[".mp4"].parent)


def test_missing_pyav_says_what_to_install(monkeypatch, videos: dict[str, Path]):
    monkeypatch.setitem(__import__("sys").modules, "av", None)
    with pytest.raises(VideoError, match="install the `av` package"):
        read_press(videos[".mp4"])


def test_deep_frames_put_the_peak_first_and_skip_shallow_frames():
    strength = np.array([0, 0, 0, 0, 2, 4, 6, 8, 10, 9, 7, 5, 3, 1], np.float32)
    span = PressSpan((0, 3), 4, 8, 13, strength, 0.0, 0.1, 2.0)
    assert deep_frames(span, 9) == [8, 4, 5, 6, 7, 9, 10, 11, 12]  # every frame, peak first
    assert deep_frames(span, 9, 0.6) == [8, 6, 7, 9, 10]  # at least 6 of the peak's 10
    assert deep_frames(span, 1, 0.6) == [8]
    with pytest.raises(ValueError):
        deep_frames(span, 3, 1.5)


def test_view_frames_are_the_peak_then_n_across_the_span_always_n_plus_one():
    strength = np.array([0, 0, 0, 0, 2, 4, 6, 8, 10, 9, 7, 5, 3, 1], np.float32)
    span = PressSpan((0, 3), 4, 8, 13, strength, 0.0, 0.1, 2.0)
    assert view_frames(span, 3) == [8, 4, 8, 12]
    assert view_frames(span, 12)[0] == 8 and len(view_frames(span, 12)) == 13  # repeats
    assert set(deep_frames(span, 12)) <= set(view_frames(span, 12))  # training views among them


# ---- the image loader --------------------------------------------------------------------------


def _touch_item(path: Path) -> Item:
    return Item(Modality.TOUCH, 1, (path,), None, path.stem)


def test_loader_reads_a_video_touch_item_and_caches_it_on_disk(videos, tmp_path, monkeypatch):
    item = _touch_item(videos[".mp4"])
    cache = tmp_path / "cache"
    config = DataConfig(image_size=16, video_gain=2.0)
    first = ImageLoader(config, cache_dir=cache)
    assert first.frame_path(item) == videos[".mp4"]
    x = first.load(item)
    assert x.shape == (3, 16, 16) and x.dtype == torch.float32
    assert float(x.min()) >= 0.0 and float(x.max()) <= 1.0
    expected = read_press(videos[".mp4"], gain=2.0).images[0]
    assert np.array_equal(
        first.array(videos[".mp4"], Modality.TOUCH),
        images_module.preprocess_rgb(expected, Modality.TOUCH, config),
    )
    assert len(list(cache.rglob("*.npy"))) == 1

    def fail(*args, **kwargs):
        raise AssertionError("decoded again")

    monkeypatch.setattr(video_module, "read_press", fail)
    again = ImageLoader(config, cache_dir=cache).load(item)  # from disk, never decoded
    assert torch.equal(x, again)


def test_loader_follows_the_video_settings(videos: dict[str, Path]):
    item = _touch_item(videos[".mov"])
    diff = ImageLoader(DataConfig(image_size=16)).load(item)
    raw = ImageLoader(DataConfig(image_size=16, video_reference="none")).load(item)
    start = ImageLoader(DataConfig(image_size=16, video_frame=0.0)).load(item)
    assert not torch.equal(diff, raw) and not torch.equal(diff, start)
    assert abs(float(diff[:, :3, -3:].mean()) - 128 / 255) < 0.02  # untouched: mid-grey
    mean = ImageLoader(DataConfig(image_size=16, video_frames=5)).array(
        videos[".mov"], Modality.TOUCH
    )
    press = read_press(videos[".mov"], frames=5)
    expected = np.rint(press.images.astype(np.float32).mean(axis=0)).astype(np.uint8)
    config = DataConfig(image_size=16)
    assert np.array_equal(mean, images_module.preprocess_rgb(expected, Modality.TOUCH, config))
    keys = {
        PreprocessSettings.of(DataConfig(**kw)).digest()
        for kw in (
            {},
            {"video_frame": 0.5},
            {"video_frames": 3},
            {"video_reference": "none"},
            {"video_gain": 2.0},
        )
    }
    assert len(keys) == 5


def test_loader_views_of_a_press_video(videos: dict[str, Path], tmp_path: Path, monkeypatch):
    item = _touch_item(videos[".mov"])
    config = DataConfig(image_size=16, video_views=9, video_views_min=0.6)
    loader = ImageLoader(config, cache_dir=tmp_path)
    assert loader.has_views(item)
    views = loader.views(item)
    press = read_press(videos[".mov"], choose=lambda span: deep_frames(span, 9, 0.6))
    assert press.indices[0] == PEAK and all(AMPLITUDE[i] >= 0.6 for i in press.indices)
    expected = [images_module.preprocess_rgb(im, Modality.TOUCH, config) for im in press.images]
    assert views.shape == (len(press.indices), 16, 16, 3) and len(views) > 2
    assert np.array_equal(views, np.stack(expected))
    # The first view is the image evaluation uses, and a second loader reads both from disk.
    assert np.array_equal(views[0], ImageLoader(config).array(videos[".mov"], Modality.TOUCH))

    # One view where views are off, and for anything but a video.
    single = ImageLoader(DataConfig(image_size=16), cache_dir=tmp_path)
    assert not single.has_views(item)
    assert np.array_equal(single.views(item), views[:1])

    def fail(*args, **kwargs):
        raise AssertionError("decoded again")

    monkeypatch.setattr(images_module, "read_press", fail)
    assert np.array_equal(ImageLoader(config, cache_dir=tmp_path).views(item), views)


def test_loader_embeds_a_press_from_its_views_with_one_decode(
    videos: dict[str, Path], tmp_path: Path, monkeypatch
):
    item = _touch_item(videos[".mov"])
    config = DataConfig(image_size=16, video_views=6, video_views_min=0.6, video_embed="views")
    decoded: list[Path] = []
    real = images_module.read_press

    def counting(path, *args, **kwargs):
        decoded.append(Path(path))
        return real(path, *args, **kwargs)

    monkeypatch.setattr(images_module, "read_press", counting)
    loader = ImageLoader(config, cache_dir=tmp_path)
    assert loader.pools_views(item)
    embedded = loader.embed_array(item)
    train = loader.views(item)
    assert len(decoded) == 1  # both from one decode
    press = real(videos[".mov"], choose=lambda span: view_frames(span, 6))
    expected = np.stack(
        [images_module.preprocess_rgb(im, Modality.TOUCH, config) for im in press.images]
    )
    assert embedded.shape == (7, 16, 16, 3) and np.array_equal(embedded, expected)
    alone = ImageLoader(dataclasses.replace(config, video_embed="image")).views(item)
    assert np.array_equal(train, alone)  # the training views do not change
    assert np.array_equal(embedded[0], ImageLoader(config).array(videos[".mov"], Modality.TOUCH))
    tensor = loader.load_embedded(item)
    assert tensor.shape == (7, 3, 16, 16)
    assert torch.equal(tensor[3], images_module.to_tensor(embedded[3]))
    # A second loader reads both from disk; the image-only setting never pools.
    before = len(decoded)
    again = ImageLoader(config, cache_dir=tmp_path)
    assert np.array_equal(again.embed_array(item), embedded)
    assert np.array_equal(again.views(item), train) and len(decoded) == before
    assert not ImageLoader(DataConfig(image_size=16, video_views=6)).pools_views(item)


def test_stack_views_repeats_a_single_image_as_every_view():
    a = np.arange(2 * 4 * 4 * 3, dtype=np.uint8).reshape(2, 4, 4, 3)
    b = np.full((4, 4, 3), 7, np.uint8)
    s = images_module.stack_views([a, b])
    assert s.shape == (2, 2, 4, 4, 3) and np.array_equal(s[1, 0], b) and np.array_equal(s[1, 1], b)
    assert images_module.stack_views([b, b]).shape == (2, 4, 4, 3)
    t = images_module.stack_views([torch.zeros(3, 4, 4), torch.ones(5, 3, 4, 4)])
    assert t.shape == (2, 5, 3, 4, 4) and float(t[0].sum()) == 0.0
    with pytest.raises(ValueError, match="different numbers of views"):
        images_module.stack_views([a, a[:1]])


def test_store_draws_training_views_deterministically(videos: dict[str, Path]):
    from lookfeel.data import ImageStore

    items = [_touch_item(videos[s]) for s in (".mov", ".mp4")]
    loader = ImageLoader(DataConfig(image_size=16, video_views=6))
    plain = ImageStore(loader, items)
    store = ImageStore(loader, items, views=True)
    rows = torch.tensor(store.rows(Modality.TOUCH, items))
    assert torch.equal(store.batch(Modality.TOUCH, rows), plain.batch(Modality.TOUCH, [0, 1]))
    n = [len(loader.views(it)) for it in items]
    assert rows.tolist() == [0, n[0]]
    drawn = [
        store.draw_views(Modality.TOUCH, rows.repeat(50), np.random.default_rng(7))
        for _ in range(2)
    ]
    assert torch.equal(drawn[0], drawn[1])
    first, second = drawn[0].view(50, 2).T
    assert set(first.tolist()) == set(range(n[0]))  # every view of each, nothing beyond
    assert set(second.tolist()) == set(range(n[0], n[0] + n[1]))
    same = plain.draw_views(Modality.TOUCH, torch.tensor([0, 1]), np.random.default_rng(7))
    assert same.tolist() == [0, 1]


def test_the_config_default_gain_is_the_measured_one():
    assert DataConfig().video_gain == video_module.DEFAULT_GAIN
    settings = PreprocessSettings.of(DataConfig())
    assert (settings.video_frame, settings.video_frames, settings.video_reference) == (
        None,
        1,
        "subtract",
    )
    assert settings.video_gain == video_module.DEFAULT_GAIN


def test_loader_names_a_bad_video(tmp_path: Path):
    path = tmp_path / "bad.mov"
    path.write_bytes(b"not a video at all" * 10)
    with pytest.raises(VideoError, match="bad.mov: cannot decode"):
        ImageLoader(DataConfig(image_size=16)).load(_touch_item(path))


@pytest.mark.parametrize(
    ("kw", "msg"),
    [
        ({"video_frame": 1.5}, "data.video_frame"),
        ({"video_gain": 0.0}, "data.video_gain"),
        ({"video_frames": 0}, "data.video_frames"),
        ({"video_frames": 3, "video_frame": 0.5}, "exclude each other"),
        ({"video_views": 0}, "data.video_views"),
        ({"video_views": 4, "video_frames": 3}, "needs the deepest frame"),
        ({"video_views_min": -0.1}, "data.video_views_min"),
        ({"video_embed": "views"}, "needs video_views >= 2"),
    ],
)
def test_config_rejects_bad_video_settings(kw, msg):
    with pytest.raises(ConfigError, match=msg):
        DataConfig(**kw)
    with pytest.raises(ConfigError, match="data.video_reference"):
        DataConfig(video_reference="median")  # type: ignore[arg-type]


def test_data_check_decodes_a_video_and_finds_its_press(videos, tmp_path: Path):
    from lookfeel.data.check import decode_problem

    decoded = decode_problem(videos[".mp4"], Modality.TOUCH)
    assert decoded.problem is None and decoded.size == (64, 48)
    still = write_video(tmp_path / "still.mov", press_frames({}))
    problem = decode_problem(still, Modality.TOUCH).problem
    assert problem is not None and problem.path == still
    # a recording with no press is a warning: runs leave it out (lookfeel.data.drop_unpressed)
    assert problem.severity == "warning" and problem.message.startswith("no contact found")
    assert problem.message.endswith("; runs leave this recording out")


# ---- real GelSight Mini videos -------------------------------------------------------------------


@pytest.fixture
def physiclear() -> Path:
    for root in PHYSICLEAR:
        if (root / "videos").is_dir():
            return root / "videos"
    pytest.skip(f"real PhysiCLeAR videos not found at {PHYSICLEAR[0]}")


@pytest.mark.parametrize("name", ["blanket_3", "rice_5", "wood_ruler_1", "ripe_avocado_4"])
def test_real_gelsight_mini_presses_are_found(physiclear: Path, name: str):
    path = physiclear / f"{name}.mov"
    if not path.is_file():
        pytest.skip(f"{path} not found")
    press = read_press(path)
    span = press.span
    assert span.frames >= 100
    assert 0 <= span.reference[0] < span.reference[1] <= span.start
    assert 3 <= span.start < span.peak < span.end <= span.frames
    assert span.end - span.start >= 15  # a hand press lasts more than half a second at 25 fps
    assert span.contrast > 2.0
    assert press.images.shape == (1, 240, 320, 3)


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("scissor_handle_4", ((0, 5), 11, 15, 41)),  # frame 0 an odd frame: not a moving gel
        ("cotton_ball_2", ((0, 5), 29, 38, 81)),  # soft: the gel creeps before contact
        ("pen_2", ((0, 5), 8, 13, 50)),  # held to the end of the video
        ("basket_3", ((0, 5), 47, 68, 87)),  # pressed twice: the deeper press, and a warning
    ],
)
def test_real_presses_keep_the_spans_the_published_numbers_used(physiclear, name, expected):
    """The checks added for QA's videos (exposure settling, a video begun mid-press, a short
    or held clip, a second press) change no span of the 398 PhysiCLeAR presses; these are the
    nearest to each rule."""
    path = physiclear / f"{name}.mov"
    if not path.is_file():
        pytest.skip(f"{path} not found")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        span = read_press(path).span
    assert (span.reference, span.start, span.peak, span.end) == expected
    two = [w for w in caught if issubclass(w.category, video_module.TwoPressesWarning)]
    assert len(two) == (name == "basket_3")


@pytest.mark.parametrize("suffix", [".mov", ".mp4", ".m4v"])
@pytest.mark.parametrize("keep", [0.5, 0.9])
def test_a_quicktime_file_cut_short_is_said_to_be(tmp_path: Path, suffix: str, keep: float):
    """QA: a .mov cut in half (a copy interrupted) was "not a video file FFmpeg can read", with
    no word that it may be cut short: its header is there, its media data and frame index are
    not, and it is said so."""
    good = write_video(tmp_path / f"whole{suffix}", press_frames())
    whole = good.read_bytes()
    path = tmp_path / f"cut{suffix}"
    path.write_bytes(whole[: int(len(whole) * keep)])
    for read in (read_press, read_video):
        with pytest.raises(VideoError) as e:
            read(path)
        assert str(e.value) == (
            f"{path}: cannot decode video: the file looks cut short (copy it again)"
        )
    # cut where a box ends, so that only the frame index (moov, written last) is missing
    mdat = whole.index(b"mdat") - 4
    path.write_bytes(whole[: mdat + int.from_bytes(whole[mdat : mdat + 4], "big")])
    with pytest.raises(VideoError, match="looks cut short"):
        read_video(path)


def test_a_file_ffmpeg_cannot_open_that_is_not_cut_short_keeps_its_words(tmp_path: Path):
    """Random bytes, and a QuickTime header whose box sizes say nothing (0 < size < 8), are not
    called cut short."""
    for name, data in (
        ("random.mov", np.random.default_rng(1).bytes(4000)),
        ("boxes.mov", b"\x00\x00\x00\x04ftyp" + bytes(64)),
    ):
        path = tmp_path / name
        path.write_bytes(data)
        with pytest.raises(VideoError) as e:
            read_video(path)
        assert str(e.value) == f"{path}: cannot decode video: not a video file FFmpeg can read"
