"""Decoding and preprocessing: the authors' conventions, holes, crops, errors, caching."""

import threading
import warnings
from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from lookfeel.config import DataConfig
from lookfeel.data import (
    ImageError,
    ImageLoader,
    decode_depth,
    decode_rgb,
    depth_to_unit,
    fill_holes,
    scan,
)
from lookfeel.data import images as images_module
from lookfeel.data.images import preprocess_depth, preprocess_rgb
from lookfeel.modality import Modality


def test_depth_mapping_matches_the_authors():
    d = np.array([[0, 700, 800], [1050, 1300, 1500]], np.uint16)
    np.testing.assert_allclose(depth_to_unit(d), [[0, 0, 0], [0.5, 1, 1]])


def test_fill_holes_takes_the_nearest_valid_pixel():
    d = np.array([[3, 0, 0, 0, 0, 9], [3, 0, 0, 0, 0, 9]], np.uint16)
    np.testing.assert_array_equal(fill_holes(d), [[3, 3, 3, 9, 9, 9]] * 2)
    assert d[0, 1] == 0  # the input is not modified
    assert np.array_equal(fill_holes(np.zeros((2, 2), np.uint16)), np.zeros((2, 2)))


def test_depth_holes_are_filled_or_clipped():
    d = np.full((8, 8), 1050, np.uint16)
    d[0, 0] = 0
    nearest = preprocess_depth(d, DataConfig(image_size=8))
    clip = preprocess_depth(d, DataConfig(image_size=8, depth_holes="clip"))
    assert nearest[0, 0] == pytest.approx(0.5)
    assert clip[0, 0] == 0.0  # the authors' mapping: 0 mm is below 800 mm


def test_gelsight_frames_are_centre_cropped_only_at_960x720():
    frame = np.zeros((720, 960, 3), np.uint8)
    frame[:, :120] = 255  # a white band left of the central 720x720
    cfg = DataConfig(image_size=24)
    assert preprocess_rgb(frame, Modality.TOUCH, cfg).max() == 0  # auto: band cropped away
    none = DataConfig(image_size=24, touch_crop="none")
    assert preprocess_rgb(frame, Modality.TOUCH, none)[:, 0].min() == 255
    mini = np.zeros((240, 320, 3), np.uint8)
    mini[:, :40] = 255  # GelSight Mini frames stay whole under auto
    assert preprocess_rgb(mini, Modality.TOUCH, cfg)[:, 0].min() == 255
    assert (
        preprocess_rgb(mini, Modality.TOUCH, DataConfig(image_size=24, touch_crop="center")).max()
        == 0
    )
    assert (
        preprocess_rgb(frame, Modality.COLOR, cfg)[:, 0].min() == 255
    )  # colour: no crop by default


def test_touch_zoom_reads_the_central_part_of_the_field_at_the_network_size():
    mini = np.zeros((240, 320, 3), np.uint8)
    mini[60:180, 80:240] = 255  # the central half of the field in each direction
    zoomed = preprocess_rgb(mini, Modality.TOUCH, DataConfig(image_size=24, touch_zoom=0.5))
    whole = preprocess_rgb(mini, Modality.TOUCH, DataConfig(image_size=24))
    assert zoomed.shape == whole.shape == (24, 24, 3)
    assert zoomed.min() == 255  # all of it is the central half
    assert whole[0].max() == 0 and whole[12, 12].min() == 255
    # Pillow images and arrays give the same bytes; the zoom is part of the cache key.
    pil = preprocess_rgb(
        Image.fromarray(mini), Modality.TOUCH, DataConfig(image_size=24, touch_zoom=0.5)
    )
    assert np.array_equal(pil, zoomed)
    digest = images_module.PreprocessSettings.of
    assert digest(DataConfig(touch_zoom=0.5)).digest() != digest(DataConfig()).digest()
    assert digest(DataConfig(touch_zoom=1.0)).digest() == digest(DataConfig()).digest()
    # Only touch is zoomed.
    colour = preprocess_rgb(mini, Modality.COLOR, DataConfig(image_size=24, touch_zoom=0.5))
    assert np.array_equal(colour, preprocess_rgb(mini, Modality.COLOR, DataConfig(image_size=24)))


def test_color_size_sets_the_photo_alone_and_keys_the_cache():
    photo = np.zeros((256, 256, 3), np.uint8)
    photo[:, 128:] = 255
    cfg = DataConfig(image_size=24, color_size=40)
    assert cfg.size_of(Modality.COLOR) == 40 and cfg.size_of(Modality.TOUCH) == 24
    colour = preprocess_rgb(photo, Modality.COLOR, cfg)
    assert colour.shape == (40, 40, 3)
    assert colour[:, :19].max() == 0 and colour[:, 21:].min() == 255  # resized, not cropped
    assert preprocess_rgb(photo, Modality.TOUCH, cfg).shape == (24, 24, 3)
    assert preprocess_depth(np.full((32, 32), 1000.0, np.float32), cfg).shape == (24, 24)
    digest = images_module.PreprocessSettings.of
    assert digest(cfg).digest() != digest(DataConfig(image_size=24)).digest()
    # Unset, it is left out of the key: caches written before the setting existed still hit.
    unset = digest(DataConfig(image_size=24))
    assert unset.color_size is None and "color_size" not in {
        k for k, v in unset.__dict__.items() if v is not None
    }


def test_decode_errors_name_the_file(tmp_path: Path):
    good = tmp_path / "F1_a.png"
    Image.fromarray(np.full((32, 32), 1000, np.uint16)).save(good)
    truncated = tmp_path / "F1_b.png"
    truncated.write_bytes(good.read_bytes()[:60])
    with pytest.raises(ImageError, match="F1_b.png: file is truncated"):
        decode_depth(truncated)
    eight = tmp_path / "F1_c.png"
    Image.fromarray(np.zeros((4, 4), np.uint8)).save(eight)
    with pytest.raises(ImageError, match="F1_c.png: depth image is mode L; expected 16-bit"):
        decode_depth(eight)
    with pytest.raises(ImageError, match="mode I;16 .*expected 8-bit RGB"):
        decode_rgb(good)
    with pytest.raises(ImageError, match="F1_x.png: file not found"):
        decode_rgb(tmp_path / "F1_x.png")
    assert decode_depth(good).dtype == np.uint16
    grey = tmp_path / "g.png"
    Image.fromarray(np.zeros((4, 5), np.uint8)).save(grey)
    assert decode_rgb(grey).shape == (4, 5, 3)


def test_loader_shapes_and_touch_frame_choice(tiny_dataset: Path, tiny_config: DataConfig):
    catalog = scan(tiny_dataset)
    loader = ImageLoader(tiny_config)
    depth = loader.load(catalog.items(Modality.DEPTH)[0])
    color = loader.load(catalog.items(Modality.COLOR)[0])
    press = catalog.items(Modality.TOUCH)[0]
    touch = loader.load(press)
    assert depth.shape == (1, 16, 16) and depth.dtype == torch.float32
    assert color.shape == touch.shape == (3, 16, 16)
    assert float(depth.min()) >= 0.0 and float(color.max()) <= 1.0
    assert loader.frame_path(press) == press.frames[-2]


def test_touch_frames_stack_a_press_s_frames_as_channels_in_order(
    tiny_dataset: Path, tmp_path: Path
):
    catalog = scan(tiny_dataset)
    press = catalog.items(Modality.TOUCH)[0]
    one = ImageLoader(DataConfig(image_size=16))
    first = one.array(press.frames[0], Modality.TOUCH)
    last = one.array(press.frames[-1], Modality.TOUCH)
    assert not np.array_equal(first, last)
    config = DataConfig(image_size=16, touch_frames=(0, -1))
    stacked = ImageLoader(config, cache_dir=tmp_path / "cache")
    assert stacked.frame_path(press) == press.frames[-1]  # the key: the last listed
    a = stacked.array(stacked.frame_path(press), Modality.TOUCH)
    assert a.shape == (16, 16, 6)
    assert np.array_equal(a[..., :3], first) and np.array_equal(a[..., 3:], last)
    assert stacked.load(press).shape == (6, 16, 16)
    # A frame file given as such (a query) is read with the frames beside it of its press.
    assert np.array_equal(ImageLoader(config).embed_file(press.frames[-1], Modality.TOUCH), a)
    # Cached on disk under both frames' contents: a second loader reads the same array.
    again = ImageLoader(config, cache_dir=tmp_path / "cache")
    assert np.array_equal(again.array(again.frame_path(press), Modality.TOUCH), a)
    assert len(list((tmp_path / "cache").rglob("*.npy"))) == 1


def test_touch_frames_warn_once_of_presses_with_fewer_frames(tiny_dataset: Path):
    presses = scan(tiny_dataset).items(Modality.TOUCH)  # 3 frames each
    enough = ImageLoader(DataConfig(image_size=16, touch_frames=(0, 1, 2)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for press in presses:
            enough.frame_path(press)
    short = ImageLoader(DataConfig(image_size=16, touch_frames=(0, 2, 3)))
    with pytest.warns(UserWarning, match=r"reads frames \[0, 2, 3\] of each press, and .* has 3"):
        for press in presses:
            short.frame_path(press)
    with warnings.catch_warnings():  # said once for the loader, not once a press
        warnings.simplefilter("error")
        short.frame_path(presses[0])
    # A press of 4 frames read from the end needs 4.
    with pytest.warns(UserWarning, match=r"reads frames \[-4, -1\]"):
        ImageLoader(DataConfig(image_size=16, touch_frames=(-4, -1))).frame_path(presses[0])


def test_touch_frames_refuse_a_file_whose_press_is_unknown_and_a_video(tmp_path: Path):
    lone = tmp_path / "press.png"
    Image.fromarray(np.full((24, 32, 3), 90, np.uint8)).save(lone)
    loader = ImageLoader(DataConfig(image_size=16, touch_frames=(0, -1)))
    with pytest.raises(ImageError, match=r"press\.png: data\.touch_frames reads frames \[0, -1\]"):
        loader.embed_file(lone, Modality.TOUCH)
    with pytest.raises(ImageError, match=r"F0001_fold_01_7\.png: file not found"):
        loader.embed_file(tmp_path / "F0001_fold_01_7.png", Modality.TOUCH)
    video = tmp_path / "F0001_fold_01_1.mov"
    video.write_bytes(b"\x00\x00\x00\x14ftypqt  ")
    with pytest.raises(ImageError, match=r"F0001_fold_01_1\.mov: .*this press is a video"):
        loader.embed_file(video, Modality.TOUCH)


def test_loader_decodes_each_file_once_and_returns_copies(
    tiny_dataset: Path, tiny_config: DataConfig, monkeypatch: pytest.MonkeyPatch
):
    catalog = scan(tiny_dataset)
    calls = []
    real = images_module.decode_depth
    monkeypatch.setattr(images_module, "decode_depth", lambda p, *a: calls.append(p) or real(p, *a))
    loader = ImageLoader(tiny_config)
    items = catalog.items(Modality.DEPTH)
    assert loader.preload(items) == len(items)
    assert loader.preload(items) == 0
    x = loader.load(items[0])
    x.mul_(0)  # a caller's in-place change must not reach the cache
    assert loader.load(items[0]).abs().sum() > 0
    assert len(calls) == len(items)


def test_disk_cache_is_keyed_by_settings(tiny_dataset: Path, tmp_path: Path):
    catalog = scan(tiny_dataset)
    item = catalog.items(Modality.DEPTH)[0]
    cache = tmp_path / "cache"
    a = ImageLoader(DataConfig(image_size=16), cache_dir=cache).load(item)
    b = ImageLoader(DataConfig(image_size=16), cache_dir=cache).load(item)  # from disk
    c = ImageLoader(DataConfig(image_size=20), cache_dir=cache).load(item)
    assert torch.equal(a, b) and c.shape == (1, 20, 20)
    assert len(list(cache.rglob("*.npy"))) == 2
    assert not list(cache.rglob("*.tmp"))
    # QA (upgrading): each settings' folder says what it holds, so an unused one can be told
    # and deleted (its name is only a digest)
    import json

    from lookfeel.data.images import CACHE_SETTINGS

    said = {
        f.parent.name: json.loads(f.read_text(encoding="utf-8"))
        for f in cache.glob(f"*/{CACHE_SETTINGS}")
    }
    assert {d["settings"]["image_size"] for d in said.values()} == {16, 20}
    assert all("can be deleted" in d["what"] for d in said.values())


@pytest.mark.parametrize(
    ("size", "modality", "image_size"),
    [
        ((960, 720), Modality.TOUCH, 32),  # GelSight: centre-cropped, then resized
        ((320, 240), Modality.TOUCH, 24),  # a Mini's frame: resized whole
        ((40, 30), Modality.COLOR, 16),
        ((16, 16), Modality.COLOR, 16),  # already the network's size: kept as it is
    ],
)
def test_preprocessing_a_pillow_image_gives_the_bytes_of_its_array(
    tmp_path: Path, size: tuple[int, int], modality: Modality, image_size: int
):
    rng = np.random.default_rng(sum(size))
    path = tmp_path / "F1_x.png"
    Image.fromarray(rng.integers(0, 256, (size[1], size[0], 3), dtype=np.uint8)).save(path)
    config = DataConfig(image_size=image_size, color_crop="center")
    from_array = preprocess_rgb(decode_rgb(path), modality, config)
    from_image = preprocess_rgb(images_module.open_rgb(path), modality, config)
    assert from_array.shape == (image_size, image_size, 3) and from_array.flags.writeable
    np.testing.assert_array_equal(from_image, from_array)


def test_a_modality_given_by_name_is_preprocessed_as_its_member():
    cfg = DataConfig(image_size=32, color_size=48)
    photo = np.random.default_rng(0).integers(0, 255, (60, 80, 3), np.uint8)
    assert cfg.size_of("color") == 48 and preprocess_rgb(photo, "color", cfg).shape == (48, 48, 3)
    frame = np.zeros((720, 960, 3), np.uint8)
    frame[:, :120] = 255  # a white band left of the central 720x720: cropped away as touch
    assert np.array_equal(
        preprocess_rgb(frame, "touch", cfg), preprocess_rgb(frame, Modality.TOUCH, cfg)
    )
    assert preprocess_rgb(frame, "touch", cfg).max() == 0
    from lookfeel.modality import ModalityError

    with pytest.raises(ModalityError, match="unknown modality 'colour'; expected one of"):
        preprocess_rgb(photo, "colour", cfg)
    with pytest.raises(ModalityError, match="'colour'"):
        cfg.size_of("colour")


@pytest.fixture
def catch_warnings_threads(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The name of the thread of each use of ``warnings.catch_warnings`` during the test (it is
    replaced by a stand-in that records that, then does what it does)."""
    threads: list[str] = []
    real = warnings.catch_warnings

    class Recording:
        def __init__(self, *args, **kwargs) -> None:
            self._real = real(*args, **kwargs)

        def __enter__(self):
            threads.append(threading.current_thread().name)
            return self._real.__enter__()

        def __exit__(self, *exc) -> None:
            self._real.__exit__(*exc)

    monkeypatch.setattr(warnings, "catch_warnings", Recording)
    return threads


def test_threaded_decoding_leaves_the_warnings_filters_alone(
    tiny_dataset: Path, catch_warnings_threads: list[str]
):
    # ``warnings.catch_warnings`` swaps the process's filters: in two decoding threads at once
    # one thread's "ignore" can outlive both (Python < 3.14). Decoding must never use it.
    catalog = scan(tiny_dataset)
    items = [it for m in catalog.modalities for it in catalog.items(m)]
    before = list(warnings.filters)
    for _ in range(3):
        loader = ImageLoader(DataConfig(image_size=16, workers=4, decode="threads"), cache_dir=None)
        assert loader.preload(items) > 8  # enough files to decode in the thread pool
    assert warnings.filters == before
    assert [t for t in catch_warnings_threads if t != "MainThread"] == []


@pytest.mark.filterwarnings("error")  # a warning fails the decode
def test_a_decompression_bomb_is_refused_without_a_warning_or_a_filter(
    tmp_path: Path, catch_warnings_threads: list[str]
):
    from ._tiny import bomb_png

    bomb = tmp_path / "bomb.png"
    bomb.write_bytes(bomb_png(13000, 13000))  # beyond Pillow's own limit: it would warn
    with pytest.raises(ImageError, match="image declares 13000x13000"):
        decode_rgb(bomb)
    assert catch_warnings_threads == []


def test_declared_size_reads_png_and_jpeg_headers_alone():
    import io

    from lookfeel.data.images import declared_size

    a = np.random.default_rng(0).integers(0, 255, (13, 21, 3), np.uint8)
    for fmt, options in [("PNG", {}), ("JPEG", {}), ("JPEG", {"progressive": True})]:
        buf = io.BytesIO()
        Image.fromarray(a).save(buf, fmt, exif=Image.Exif(), **options)
        assert declared_size(buf.getvalue()) == (21, 13)
        assert declared_size(buf.getvalue()[:10]) is None  # too short to say
    buf = io.BytesIO()
    Image.fromarray(a).save(buf, "BMP")
    assert declared_size(buf.getvalue()) is None  # another format: Pillow says


def test_a_blank_depth_image_s_note_goes_with_its_entries_to_another_loader(tmp_path: Path):
    """A decoding worker's loader notes a depth image with no valid pixel and does not warn of
    it (`ImageLoader.decode_one`: the caller's loader warns once of all, `BlankDepthWarning`);
    `take` hands the note over with the image, and `adopt` keeps it. A depth image with a
    valid pixel carries no note."""
    from lookfeel.data.catalog import Item
    from lookfeel.data.images import BlankDepthWarning

    blank, valid = tmp_path / "F0001_Depth_New_000000.png", tmp_path / "F0001_Depth_New_000001.png"
    Image.fromarray(np.zeros((24, 24), np.uint16)).save(blank)
    Image.fromarray(np.full((24, 24), 1000, np.uint16)).save(valid)
    worker = ImageLoader(DataConfig(image_size=16), cache_dir=None)
    with warnings.catch_warnings():
        warnings.simplefilter("error", BlankDepthWarning)
        worker.decode_one(Item(Modality.DEPTH, 1, (blank,)))
        worker.decode_one(Item(Modality.DEPTH, 1, (valid,)))
    entries = worker.take(blank)
    assert set(entries) == {"image", "blank"} and bool(entries["blank"])
    assert not entries["image"].any()  # read as a blank input
    assert set(worker.take(valid)) == {"image"}
    parent = ImageLoader(DataConfig(image_size=16), cache_dir=None)
    parent.adopt(blank, entries)
    assert set(parent.take(blank)) == {"image", "blank"}
