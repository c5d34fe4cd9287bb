"""`lookfeel.predict.predict_files` called from Python: modalities by name, single paths, the
wording of its errors."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest
import torch

from lookfeel.checkpoint import LoadedModel, load_model
from lookfeel.config import RunConfig, load_config
from lookfeel.modality import Modality, ModalityError, PressKind
from lookfeel.predict import PredictError, predict_files
from lookfeel.train import train

from ._library import TINY, train_one_thread

pytestmark = pytest.mark.filterwarnings("ignore:.*probabilities are as trained, not calibrated")

GREY = (  # what a grey press video is warned of
    "the video has no colour (grey); lookfeel reads a press's colours, and a model trained on "
    "colour presses reads a grey one unlike them"
)


@pytest.fixture(scope="module")
def heads(run, tmp_path_factory: pytest.TempPathFactory) -> LoadedModel:
    """`run`'s dataset under a tiny model with a class head (stretchiness), a few steps."""
    data, _ = run
    overrides = ["model.class_heads=[stretchiness]", "train.steps=2", "train.split=none"]
    config = load_config(
        RunConfig, TINY, [*overrides, "train.val_every=0", "train.checkpoint_every=0"]
    )
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # as `tests._library.tiny_run`: faster on a shared CPU
    try:
        result = train(config, data, tmp_path_factory.mktemp("heads") / "run")
    finally:
        torch.set_num_threads(threads)
    return load_model(result.last_checkpoint)


def test_a_modality_by_name_and_a_single_path_are_taken_as_meant(run, heads: LoadedModel):
    data, _ = run
    photo = data / "color/F0003_2.png"
    [want] = predict_files(heads, [photo], Modality.COLOR)
    assert want.modality == "color" and "stretchiness" in want.properties
    for paths in (str(photo), photo):  # one file, not one per character of its name
        assert predict_files(heads, paths, "color") == [want]
    press = data / "touch/F0004_fold_02_400.png"
    [touch] = predict_files(heads, str(press), "touch", together=True)
    assert touch.paths == [str(press)] and touch.modality == "touch"
    with pytest.raises(ModalityError, match="unknown modality 'colour'; expected one of"):
        predict_files(heads, [photo], "colour")
    with pytest.raises(PredictError, match="no input file given"):
        predict_files(heads, [])


def test_errors_name_the_cli_flag_and_the_python_argument(run, heads: LoadedModel, tmp_path: Path):
    data, _ = run
    photo = str(data / "color/F0003_2.png")
    loose = shutil.copy(photo, tmp_path / "F0003_2.png")  # no folder says what it shows
    with pytest.raises(
        PredictError,
        match=r"F0003_2.png: cannot tell .*: say which with --modality depth, color or",
    ):
        predict_files(heads, [loose])
    with pytest.raises(PredictError, match=r"^--together \(together\) pools touch presses"):
        predict_files(heads, [photo, photo], Modality.COLOR, together=True)


def test_a_checkpoint_path_is_loaded_and_a_device_checked_first(run, heads: LoadedModel):
    from lookfeel.devices import DeviceError

    data, _ = run
    photo = data / "color/F0003_2.png"
    [want] = predict_files(heads, photo, "color")
    for path in (heads.path, str(heads.path)):  # as `evaluate_checkpoint` takes it
        assert predict_files(path, photo, "color") == [want]
    with pytest.raises(DeviceError, match="^device 'tpu': not a device torch knows"):
        predict_files(heads, photo, "color", device="tpu")


def test_the_modality_is_guessed_from_the_layouts_folder_or_a_depth_png(
    run, heads: LoadedModel, tmp_path: Path
):
    """QA: a file of the dataset's own touch/ folder needed --modality with a model of three
    senses, and the docstring's "a 16-bit PNG is depth" was not done."""
    from lookfeel.predict import guess_modality

    data, _ = run
    have = list(heads.model.modalities)
    assert len(have) == 3
    for folder, m in (
        ("touch", Modality.TOUCH),
        ("color", Modality.COLOR),
        ("depth", Modality.DEPTH),
    ):
        some = sorted((data / folder).iterdir())[0]
        assert guess_modality(some, have) is m
    depth = shutil.copy(sorted((data / "depth").iterdir())[0], tmp_path / "drape.png")
    assert guess_modality(Path(depth), have) is Modality.DEPTH  # 16-bit greyscale, anywhere
    photo = shutil.copy(data / "color/F0003_2.png", tmp_path / "photo.png")
    with pytest.raises(PredictError, match="cannot tell which modality"):
        guess_modality(Path(photo), have)  # 8-bit RGB outside the layout: it does not say


def test_the_files_folder_decides_its_modality_even_when_the_model_lacks_it(run, tmp_path: Path):
    """QA: with a touch-only model a photo in color/ was read as touch, and a depth map in
    depth/ refused as a still touch image; a folder was "a still image", a GIF "not an image"
    only when the modality was guessed."""
    from lookfeel.data import ImageError
    from lookfeel.predict import guess_modality

    data, _ = run
    touch, both = [Modality.TOUCH], [Modality.DEPTH, Modality.TOUCH]
    with pytest.raises(
        PredictError,
        match=r"F0003_2.png: an image in a color/ folder shows color, which the library does not "
        r"take \(it takes touch\); give --modality touch to read it as touch anyway$",
    ):
        guess_modality(data / "color/F0003_2.png", touch, "the library")
    drape = shutil.copy(data / "depth/F0001_Depth_New_000000.png", tmp_path / "drape.png")
    with pytest.raises(PredictError, match=r"16-bit greyscale PNG is a depth map, which the model"):
        guess_modality(Path(drape), touch)
    with pytest.raises(PredictError, match=r"--modality depth or touch to read it as one of those"):
        guess_modality(data / "color/F0003_2.png", both)
    video = tmp_path / "press.mov"
    video.write_bytes(b"")
    no_touch = (
        r"press.mov: a video is a touch press, which the model does not take \(it takes depth\)$"
    )
    with pytest.raises(PredictError, match=no_touch):  # no --modality: a video is nothing else
        guess_modality(video, [Modality.DEPTH])
    with pytest.raises(ImageError, match=r"touch: is a folder, not an image or video file"):
        guess_modality(data / "touch", both)
    gif = tmp_path / "p.gif"
    gif.write_bytes(b"GIF89a")
    with pytest.raises(ImageError, match=r"p.gif: not a PNG or JPEG image \(.png, .jpg, .jpeg\)"):
        guess_modality(gif, both)
    # A file that is not there is said so, not read as its folder's modality (QA).
    with pytest.raises(ImageError, match=r"nothere.jpg: file not found$"):
        guess_modality(data / "color/nothere.jpg", touch)
    assert guess_modality(data / "touch/F0004_fold_02_400.png", touch) is Modality.TOUCH


def test_a_gif_or_webp_is_refused_as_serve_refuses_it_and_a_folder_is_named_one(
    run, heads: LoadedModel, tmp_path: Path
):
    """One list of query images (PNG and JPEG, by content) in the CLI and the server; a folder
    given as touch is a folder, not "a still image". A file refused for its content is its
    query's error (as any input that cannot be read)."""
    from PIL import Image

    data, _ = run
    photo = Image.open(data / "color/F0003_2.png")
    for name, kind in (("p.gif", "GIF"), ("p.webp", "WebP"), ("gif.png", "GIF")):
        photo.save(tmp_path / name, format="GIF" if kind == "GIF" else "WEBP")
        [answer] = predict_files(heads, tmp_path / name, "color")
        assert answer.properties == {} and answer.error is not None
        assert re.match(rf".*{name}: is a {kind} image, not a PNG or JPEG", answer.error)
    folder = r".*touch: is a folder, not a press: give a press's video or its frame files$"
    [answer] = predict_files(heads, data / "touch", "touch")  # its own query's error, as any
    assert answer.properties == {} and re.match(folder, answer.error or "")


def test_a_still_frame_model_warns_of_a_press_video(run, heads: LoadedModel, tmp_path: Path):
    """A model trained on still frames takes a video (as documented), with a warning: the video
    is read as a difference image, which it never saw."""
    pytest.importorskip("av")
    from lookfeel.checkpoint import TOUCH_FRAMES
    from lookfeel.index.query import VIDEO_FOR_STILL_MODEL

    from ._video import PRESS, object_press, write_video

    assert heads.touch_input == TOUCH_FRAMES
    video = write_video(tmp_path / "press.mov", object_press(1, PRESS, t=14))
    with pytest.warns(UserWarning, match=rf"press.mov: {re.escape(VIDEO_FOR_STILL_MODEL)}"):
        [answer] = predict_files(heads, video)
    assert answer.modality == "touch" and answer.error is None and answer.properties


def test_a_frames_stacking_model_refuses_a_press_video_saying_what_to_give(
    run, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    """QA: `Matcher.match_files("press.mov", "touch")` (and `predict_files`) with a model that
    stacks a press's frame images (data.touch_frames) first warned "give a still frame of the
    press", then failed with "this press is a video", which said nothing of what to do. Now one
    error, no warning: give the press's frame images, or train on videos."""
    import warnings

    from lookfeel.cli import main
    from lookfeel.data import ImageError
    from lookfeel.index import Library, Matcher, build_library

    data, _ = run
    sets = ["data.touch_frames=[0,1,2]", "model.class_heads=[stretchiness]", "train.steps=2"]
    sets += ["train.split=none", "train.val_every=0", "train.checkpoint_every=0"]
    result = train_one_thread(load_config(RunConfig, TINY, sets), data, tmp_path / "run")
    loaded = load_model(result.last_checkpoint)
    assert loaded.config.data.stacks_touch_frames
    lib = tmp_path / "lib"
    build_library(result.last_checkpoint, data, lib, calibration_queries=20)
    matcher = Matcher(Library.open(lib))
    video = tmp_path / "mine" / "press.mov"  # refused by its name, before it is decoded
    video.parent.mkdir()
    video.write_bytes(b"not decoded")
    said = (
        f"{video}: this model reads frames [0, 1, 2] of each press stacked together, from the "
        "press's frame images (data.touch_frames), and a video has none: give the press's "
        "frame images, named F<id>_<kind>_<frame>_<press>.<ext> side by side, or train a "
        "model on press videos (data.touch_frames=[])"
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no warning before the error
        warnings.filterwarnings("ignore", ".*probabilities are as trained, not calibrated")
        with pytest.raises(ImageError) as e:
            matcher.match_files(str(video), "touch")
        assert str(e.value) == said
        # predict answers each input: this one with its error, the same line
        for answers in (predict_files(loaded, video, "touch"), predict_files(loaded, [video])):
            assert [(a.error, a.properties) for a in answers] == [(said, {})]
        frame = data / "touch" / "F0003_fold_02_300.png"  # a press's frame: its others beside
        [r] = matcher.match_files(frame, "touch", top=2)
        assert len(r.fabrics) == 2
    capsys.readouterr()
    assert main(["match", "--index", str(lib), "--modality", "touch", str(video)]) == 1
    assert capsys.readouterr().err.strip().splitlines() == [f"lookfeel: {said}"]


def test_a_column_of_ranks_without_a_class_head_is_answered_as_its_nearest_rank(
    run, tmp_path: Path
):
    # The tiny labels: stiffness is fabric id % 5 (ranks 0-4), thickness_mm 0.5 x id (numbers).
    data, _ = run
    config = load_config(
        RunConfig,
        TINY,
        ["model.num_properties=auto", "train.steps=2", "train.split=none", "train.val_every=0"],
    )
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        result = train(config, data, tmp_path / "run")
    finally:
        torch.set_num_threads(threads)
    loaded = load_model(result.last_checkpoint)
    assert loaded.rank_columns == {"stiffness": (0, 1, 2, 3, 4), "stretchiness": (0, 1)}
    [p] = predict_files(loaded, [data / "color/F0003_2.png"], "color")
    stiff, thick = p.properties["stiffness"], p.properties["thickness_mm"]
    assert isinstance(stiff.number, float) and stiff.probability is None
    assert stiff.value == min(range(5), key=lambda r: (abs(r - stiff.number), r))
    assert isinstance(thick.value, float) and thick.number is None


def test_a_press_of_a_kind_the_model_was_not_trained_on_is_warned_of_once(
    run, heads: LoadedModel, tmp_path_factory: pytest.TempPathFactory
):
    """QA: a flat press given to `predict` and `match` with a model (and library) trained on
    fold presses only was answered without a word. One line, naming the first such press and
    counting the rest; presses of the trained kind, or whose name says no kind, are not."""
    import warnings

    from lookfeel.index import Library, Matcher
    from lookfeel.index.match import press_kind

    from ._library import tiny_library

    data, _ = run
    flat = [data / "touch" / f"F000{f}_flat_02_{100 * f}.png" for f in (1, 2, 3)]
    fold = data / "touch" / "F0001_fold_02_100.png"
    assert [press_kind(p) for p in (flat[0], fold, "press.mp4", "x/image_flat/a.png")] == [
        PressKind.FLAT,
        PressKind.FOLD,
        None,
        PressKind.FLAT,
    ]
    said = (
        f"{flat[0]} (and 2 other such presses): a flat press, but the model was trained on fold "
        "presses only (its data.touch_kinds), so it may answer a flat press less well"
    )
    with pytest.warns(UserWarning) as caught:
        predict_files(heads, flat, "touch")
    assert [str(w.message) for w in caught if "trained on fold" in str(w.message)] == [said]
    assert {w.filename for w in caught} == {__file__}  # the caller's line, not torch's
    matcher = Matcher(Library.open(tiny_library(tmp_path_factory, "kinds", 64)))
    with pytest.warns(UserWarning) as caught:
        matcher.match_files(flat[:1], "touch")
    assert [str(w.message) for w in caught if "trained on fold" in str(w.message)] == [
        f"{flat[0]}: a flat press, but the library's model was trained on fold presses only "
        "(its data.touch_kinds), so it may answer a flat press less well"
    ]
    assert {w.filename for w in caught} == {__file__}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.filterwarnings("ignore", ".*probabilities are as trained, not calibrated")
        predict_files(heads, [fold], "touch")
        matcher.match_files([fold], "touch")


TURNED = "most likely turned"


def _turned(call) -> list[str]:
    """The turned-query warnings ``call()`` gives."""
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        call()
    return [str(w.message) for w in caught if TURNED in str(w.message)]


def test_a_query_turned_against_the_training_items_is_warned_of_once(
    run, heads: LoadedModel, tmp_path: Path
):
    """A checkpoint records the shape of each modality's training items (the tiny touch frames
    are 32x24, landscape; depth and colour 24x24), and `predict` warns once of a portrait
    touch query, naming the first turned file and counting the rest (as `lookfeel match`)."""
    from ._tiny import write_rgb

    landscape = {"orientation": "landscape", "size": [32, 24]}
    square = {"orientation": "square", "size": [24, 24]}
    assert heads.shapes == {
        Modality.TOUCH: landscape,
        Modality.DEPTH: square,
        Modality.COLOR: square,
    }
    write_rgb(tmp_path / "turned.png", 3, 0, size=(24, 32))
    write_rgb(tmp_path / "also.png", 3, 1, size=(24, 32))
    write_rgb(tmp_path / "level.png", 3, 2, size=(32, 24))
    turned = tmp_path / "turned.png"
    assert _turned(lambda: predict_files(heads, turned, "touch")) == [
        f"{turned}: a portrait touch frame (24x32), but the model's touch presses are "
        "landscape (32x24): each is resized to the network's one square input, so this one is "
        "stretched unlike them and most likely turned; turn it to landscape"
    ]
    files = [tmp_path / "level.png", turned, tmp_path / "also.png"]
    [message] = _turned(lambda: predict_files(heads, files, "touch"))
    assert message.startswith(f"{turned} (and 1 other such file): a portrait touch frame")
    [message] = _turned(lambda: predict_files(heads, files, "touch", together=True))
    assert message.startswith(f"{turned} (and 1 other such file)")
    assert _turned(lambda: predict_files(heads, tmp_path / "level.png", "touch")) == []
    # Colour was trained on square images: a query of any shape is not checked against them.
    photo = tmp_path / "color" / "tall.png"
    write_rgb(photo, 3, 0, size=(24, 40))
    assert _turned(lambda: predict_files(heads, photo)) == []


def test_a_checkpoint_from_before_the_shape_record_predicts_without_the_warning(
    heads: LoadedModel, tmp_path: Path
):
    import warnings

    from lookfeel.checkpoint import read_checkpoint, save_checkpoint

    from ._tiny import write_rgb

    state = read_checkpoint(heads.path)
    del state["shapes"]
    old = load_model(save_checkpoint(tmp_path / "old.pt", state))
    assert old.shapes == {}
    turned = tmp_path / "turned.png"
    write_rgb(turned, 3, 0, size=(24, 32))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.filterwarnings("ignore", ".*probabilities are as trained, not calibrated")
        [p] = predict_files(old, turned, "touch")
    assert "stretchiness" in p.properties
    # A record this version cannot read (a newer lookfeel's) is left out, not refused.
    state["shapes"] = {"smell": {"orientation": "landscape"}, "touch": "landscape"}
    assert load_model(save_checkpoint(tmp_path / "newer.pt", state)).shapes == {}


def test_a_resumed_run_and_an_ensemble_keep_the_shape_record(
    run, heads: LoadedModel, tmp_path: Path
):
    """The record survives a resumed run's checkpoints and an ensemble's merged checkpoint
    (which also keeps the ranks of the columns of ranks)."""
    from lookfeel.checkpoint import read_checkpoint

    data, _ = run
    run_dir = shutil.copytree(heads.path.parents[1], tmp_path / "resumed")
    config = load_config(RunConfig, run_dir / "config.yaml", ["train.steps=3"])
    ensemble = load_config(
        RunConfig,
        TINY,
        ["model.members=2", "train.steps=1", "train.split=none", "train.val_every=0"],
    )
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # as `heads` trained: a resumed run warns of another count
    try:
        resumed = train(config, data, run_dir, resume=True)
        merged = train(ensemble, data, tmp_path / "ensemble")
    finally:
        torch.set_num_threads(threads)
    state = read_checkpoint(resumed.last_checkpoint)
    assert state["step"] == 3
    assert load_model(resumed.last_checkpoint).shapes == heads.shapes
    loaded = load_model(merged.last_checkpoint)
    assert loaded.config.model.members == 2
    assert loaded.shapes == heads.shapes
    assert loaded.rank_columns == {"stiffness": (0, 1, 2, 3, 4), "stretchiness": (0, 1)}


def test_an_input_that_cannot_be_decoded_is_its_own_error_and_the_others_are_answered(
    run, heads: LoadedModel, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    """QA: one empty video (or a PNG renamed .mp4) among `lookfeel predict`'s inputs aborted the
    whole batch with one line, --json included, while a video without a press was already its
    own "error". Now any input that cannot be read is answered so, naming it; the exit status is
    1 only when no input could be answered, as for a video without a press."""
    import json

    pytest.importorskip("av")
    from lookfeel.cli import main

    from ._video import PRESS, object_press, write_video

    data, _ = run
    photo = str(data / "color/F0003_2.png")
    damaged = tmp_path / "color" / "damaged.png"
    damaged.parent.mkdir()
    damaged.write_bytes(Path(photo).read_bytes()[:60])  # a PNG cut short
    good, broken = predict_files(heads, [photo, damaged], "color")
    assert good == predict_files(heads, photo, "color")[0]  # answered as if alone
    assert broken.properties == {} and broken.error == f"{damaged}: file is truncated"
    empty = tmp_path / "empty.mp4"
    empty.write_bytes(b"")
    image = tmp_path / "image.mp4"
    image.write_bytes(Path(photo).read_bytes())  # a PNG renamed
    ckpt = str(heads.path)
    with pytest.warns(UserWarning):  # a still-frame model warns of videos
        code = main(["predict", "--checkpoint", ckpt, photo, str(empty), str(image), "--json"])
    assert code == 0
    out = capsys.readouterr()
    answers = json.loads(out.out)
    assert [a["path"] for a in answers] == [photo, str(empty), str(image)]
    assert answers[0]["error"] is None and answers[0]["properties"]
    assert answers[1]["properties"] == {}
    assert answers[1]["error"] == f"{empty}: cannot decode video: file is empty"
    assert answers[2]["error"].startswith(f"{image}: cannot decode video: the file is an image")
    assert len(out.err.strip().splitlines()) == 2  # one warning line each
    with pytest.warns(UserWarning):
        assert main(["predict", "--checkpoint", ckpt, str(empty), str(image)]) == 1
    assert capsys.readouterr().out.splitlines() == [
        f"{empty}: cannot decode video: file is empty (nothing predicted)",
        f"{image}: cannot decode video: the file is an image (png_pipe), not a video "
        "(nothing predicted)",
    ]
    # Presses given together: the pooled query's error names the file that failed.
    press = write_video(tmp_path / "press.mov", object_press(1, PRESS, t=14))
    with pytest.warns(UserWarning):
        [pooled] = predict_files(heads, [press, image], "touch", together=True)
    assert pooled.paths == [str(press), str(image)] and pooled.properties == {}
    assert pooled.error is not None and pooled.error.startswith(f"{image}: cannot decode video")
    assert pooled.error.endswith("; it is one of the 2 presses given together")


def test_a_grey_press_video_is_answered_with_one_warning_naming_it(
    heads: LoadedModel, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    """QA: a grey press video was answered silently, and unlike the colour video of the same
    press. It is still answered, with one warning line naming it, on stderr (`--json` carries
    no warnings); a colour video, or a grey one that holds no press (its own error), gets none.
    """
    import json
    import warnings

    pytest.importorskip("av")
    from lookfeel.cli import run as cli_run

    from ._video import PRESS, object_press, write_video

    frames = object_press(1, PRESS, t=14)
    colour = write_video(tmp_path / "colour.mov", frames)
    grey = write_video(tmp_path / "grey.mkv", frames, "ffv1", "gray")
    also = write_video(tmp_path / "also.mkv", object_press(2, PRESS, t=14), "ffv1", "gray")
    unpressed = write_video(tmp_path / "unpressed.mkv", object_press(1, {}, t=14), "ffv1", "gray")

    def grey_lines(paths: list[Path], together: bool = False) -> list[str]:
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            answers = predict_files(heads, paths, together=together)
        assert all(a.properties for a in answers if str(unpressed) not in a.paths)
        return [str(w.message) for w in said if "no colour" in str(w.message)]

    assert grey_lines([colour, grey, unpressed]) == [f"{grey}: {GREY}"]
    assert grey_lines([grey, also], together=True) == [f"{grey} (and 1 other grey video): {GREY}"]
    assert grey_lines([colour]) == []

    capsys.readouterr()
    assert cli_run(["predict", "--checkpoint", str(heads.path), str(grey), "--json"]) == 0
    out = capsys.readouterr()
    [answer] = json.loads(out.out)
    assert answer["path"] == str(grey) and answer["error"] is None and answer["properties"]
    assert f"lookfeel: warning: {grey}: {GREY}" in out.err.splitlines()


def test_a_query_video_is_decoded_once_whether_grey_or_not(
    heads: LoadedModel, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """Whether a press video is grey is known from the decoding that reads its press: asking
    again decoded one more frame of a colour or one-channel video, and the whole of a grey one
    stored as colour."""
    import warnings

    pytest.importorskip("av")
    from ._video import count_decoded_frames, grey_and_colour_presses

    colour, grey, stored = grey_and_colour_presses(tmp_path).values()
    decoded = count_decoded_frames(monkeypatch)  # frames decoded, by file
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        answers = predict_files(heads, [colour, grey, stored], "touch")
    assert all(a.properties for a in answers)
    assert [str(w.message) for w in said if "no colour" in str(w.message)] == [
        f"{grey}: {GREY}",
        f"{stored}: {GREY}",
    ]
    assert decoded == {"colour.mov": 14, "grey.mkv": 14, "stored.mov": 14}  # each frame once


def test_a_missing_file_is_its_own_inputs_error_and_the_others_are_answered(
    run, heads: LoadedModel, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    """QA: `predict nope.jpg photo.png` stopped the whole batch at the missing file, though
    an unreadable one was already its own input's error."""
    import json

    from lookfeel.cli import main

    data, _ = run
    photo = data / "color/F0003_2.png"
    missing = tmp_path / "nope.png"
    gone, answered = predict_files(heads, [missing, photo], "color")
    assert gone.error == f"{missing}: file not found" and gone.properties == {}
    assert gone.modality == "color"  # as asked
    assert answered.error is None and answered.properties
    [unasked] = predict_files(heads, [missing])  # nothing to guess a modality from
    assert unasked.error == f"{missing}: file not found" and unasked.modality is None
    capsys.readouterr()
    argv = ["predict", "--checkpoint", str(heads.path), str(missing), str(photo), "--json"]
    assert main(argv) == 0  # one input answered
    out = capsys.readouterr()
    assert out.err.splitlines() == [
        f"lookfeel: warning: {missing}: file not found; nothing predicted for it"
    ]
    assert [a["error"] for a in json.loads(out.out)] == [f"{missing}: file not found", None]
    assert main(["predict", "--checkpoint", str(heads.path), str(missing)]) == 1  # none answered


def test_match_gives_each_property_as_predict_gives_it(
    run, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    """One shape for a property everywhere (issue #13's contract): `match --json`'s
    ``properties`` (and ``serve``'s) was a list of {name, mean, ...} where `predict --json`'s is
    label -> {value, probability, probabilities, number}. Now match gives each label
    predict's fields, in predict's order and of its kinds (a number, a class in the column's own
    terms), its spread ``std`` and count ``fabrics`` beside; and names its files as predict."""
    import json

    from lookfeel.cli import main
    from lookfeel.index import build_library

    data, _ = run
    sets = ["model.class_heads=[stretchiness]", "model.num_properties=auto", "train.steps=2"]
    sets += ["train.split=none", "train.val_every=0", "train.checkpoint_every=0"]
    result = train_one_thread(load_config(RunConfig, TINY, sets), data, tmp_path / "run")
    lib = tmp_path / "lib"
    build_library(result.last_checkpoint, data, lib, calibration_queries=20)
    photo = str(data / "color/F0003_2.png")
    capsys.readouterr()
    assert main(["predict", "--checkpoint", str(result.last_checkpoint), photo, "--json"]) == 0
    [predicted] = json.loads(capsys.readouterr().out)
    assert main(["match", "--index", str(lib), photo, "--json"]) == 0
    [matched] = json.loads(capsys.readouterr().out)
    for key in ("path", "paths", "error"):
        assert matched[key] == predicted[key]
    # stretchiness: a class head / a class; thickness_mm: a number; stiffness: a rank
    assert isinstance(matched["properties"], dict)
    both = set(predicted["properties"]) & set(matched["properties"])
    assert {"stretchiness", "thickness_mm", "stiffness"} <= both
    for label, p in predicted["properties"].items():
        m = matched["properties"][label]
        assert list(m) == [*p, "std", "fabrics"], label
        assert type(m["value"]) is type(p["value"]), label  # int rank, float number
        if p["probabilities"]:  # a class head's classes (a rank regressed has none)
            assert set(m["probabilities"]) == set(p["probabilities"]), label
    stretch = matched["properties"]["stretchiness"]
    assert stretch["probability"] == max(stretch["probabilities"].values())
