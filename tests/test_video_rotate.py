"""``data.video_rotate``: press videos turned as they are decoded, everywhere they are read.

The videos are built with PyAV (`tests._video`): 64x48 (landscape) frames with a known press
(frames 5-9, deepest at 7), so that a turn shows in the shape of what is read.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lookfeel.config import ConfigError, DataConfig, RunConfig, load_config
from lookfeel.data import ImageLoader
from lookfeel.data import images as images_module
from lookfeel.data.catalog import Item
from lookfeel.data.images import PreprocessSettings, preprocess_rgb
from lookfeel.data.video import (
    PRESS_DETECTOR_VERSION,
    PressSpan,
    detect_press,
    read_press,
    read_video,
    rotate_frame,
    small_greyscale,
)
from lookfeel.index.query import orientation_note, seen_size, shape_record
from lookfeel.modality import Modality

pytest.importorskip("av")

from ._video import PRESS, H, W, object_press, write_video

T = 16
CLOCKWISE = {90: -1, 180: 2, 270: 1}
"""``np.rot90``'s ``k`` (counter-clockwise quarter turns) for each clockwise turn."""


@pytest.fixture(scope="module")
def video(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 64x48 (landscape) press video, pressed over frames 5-9."""
    root = tmp_path_factory.mktemp("turned")
    return write_video(root / "press.mp4", object_press(2, PRESS, T))


def _turned(a: np.ndarray, degrees: int, axes: tuple[int, int] = (0, 1)) -> np.ndarray:
    return np.rot90(a, k=CLOCKWISE[degrees], axes=axes)


def test_a_turned_video_reads_as_its_frames_turned_clockwise(video: Path):
    frames = read_video(video)
    assert frames.shape == (T, H, W, 3)
    turned = read_video(video, rotate=90)
    assert turned.shape == (T, W, H, 3)  # landscape 64x48 -> portrait 48x64
    # Clockwise: the top row, left to right, becomes the right column, top to bottom.
    assert np.array_equal(turned[:, :, -1], frames[:, 0, :])
    assert np.array_equal(turned[:, 0, 0], frames[:, -1, 0])  # bottom left -> top left
    for degrees in (90, 180, 270):
        expected = _turned(frames, degrees, axes=(1, 2))
        assert np.array_equal(read_video(video, rotate=degrees), expected), degrees
    assert np.array_equal(read_video(video, rotate=0), frames)
    small = small_greyscale(video)
    assert np.array_equal(small_greyscale(video, rotate=270), _turned(small, 270, axes=(1, 2)))


@pytest.mark.parametrize("degrees", [90, 180, 270])
def test_a_turned_press_is_the_same_press_its_images_turned(video: Path, degrees: int):
    """The press is found on the turned frames (the detector is handed them), and a turn
    changes no frame chosen; the reference and the differences are of turned frames."""
    seen: list[tuple[int, ...]] = []

    def detect(small: np.ndarray, path: Path) -> PressSpan:
        seen.append(small.shape)
        return detect_press(small, path)

    plain = read_press(video, frames=3)
    turned = read_press(video, frames=3, rotate=degrees, detect=detect)
    quarter = degrees != 180
    h, w = small_greyscale(video).shape[1:]
    assert seen == [(T, w, h) if quarter else (T, h, w)]  # the detector sees turned frames
    assert turned.indices == plain.indices
    a, b = plain.span, turned.span
    assert (a.reference, a.start, a.peak, a.end) == (b.reference, b.start, b.peak, b.end)
    assert (a.start, a.peak, a.end) == (5, 7, 10)
    np.testing.assert_allclose(b.strength, a.strength, rtol=1e-5, atol=1e-5)
    assert turned.images.shape == ((3, W, H, 3) if quarter else (3, H, W, 3))
    assert np.array_equal(turned.images, _turned(plain.images, degrees, axes=(1, 2)))
    assert np.array_equal(turned.reference, _turned(plain.reference, degrees))
    raw = read_press(video, subtract_reference=False, rotate=degrees)
    assert np.array_equal(
        raw.images[0], _turned(read_press(video, subtract_reference=False).images[0], degrees)
    )


def test_rotate_frame_and_a_bad_turn():
    a = np.arange(6).reshape(2, 3)  # [[0 1 2], [3 4 5]]
    assert rotate_frame(a, 0) is a
    assert rotate_frame(a, 90).tolist() == [[3, 0], [4, 1], [5, 2]]
    assert rotate_frame(a, 180).tolist() == [[5, 4, 3], [2, 1, 0]]
    assert rotate_frame(a, 270).tolist() == [[2, 5], [1, 4], [0, 3]]
    for bad in (45, -90, 360, 90.0, True):
        with pytest.raises(ValueError, match=r"^rotate must be 0, 90, 180 or 270 \(degrees"):
            rotate_frame(a, bad)  # type: ignore[arg-type]
        with pytest.raises(ValueError, match="rotate must be"):
            read_press("no-such-file.mp4", rotate=bad)  # type: ignore[arg-type]  # before reading


@pytest.mark.parametrize("bad", [45, -90, 360, 1])
def test_a_bad_value_is_one_line_naming_the_key_and_the_value(bad: int):
    message = (
        f"data.video_rotate: {bad} is not a turn of a press video; give 0, 90, 180 or 270 "
        "(degrees clockwise)"
    )
    with pytest.raises(ConfigError) as e:
        DataConfig(video_rotate=bad)  # type: ignore[arg-type]
    assert str(e.value) == message
    with pytest.raises(ConfigError) as e:
        load_config(RunConfig, None, [f"data.video_rotate={bad}"])
    assert str(e.value) == f"--set data.video_rotate={bad}: {message}"
    with pytest.raises(ConfigError, match=r"data.video_rotate: expected an integer, got 'left'$"):
        load_config(RunConfig, None, ["data.video_rotate=left"])
    assert load_config(RunConfig, None, ["data.video_rotate=270"]).data.video_rotate == 270
    assert DataConfig().video_rotate == 0


def _item(path: Path) -> Item:
    return Item(Modality.TOUCH, 1, (path,), None, path.stem)


def test_the_loader_turns_a_press_and_its_cache_never_mixes_turns(
    video: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """Each turn is decoded (and cached) on its own: a press cached unturned is never served
    turned, nor the other way round; the same turn is read back from disk."""
    decoded: list[int] = []

    def counting(*args, **kwargs):
        decoded.append(kwargs.get("rotate", 0))
        return read_press(*args, **kwargs)

    monkeypatch.setattr(images_module, "read_press", counting)
    cache = tmp_path / "cache"
    item = _item(video)
    plain_cfg = DataConfig(image_size=16, touch_crop="none")
    turned_cfg = DataConfig(image_size=16, touch_crop="none", video_rotate=90)
    plain = ImageLoader(plain_cfg, cache_dir=cache).array(video, Modality.TOUCH)
    turned = ImageLoader(turned_cfg, cache_dir=cache).array(video, Modality.TOUCH)
    assert decoded == [0, 90]  # the turned press was decoded, not read from the plain cache
    image = read_press(video).images[0]  # (48, 64, 3): the deepest frame's difference
    assert np.array_equal(plain, preprocess_rgb(image, Modality.TOUCH, plain_cfg))
    assert np.array_equal(turned, preprocess_rgb(_turned(image, 90), Modality.TOUCH, turned_cfg))
    assert not np.array_equal(plain, turned)
    assert len(list(cache.rglob("*.npy"))) == 2
    # Read again from disk, each under its own turn: nothing decoded.
    assert np.array_equal(ImageLoader(turned_cfg, cache_dir=cache).array(video, "touch"), turned)
    assert np.array_equal(ImageLoader(plain_cfg, cache_dir=cache).array(video, "touch"), plain)
    assert decoded == [0, 90]
    # Training views of a press video are turned as its image is.
    views_cfg = DataConfig(image_size=16, touch_crop="none", video_rotate=90, video_views=3)
    views = ImageLoader(views_cfg, cache_dir=cache).views(item)
    assert decoded == [0, 90, 90] and views.shape[1:] == (16, 16, 3)
    assert np.array_equal(views[0], turned)  # the deepest frame first


def test_the_cache_key_holds_the_turn_and_the_detector_version(monkeypatch: pytest.MonkeyPatch):
    def key(**kw) -> str:
        return PreprocessSettings.of(DataConfig(**kw)).digest()

    keys = {key(video_rotate=r) for r in (0, 90, 180, 270)}
    assert len(keys) == 4
    assert PreprocessSettings.of(DataConfig()).press_detector == PRESS_DETECTOR_VERSION
    before = key()
    monkeypatch.setattr(images_module, "PRESS_DETECTOR_VERSION", PRESS_DETECTOR_VERSION + 1)
    assert key() != before  # a new detector: every press decoded again
    assert len({key(video_rotate=r) for r in (0, 90, 180, 270)} | keys) == 8


def test_predict_reads_a_video_with_the_checkpoints_turn(
    video: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """A model trained with a turn keeps it in its checkpoint's data settings, and `predict`
    reads a press video with them: the turned press, not the file as it lies."""
    import warnings

    import torch

    from lookfeel.checkpoint import load_model, save_checkpoint
    from lookfeel.config import ModelConfig, to_dict
    from lookfeel.models import create_model
    from lookfeel.predict import predict_files

    config = RunConfig(
        data=DataConfig(image_size=16, video_rotate=90),
        model=ModelConfig(backbone="compact", width=4, embed_dim=8, num_properties=1),
    )
    torch.manual_seed(0)
    model = create_model(config.model, [Modality.TOUCH], load_weights=False)
    state = {
        "config": to_dict(config),
        "model": model.state_dict(),
        "modalities": ["touch"],
        "label_columns": ["hardness"],
    }
    loaded = load_model(save_checkpoint(tmp_path / "turned.pt", state))
    assert loaded.config.data.video_rotate == 90
    presses = []

    def spying(*args, **kwargs):
        presses.append(read_press(*args, **kwargs))
        return presses[-1]

    monkeypatch.setattr(images_module, "read_press", spying)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        [p] = predict_files(loaded, video, "touch")
    assert p.error is None and p.properties
    [press] = presses
    assert press.images.shape == (1, W, H, 3)
    assert np.array_equal(press.images[0], _turned(read_press(video).images[0], 90))


def test_orientation_is_checked_as_the_model_reads_a_video_and_names_the_option(video: Path):
    """A video is as portrait or landscape as it is once turned (`seen_size`), in a record of
    training items and in a query; the warning about a turned press video names
    ``data.video_rotate``, a frame's does not."""
    plain, turned = DataConfig(), DataConfig(video_rotate=90)
    assert shape_record([video], "touch", plain) == {"orientation": "landscape", "size": [64, 48]}
    assert shape_record([video], "touch", turned) == {"orientation": "portrait", "size": [48, 64]}
    assert seen_size("a.MOV", (64, 48), "touch", turned) == (48, 64)
    assert seen_size("a.png", (64, 48), "touch", turned) == (64, 48)  # frames are not turned
    assert seen_size("a.mp4", (64, 48), "color", turned) == (64, 48)
    assert seen_size("a.mp4", (64, 48), "touch", DataConfig(video_rotate=180)) == (64, 48)
    portrait = {"orientation": "portrait", "size": [48, 64]}
    landscape = {"orientation": "landscape", "size": [64, 48]}
    ok = [("q.mp4", (64, 48))]
    assert orientation_note(ok, "touch", landscape, plain, "the model") is None
    assert orientation_note(ok, "touch", portrait, turned, "the model") is None
    head = "q.mp4: a landscape touch video (64x48), but the model's touch presses are portrait "
    tail = (
        ": each is resized to the network's one square input, so this one is stretched unlike "
        "them and most likely turned; turn it to portrait (or train with --set "
    )
    option = ", which turns every press video clockwise as it is decoded)"
    assert orientation_note(ok, "touch", portrait, plain, "the model") == (
        f"{head}(48x64){tail}data.video_rotate=90 or 270{option}"
    )
    # Turned already: its size as read is said, and the turns from there.
    assert orientation_note(ok, "touch", landscape, turned, "the library") == (
        "q.mp4: a portrait touch video (64x48, 48x64 as data.video_rotate=90 turns it), but the "
        "library's touch presses are landscape (64x48): each is resized to the network's one "
        "square input, so this one is stretched unlike them and most likely turned; turn it to "
        f"landscape (or train with --set data.video_rotate=0 or 180{option}"
    )
    frame = orientation_note([("q.png", (64, 48))], "touch", portrait, turned, "the model")
    assert frame is not None and frame.endswith("turn it to portrait")
    assert "\n" not in frame


def test_the_untouched_control_and_the_leak_report_read_a_press_turned(video: Path):
    # cv's untouched control and `data leakage`'s press images read the video as training
    # does: turned by data.video_rotate.
    from lookfeel.data.leakage import _pool_press, _read_press
    from lookfeel.data.touch_control import untouched_image

    def arrays(config: DataConfig) -> tuple[np.ndarray, ...]:
        press = _read_press(video, config)  # pooled by 1: the press's own pixels
        return _pool_press(press, config.video_gain, press.images.shape[1:3], 1)

    plain, turned = DataConfig(image_size=32), DataConfig(image_size=32, video_rotate=90)
    assert untouched_image(video, turned).shape == (32, 32, 3)
    # The control is made from the no-contact frames turned: not the unturned image's pixels.
    assert not np.array_equal(untouched_image(video, turned), untouched_image(video, plain))
    for a, b in zip(arrays(plain), arrays(turned), strict=True):
        assert b.shape == (W, H, 3)
        assert np.array_equal(b, _turned(a, 90))
