"""`lookfeel data check` on press videos: what runs warn of a video is a warning of the file,
and a video whose first frames look pressed among its object's others is one too."""

import warnings
from pathlib import Path

import numpy as np
import pytest

from lookfeel.cli import main
from lookfeel.data import check_dataset
from lookfeel.data.video import TruncatedVideoWarning, TwoPressesWarning, read_press

from ._tiny import write_recordings
from ._video import (
    PRESS,
    PRESSED_START,
    TWO_PRESSES,
    another_session,
    cut_in_half,
    object_press,
    write_video,
)

pytest.importorskip("av")

OBJECTS = ("cork", "egg", "felt", "silk", "wool")


def _dataset(root: Path, per_object: int = 3) -> Path:
    """``per_object`` press videos of each of `OBJECTS`, recorded alike (one session)."""
    labels = "object\n" + "\n".join(OBJECTS) + "\n"
    root = write_recordings(root, {}, labels)
    for k, name in enumerate(OBJECTS):
        for n in range(per_object):
            write_video(root / "videos" / f"{name}_{n}.mov", object_press(k, PRESS, 14, seed=n))
    return root


def _warned(root: Path, workers: int = 1) -> dict[Path, str]:
    """``data check``'s warnings of ``root``, by file."""
    return {p.path: p.message for p in check_dataset(root, workers=workers).warnings}


@pytest.mark.parametrize("workers", [1, 2])
def test_a_truncated_video_and_one_of_two_presses_are_warnings_naming_them(
    tmp_path: Path, workers: int
):
    """QA: a .mkv cut in half passed `data check` ("OK") while train and predict said "video
    is truncated"; a video of two presses passed silently while they warned "more than one
    press". Each is now a warning of the file, in threads as in one, and no longer a Python
    warning (shown once more on stderr) instead."""
    root = _dataset(tmp_path / "rec")  # 15 videos: with 2 more, decoded in threads
    cut = cut_in_half(write_video(root / "videos" / "egg_3.mkv", object_press(1, PRESS, 40)))
    two = write_video(root / "videos" / "felt_3.mov", object_press(2, TWO_PRESSES, 24))
    with warnings.catch_warnings(record=True) as shown:
        warnings.simplefilter("always")
        said = _warned(root, workers)
    assert said[cut].startswith("video is truncated: ")
    assert said[cut].endswith(
        "frames) it declares; runs read those: copy the whole file again, or record it again"
    )
    assert said[two].startswith("more than one press: frames 5-9 (the deepest, used) and 15-18")
    assert set(said) == {cut, two}
    assert not [w for w in shown if issubclass(w.category, TruncatedVideoWarning)]
    assert not [w for w in shown if issubclass(w.category, TwoPressesWarning)]


def test_the_cli_lists_them_as_warnings_and_prints_them_once(tmp_path: Path, capsys):
    root = _dataset(tmp_path / "rec", per_object=1)
    cut = cut_in_half(write_video(root / "videos" / "egg_3.mkv", object_press(1, PRESS, 40)))
    assert main(["data", "check", str(root), "--no-leakage", "--quiet"]) == 0
    out, err = capsys.readouterr()
    assert f"WARNING  {cut}: video is truncated: " in out
    assert "OK: 0 error(s), 1 warning(s)." in out
    assert "truncated" not in err
    assert main(["data", "check", str(root), "--no-leakage", "--quiet", "--strict"]) == 1
    # The leak check decodes the videos again: what the check said is not said once more.
    root = _dataset(tmp_path / "leaks", per_object=2)  # two a fabric: the leak check runs
    cut = cut_in_half(write_video(root / "videos" / "egg_3.mkv", object_press(1, PRESS, 40)))
    capsys.readouterr()
    with warnings.catch_warnings(record=True) as shown:
        warnings.simplefilter("always")
        main(["data", "check", str(root), "--quiet"])
    out, err = capsys.readouterr()
    assert f"WARNING  {cut}: video is truncated: " in out
    assert "truncated" not in err
    assert not [w for w in shown if issubclass(w.category, TruncatedVideoWarning)]


def test_a_video_whose_first_frames_look_pressed_is_a_warning_naming_its_object(tmp_path: Path):
    """QA: a video in contact from its first frame, held still (egg frames 40-70), passed
    `data check` silently: the press detector took pressed frames for the untouched gel. Among
    the other videos of its object it looks pressed: a warning naming it and its object."""
    root = _dataset(tmp_path / "rec")
    assert _warned(root) == {}  # videos recorded alike: nothing to say
    pressed = write_video(root / "videos" / "egg_3.mov", object_press(1, PRESSED_START, 14))
    read_press(pressed)  # the press detector accepts it
    said = _warned(root)
    assert list(said) == [pressed]
    assert said[pressed].startswith(
        "its first frames look pressed compared with the other videos of egg: once a change of "
        "the whole frame's light is removed, they differ from theirs by "
    )
    assert said[pressed].endswith(
        "and runs read its press against a pressed gel: record from before the press, or "
        "leave this video out"
    )
    from lookfeel.data.check import PRESSED_START_LEVELS

    change = float(said[pressed].split(" by ")[1].split(" grey levels")[0])
    assert change > 3 * PRESSED_START_LEVELS
    # two videos of an object: each is compared with the other, and told from the other
    # objects' (the untouched one is like theirs)
    for n in (1, 2):
        (root / "videos" / f"egg_{n}.mov").unlink()
    assert list(_warned(root)) == [pressed]


def test_a_video_recorded_in_another_session_is_no_warning(tmp_path: Path):
    """PhysiCLeAR's ``wood_ruler_5`` and three others were recorded in another session than
    their object's other videos (another light: unlike theirs), and in the session of other
    objects' videos: like those, so not pressed."""
    from lookfeel.data.check import PRESSED_START_LEVELS, _light_change, _small_reference

    root = _dataset(tmp_path / "rec")
    for n in range(3):  # silk's videos: another session
        frames = another_session(object_press(3, PRESS, 14, seed=n))
        write_video(root / "videos" / f"silk_{n}.mov", frames)
    other = write_video(
        root / "videos" / "egg_3.mov", another_session(object_press(1, PRESS, 14, seed=3))
    )
    egg = [_small_reference(read_press(root / "videos" / f"egg_{n}.mov")) for n in range(3)]
    change = _light_change(np.median(egg, axis=0), _small_reference(read_press(other)))[0]
    assert change > 3 * PRESSED_START_LEVELS  # unlike egg's other videos ...
    assert _warned(root) == {}  # ... like silk's
    for n in range(3):  # no video like it: it looks pressed
        (root / "videos" / f"silk_{n}.mov").unlink()
    (root / "labels.csv").write_text(
        "object\n" + "\n".join(o for o in OBJECTS if o != "silk"), encoding="utf-8"
    )
    assert list(_warned(root)) == [other]
