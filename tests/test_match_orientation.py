"""A query turned against a library's items (portrait among landscape) is warned of, once."""

from __future__ import annotations

import json
import os
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from lookfeel.cli import run as cli_run
from lookfeel.config import DataConfig
from lookfeel.data.images import GELSIGHT_SIZE
from lookfeel.index import Library, Matcher
from lookfeel.index.query import (
    bytes_frame_size,
    frame_size,
    orientation_of,
    shape_record,
    warn_orientation,
)
from lookfeel.modality import Modality

from ._library import tiny_library
from ._tiny import write_depth, write_rgb

TURNED = "most likely turned"


@pytest.fixture(scope="module")
def library(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tiny_library(tmp_path_factory, "orientation", shard_size=64)


@pytest.fixture(scope="module")
def matcher(library: Path) -> Matcher:
    return Matcher(Library.open(library))


def _portrait_video(path: Path) -> Path:
    """A press video of 48x64 (portrait) frames."""
    from ._video import PRESS, object_press, write_video

    pytest.importorskip("av")
    frames = np.ascontiguousarray(object_press(1, PRESS, t=14).transpose(0, 2, 1, 3))
    return write_video(path, frames)


def _turned(caught: list[warnings.WarningMessage]) -> list[str]:
    return [str(w.message) for w in caught if TURNED in str(w.message)]


def _match(matcher: Matcher, files: list[Path], modality: Modality) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        matcher.match_files(files, modality, top=2)
    return _turned(caught)


def test_frame_size_reads_headers_of_images_and_videos(tmp_path: Path):
    write_rgb(tmp_path / "p.png", 1, 0, size=(24, 32))
    write_rgb(tmp_path / "l.jpg", 1, 0, size=(40, 30))
    assert frame_size(tmp_path / "p.png") == (24, 32)
    assert frame_size(tmp_path / "l.jpg") == (40, 30)
    assert frame_size(_portrait_video(tmp_path / "press.mp4")) == (48, 64)
    (tmp_path / "junk.mp4").write_bytes(b"\x00\x00\x00\x14ftypqt  " + bytes(64))
    assert frame_size(tmp_path / "junk.mp4") is None  # a video header, nothing behind it
    (tmp_path / "text.png").write_text("not an image", encoding="utf-8")
    assert frame_size(tmp_path / "text.png") is None
    assert frame_size(tmp_path / "missing.png") is None
    assert frame_size(tmp_path) is None
    if hasattr(os, "mkfifo"):
        os.mkfifo(tmp_path / "fifo.png")
        assert frame_size(tmp_path / "fifo.png") is None  # never waited on


def test_an_upload_s_bytes_say_the_size_its_file_says(tmp_path: Path):
    write_rgb(tmp_path / "p.png", 1, 0, size=(24, 32))
    write_rgb(tmp_path / "l.jpg", 1, 0, size=(40, 30))
    video = _portrait_video(tmp_path / "press.mp4")
    for path, size in [
        (tmp_path / "p.png", (24, 32)),
        (tmp_path / "l.jpg", (40, 30)),
        (video, (48, 64)),
    ]:
        assert bytes_frame_size(path.read_bytes()) == frame_size(path) == size
    assert bytes_frame_size(video.read_bytes()[:64]) is None  # a video header, nothing behind it
    assert bytes_frame_size(b"not an image") is None


def test_a_turned_upload_to_serve_is_answered_with_match_s_warning(library: Path, tmp_path: Path):
    """``lookfeel serve`` says of a turned upload what ``lookfeel match`` says of the file, in
    the response's ``warnings`` (with the upload's name), and nothing of a level one."""
    import httpx

    from lookfeel.serve import ServeConfig, background_server, create_app

    write_rgb(tmp_path / "turned.png", 3, 0, size=(24, 32))
    write_rgb(tmp_path / "level.png", 3, 2, size=(32, 24))
    matcher = Matcher(Library.open(library))
    [expected] = _match(matcher, [tmp_path / "turned.png"], Modality.TOUCH)
    app = create_app(Library.open(library), ServeConfig(), matcher)
    with background_server(app) as url:
        answers = {}
        for name in ("turned.png", "level.png"):
            r = httpx.post(
                url + "/api/match",
                data={"modality": "touch", "top": "1"},
                files=[("files", (name, (tmp_path / name).read_bytes(), "image/png"))],
            )
            assert r.status_code == 200, r.text
            answers[name] = r.json()["warnings"]
    assert answers["turned.png"] == [expected.replace(str(tmp_path / "turned.png"), "turned.png")]
    assert answers["level.png"] == []


def test_orientation_is_the_shape_the_model_resizes():
    config = DataConfig()
    assert orientation_of((240, 320), Modality.TOUCH, config) == "portrait"
    assert orientation_of((320, 240), "touch", config) == "landscape"
    assert orientation_of((100, 102), Modality.DEPTH, config) == "square"  # within 3%
    # 960x720 GelSight frames are cropped to their central square (data.touch_crop: auto)
    assert orientation_of(GELSIGHT_SIZE, Modality.TOUCH, config) == "square"
    none = DataConfig(touch_crop="none")
    assert orientation_of(GELSIGHT_SIZE, Modality.TOUCH, none) == "landscape"
    assert orientation_of((320, 240), Modality.TOUCH, DataConfig(touch_crop="center")) == "square"
    assert orientation_of((320, 240), Modality.COLOR, DataConfig(color_crop="center")) == "square"
    assert orientation_of((320, 240), Modality.DEPTH, DataConfig(color_crop="center")) == (
        "landscape"
    )


def test_shape_record_is_the_one_orientation_of_the_files(tmp_path: Path):
    config = DataConfig()
    for i, size in enumerate([(24, 32), (24, 32), (30, 40)]):
        write_rgb(tmp_path / f"p{i}.png", 1, i, size=size)
    portrait = sorted(tmp_path.glob("p*.png"))
    got = shape_record(portrait, Modality.TOUCH, config)
    assert got == {"orientation": "portrait", "size": [24, 32]}  # the most common size
    write_rgb(tmp_path / "l.png", 1, 9, size=(32, 24))
    assert shape_record([*portrait, tmp_path / "l.png"], Modality.TOUCH, config) is None
    assert shape_record([tmp_path / "missing.png"], Modality.TOUCH, config) is None


def test_an_unknown_or_square_record_is_not_checked(tmp_path: Path):
    write_rgb(tmp_path / "l.png", 1, 0, size=(32, 24))
    files = [tmp_path / "l.png"]
    config = DataConfig()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for record in (
            None,
            {},
            {"orientation": "diagonal", "size": [1, 2]},  # a newer lookfeel's
            {"orientation": "square", "size": [24, 24]},
            {"orientation": "landscape", "size": [32, 24]},
        ):
            warn_orientation(files, Modality.TOUCH, record, config, "the library")
    with pytest.warns(UserWarning, match=r"l.png: a landscape touch frame \(32x24\), but the "):
        record = {"orientation": "portrait", "size": "?"}  # a size it cannot read: left out
        warn_orientation(files, Modality.TOUCH, record, config, "the library")


def test_a_library_records_the_shape_of_its_items(library: Path):
    entries = json.loads((library / "manifest.json").read_text(encoding="utf-8"))["modalities"]
    assert entries["touch"]["shape"] == {"orientation": "landscape", "size": [32, 24]}
    assert entries["depth"]["shape"] == {"orientation": "square", "size": [24, 24]}
    assert entries["color"]["shape"] == {"orientation": "square", "size": [24, 24]}


def test_a_turned_touch_query_is_warned_of_once(matcher: Matcher, tmp_path: Path):
    write_rgb(tmp_path / "turned.png", 3, 0, size=(24, 32))
    write_rgb(tmp_path / "also.png", 3, 1, size=(24, 32))
    write_rgb(tmp_path / "level.png", 3, 2, size=(32, 24))
    [message] = _match(matcher, [tmp_path / "turned.png"], Modality.TOUCH)
    assert message == (
        f"{tmp_path / 'turned.png'}: a portrait touch frame (24x32), but the library's touch "
        "presses are landscape (32x24): each is resized to the network's one square input, so "
        "this one is stretched unlike them and most likely turned; turn it to landscape"
    )
    assert "\n" not in message
    files = [tmp_path / "level.png", tmp_path / "turned.png", tmp_path / "also.png"]
    [message] = _match(matcher, files, Modality.TOUCH)  # one warning for the query
    assert message.startswith(f"{tmp_path / 'turned.png'} (and 1 other such file): a portrait")
    assert _match(matcher, [tmp_path / "level.png"], Modality.TOUCH) == []


def test_a_square_library_takes_any_shape(matcher: Matcher, tmp_path: Path):
    write_depth(tmp_path / "d.png", 2, 0)
    Image.fromarray(np.full((30, 20), 1000, np.uint16)).save(tmp_path / "tall.png")
    assert _match(matcher, [tmp_path / "d.png", tmp_path / "tall.png"], Modality.DEPTH) == []


def test_a_turned_press_video_is_warned_of_in_one_line(
    library: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    video = _portrait_video(tmp_path / "press.mp4")
    code = cli_run(["match", str(video), "--index", str(library), "--top", "1"])
    assert code == 0
    turned = [line for line in capsys.readouterr().err.splitlines() if TURNED in line]
    assert turned == [
        f"lookfeel: warning: {video}: a portrait touch video (48x64), but the library's touch "
        "presses are landscape (32x24): each is resized to the network's one square input, so "
        "this one is stretched unlike them and most likely turned; turn it to landscape (or "
        "train with --set data.video_rotate=90 or 270, which turns every press video clockwise "
        "as it is decoded)"
    ]


def test_a_library_from_before_the_record_is_not_checked(library: Path, tmp_path: Path):
    old = tmp_path / "old"
    shutil.copytree(library, old)
    manifest = json.loads((old / "manifest.json").read_text(encoding="utf-8"))
    for entry in manifest["modalities"].values():
        del entry["shape"]
    (old / "manifest.json").write_text(json.dumps(manifest), encoding="utf-8")
    write_rgb(tmp_path / "turned.png", 3, 0, size=(24, 32))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # it opens and matches, warning of nothing
        matcher = Matcher(Library.open(old))
        [r] = matcher.match_files([tmp_path / "turned.png"], Modality.TOUCH, top=1)
    assert len(r.fabrics) == 1


def test_serve_takes_an_upload_for_a_video_by_its_content_as_it_reads_it(
    library: Path, tmp_path: Path
):
    """QA: the orientation note decided "video" by an upload's name while the server reads it
    by its content: the same press video named ``press.bin`` was called a frame, and a PNG
    named ``frame.mp4`` a video (with the advice to turn videos by data.video_rotate). Now
    it is what the server reads it as, whatever its name."""
    import httpx

    from lookfeel.index.query import orientation_note
    from lookfeel.serve import ServeConfig, background_server, create_app

    video = _portrait_video(tmp_path / "press.mp4").read_bytes()
    write_rgb(tmp_path / "frame.png", 3, 0, size=(24, 32))
    frame = (tmp_path / "frame.png").read_bytes()
    matcher = Matcher(Library.open(library))
    answers = {}
    with background_server(create_app(Library.open(library), ServeConfig(), matcher)) as url:
        for name, body in (("press.mov", video), ("press.bin", video), ("frame.mp4", frame)):
            r = httpx.post(
                url + "/api/match",
                data={"modality": "touch", "top": "1"},
                files=[("files", (name, body, "application/octet-stream"))],
            )
            assert r.status_code == 200, (name, r.text)
            [answers[name]] = [w for w in r.json()["warnings"] if TURNED in w]
    assert answers["press.mov"].startswith("press.mov: a portrait touch video (48x64), but ")
    assert "data.video_rotate=90 or 270" in answers["press.mov"]
    assert answers["press.bin"] == answers["press.mov"].replace("press.mov", "press.bin", 1)
    assert answers["frame.mp4"].startswith("frame.mp4: a portrait touch frame (24x32), but ")
    assert "video_rotate" not in answers["frame.mp4"]
    # the same decision passed to the note directly; files on disk by suffix, as read
    record = {"orientation": "landscape", "size": [64, 48]}
    turned = DataConfig(video_rotate=90)
    assert orientation_note([("a.bin", (64, 48))], "touch", record, turned, "it") is None
    note = orientation_note([("a.bin", (64, 48))], "touch", record, turned, "it", videos=[True])
    assert note is not None and "a.bin: a portrait touch video (64x48, 48x64 as " in note
    note = orientation_note([("a.mp4", (64, 48))], "touch", record, turned, "it", videos=[False])
    assert note is None
