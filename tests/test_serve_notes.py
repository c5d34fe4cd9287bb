"""What ``lookfeel serve`` says of an upload as ``lookfeel match`` says it of a file: its
warnings answered in ``warnings`` (not lost on the server's stderr), a depth map of holes and a
video given as an image refused in one line, the page's words as the CLI's."""

from __future__ import annotations

import io
import warnings
from pathlib import Path

import httpx
import numpy as np
import pytest
from PIL import Image

from lookfeel.config import DataConfig
from lookfeel.data.images import ImageError
from lookfeel.index import Library, Matcher, load_query_bytes
from lookfeel.index.query import (
    NO_VALID_DEPTH,
    VIDEO_FOR_STILL_MODEL,
    load_query_image,
)
from lookfeel.modality import Modality
from lookfeel.serve import ServeConfig, background_server, create_app

from .test_serve import _video_library


def _png16(a: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(a.astype(np.uint16)).save(buf, format="PNG")
    return buf.getvalue()


def test_an_upload_gets_the_warnings_match_gives(run, tmp_path: Path):
    """A press video to the tiny model (trained on still frames) and a flat press to a model
    trained on fold presses: both warnings come back in ``warnings``, as ``lookfeel match``
    warns of the same file, and none goes to the server's warnings."""
    lib = _video_library(run, tmp_path)
    pressed = tmp_path / "data" / "videos" / "spoon_1.mov"
    flat = tmp_path / "F0007_flat_1000.mov"
    flat.write_bytes(pressed.read_bytes())
    matcher = Matcher(Library.open(lib))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        matcher.match_files([flat], Modality.TOUCH, top=3)
    expected = sorted(str(w.message).replace(str(flat), flat.name) for w in caught)
    assert any(VIDEO_FOR_STILL_MODEL in w for w in expected)
    assert any("a flat press, but the library's model was trained on fold" in w for w in expected)
    with background_server(create_app(Library.open(lib), ServeConfig(), matcher)) as url:
        with warnings.catch_warnings(record=True) as on_server:
            warnings.simplefilter("always")
            r = httpx.post(
                url + "/api/match",
                data={"modality": "touch", "top": "3"},
                files=[("files", (flat.name, flat.read_bytes(), "video/quicktime"))],
            )
        assert r.status_code == 200, r.text
        assert sorted(r.json()["warnings"]) == expected
        assert not [w for w in on_server if flat.name in str(w.message)]


def test_a_depth_map_of_holes_only_is_refused(run, server_url, tmp_path: Path):
    holes = tmp_path / "holes.png"
    holes.write_bytes(_png16(np.zeros((24, 32))))
    config = DataConfig()
    with pytest.raises(ImageError) as e:
        load_query_image(holes, Modality.DEPTH, config)
    assert str(e.value) == f"{holes}: {NO_VALID_DEPTH}"
    with pytest.raises(ImageError, match=r"^holes\.png: the depth map has no valid pixel"):
        load_query_bytes(holes.read_bytes(), "holes.png", Modality.DEPTH, config)
    r = httpx.post(
        server_url + "/api/match",
        data={"modality": "depth"},
        files=[("files", ("holes.png", holes.read_bytes(), "image/png"))],
    )
    assert r.status_code == 422
    assert r.json()["detail"] == (
        "holes.png: the depth map has no valid pixel (every pixel is 0, no reading)"
    )
    # Beside a depth map that can be matched, it is its own query's error, as `lookfeel match`
    # answers it, and the other is matched.
    data, _ = run
    good = data / "depth/F0003_Depth_New_000001.png"
    r = httpx.post(
        server_url + "/api/match",
        data={"modality": "depth"},
        files=[
            ("files", ("holes.png", holes.read_bytes(), "image/png")),
            ("files", (good.name, good.read_bytes(), "image/png")),
        ],
    )
    assert r.status_code == 200, r.text
    failed, matched = r.json()["results"]
    assert failed["paths"] == ["holes.png"] and failed["fabrics"] == []
    assert failed["error"] == (
        "holes.png: the depth map has no valid pixel (every pixel is 0, no reading)"
    )
    assert matched["error"] is None and matched["fabrics"][0]["fabric_id"] == 3
    one = np.zeros((24, 32))
    one[3, 4] = 700  # one reading is a map
    assert load_query_bytes(_png16(one), "one.png", Modality.DEPTH, config).shape[0] == 1


def test_a_video_given_as_an_image_says_videos_are_touch(server_url, tmp_path: Path):
    video = b"\x00\x00\x00\x18ftypmp42" + bytes(64)
    for modality in ("depth", "color"):
        r = httpx.post(
            server_url + "/api/match",
            data={"modality": modality},
            files=[("files", ("t7.mp4", video, "video/mp4"))],
        )
        assert r.status_code == 415
        assert r.json()["detail"] == (
            "t7.mp4: not a PNG or JPEG image (videos are read as touch only)"
        )
    path = tmp_path / "t7.mp4"
    path.write_bytes(video)
    with pytest.raises(ImageError, match=r"a video \(videos are read as touch only\)"):
        load_query_image(path, Modality.COLOR, DataConfig())


def test_a_stacking_model_refuses_a_video_upload_without_warning_first():
    from lookfeel.checkpoint import TOUCH_FRAMES

    config = DataConfig(touch_frames=(0, 1), video_reference="subtract")
    assert config.stacks_touch_frames
    notes: list[str] = []
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any warning fails the test
        with pytest.raises(ImageError, match="data.touch_frames"):
            load_query_bytes(
                b"\x00\x00\x00\x14ftypqt  " + bytes(64),
                "t7.mov",
                Modality.TOUCH,
                config,
                trained_on=TOUCH_FRAMES,
                warn=notes.append,
            )
    assert notes == []


def test_the_page_says_what_its_properties_are_and_previews_videos_by_name(server_url):
    js = httpx.get(server_url + "/static/app.js").text
    assert "Predicted properties" not in js  # the heads' answer is `lookfeel predict`'s
    assert "likeliest ${noun}s" in js and "weighted by P" in js
    assert "isVideo(f)" in js and "toPrecision(digits)))" in js


@pytest.fixture(scope="module")
def server_url(run, tmp_path_factory: pytest.TempPathFactory):
    from lookfeel.index import build_library

    data, ckpt = run
    out = tmp_path_factory.mktemp("notes") / "lib"
    build_library(ckpt, data, out, shard_size=64)
    with background_server(create_app(Library.open(out), ServeConfig())) as url:
        yield url


def test_far_from_every_object_is_no_known_object(run, tmp_path: Path):
    """A library of named objects says "no known object", as its properties line does."""
    from lookfeel.index import format_match

    matcher = Matcher(Library.open(_video_library(run, tmp_path)))
    table = matcher.library.table(Modality.TOUCH)
    far = table.embeddings.mean(axis=0) + 100.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = matcher.match_embedding(far, Modality.TOUCH, ["far"], top=2, gallery=Modality.TOUCH)
    assert not r.known and r.message.startswith("no known object: the best match, ")
    assert "No known object" in format_match(r) and "fabric:" not in r.message


def test_a_grey_press_video_upload_is_answered_with_one_note_naming_it(run, tmp_path: Path):
    """QA: ``lookfeel match`` warned of a press video with no colour (grey), and ``serve``
    answered the same upload silently. It is still answered, with the line ``lookfeel match``
    warns of the same files in ``warnings`` (of several, the first grey one named and the
    others counted), which the page shows as a note; a colour video gets none."""
    from lookfeel.index.match import GREY_VIDEO

    from ._video import PRESS, object_press, write_video

    lib = _video_library(run, tmp_path)
    frames = object_press(1, PRESS, t=14)
    equal = np.repeat(frames.mean(axis=-1, keepdims=True).astype(np.uint8), 3, axis=-1)
    colour = write_video(tmp_path / "colour.mov", frames)
    grey = write_video(tmp_path / "grey.mkv", frames, "ffv1", "gray")  # one channel
    stored = write_video(tmp_path / "stored.mov", equal)  # red, green and blue equal
    matcher = Matcher(Library.open(lib))

    def match_says(paths: list[Path]) -> list[str]:
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            matcher.match_files(paths, Modality.TOUCH, top=2)
        lines = [str(w.message) for w in said if GREY_VIDEO in str(w.message)]
        for p in paths:  # the server names the client's file, not a path
            lines = [line.replace(str(p), p.name) for line in lines]
        return lines

    with background_server(create_app(Library.open(lib), ServeConfig(), matcher)) as url:

        def serve_says(paths: list[Path]) -> list[str]:
            with warnings.catch_warnings(record=True) as on_server:
                warnings.simplefilter("always")
                r = httpx.post(
                    url + "/api/match",
                    data={"modality": "touch", "top": "2"},
                    files=[("files", (p.name, p.read_bytes(), "video/mp4")) for p in paths],
                )
            assert r.status_code == 200, r.text
            [result] = r.json()["results"]
            assert result["paths"] == [p.name for p in paths] and len(result["fabrics"]) == 2
            assert not [w for w in on_server if GREY_VIDEO in str(w.message)]
            return [w for w in r.json()["warnings"] if GREY_VIDEO in w]

        assert serve_says([grey]) == [f"grey.mkv: {GREY_VIDEO}"] == match_says([grey])
        assert serve_says([colour]) == [] == match_says([colour])
        several = [colour, stored, grey]
        said = serve_says(several)
        assert said == [f"stored.mov (and 1 other grey video): {GREY_VIDEO}"] == match_says(several)
        page = httpx.get(url + "/static/app.js").text  # the page shows each line as a note
        assert "(data.warnings || []).map((w) => ` Note: ${w}.`)" in page


def test_a_touch_upload_that_is_no_video_is_not_told_videos_are_touch(server_url):
    """QA: a text file named ``notes.mp4`` sent as touch was told "(videos are read as touch
    only)", which it was sent as; that hint is for depth and colour."""
    from lookfeel.data.files import VIDEO_SUFFIXES

    for modality, hint in (("touch", ""), ("depth", " (videos are read as touch only)")):
        r = httpx.post(
            server_url + "/api/match",
            data={"modality": modality},
            files=[("files", ("notes.mp4", b"just some text, not a video", "video/mp4"))],
        )
        assert r.status_code == 415
        videos = f" or a video ({', '.join(VIDEO_SUFFIXES)})" if modality == "touch" else ""
        assert r.json()["detail"] == f"notes.mp4: not a PNG or JPEG image{videos}{hint}"
