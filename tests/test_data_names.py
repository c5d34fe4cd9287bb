"""Names as QA found them in real folders: spelt in another case, copied files, a lowercase
``f``, and a sense that only some fabrics have."""

import shutil
from pathlib import Path

import pytest

from lookfeel.cli import main
from lookfeel.data import DatasetError, scan
from lookfeel.data.layout import duplicate_files
from lookfeel.modality import Modality

from ._tiny import write_tiny_dataset

MP4 = b"\x00\x00\x00\x18ftypmp42"
"""The first bytes of an MP4 (all the scan reads); a suffix makes each video's bytes its own."""


def _videos(root: Path, names: list[str], labels: str) -> Path:
    """``videos/<name>`` for each of ``names``, each of its own bytes, and labels.csv."""
    (root / "videos").mkdir(parents=True)
    (root / "labels.csv").write_text(labels, encoding="utf-8")
    for i, name in enumerate(names):
        (root / "videos" / name).write_bytes(MP4 + bytes([i]) * 64)
    return root


def test_object_names_differing_only_in_case_are_a_warning_naming_them(tmp_path: Path):
    """QA: ``egg_0.mov``, ``Egg_0.mov`` and ``EGG_1.mov`` silently made three objects, so one
    physical object could sit on both sides of a held-out split. They still are three (names
    are case-sensitive, as labels.csv's are), with one warning naming them; ``egg_0.mov`` and
    ``Egg_0.mov`` have a warning of their own as files (session 57): macOS and Windows cannot
    hold both in one folder."""
    root = _videos(
        tmp_path / "rec",
        ["egg_0.mov", "Egg_0.mov", "EGG_1.mov", "ball_0.mov"],
        "object,hardness\negg,1\nEgg,1\nEGG,1\nball,0\n",
    )
    catalog = scan(root)
    assert sorted(f.display_name for f in catalog.fabrics) == ["EGG", "Egg", "ball", "egg"]
    assert [(p.path, p.severity, p.message) for p in catalog.problems] == [
        (
            root / "videos",
            "warning",
            "'Egg_0.mov' and 'egg_0.mov' differ only in case: they cannot both exist on macOS "
            "or Windows, where a copy of this folder keeps one; rename one if they are "
            "different",
        ),
        (
            root / "videos",
            "warning",
            "objects 'EGG', 'Egg' and 'egg' differ only in case, so they are 3 objects (a "
            "split may train on one and hold out another); rename their files alike if they "
            "are one",
        ),
    ]


def test_a_row_differing_only_in_case_is_named_where_an_object_has_no_row(tmp_path: Path):
    """QA: a labels row ``Egg`` and files ``egg_*`` said "object 'egg' has no row" and "object
    'Egg' is in labels.csv but has no video", with no hint that the other exists."""
    root = _videos(
        tmp_path / "rec", ["egg_0.mov", "egg_1.mov", "ball_0.mov"], "object\nEgg\nball\n"
    )
    catalog = scan(root)
    assert [(p.path, p.line, p.message) for p in catalog.problems] == [
        (
            root / "videos" / "egg_0.mov",
            None,
            "object 'egg' (2 item(s)) has no row in labels.csv (labels.csv has row 'Egg': "
            "names are case-sensitive; write them alike if they are one)",
        ),
        (
            root / "labels.csv",
            2,
            "object 'Egg' is in labels.csv but has no video (the videos name 'egg': names are "
            "case-sensitive; write them alike if they are one)",
        ),
    ]
    # Without a near spelling, the words are as they were.
    (root / "labels.csv").write_text("object\nball\n", encoding="utf-8")
    assert [p.message for p in scan(root).problems] == [
        "object 'egg' (2 item(s)) has no row in labels.csv"
    ]


def test_byte_identical_files_are_a_warning_naming_both(tmp_path: Path):
    """QA: Finder's ``F0002_2 copy.png`` and a press saved twice (``egg_3.mp4`` = ``egg_0.mov``)
    counted as items of their own with no word, so a query could "find" its own copy. They are
    still items, and `duplicate_files` (``lookfeel data check``) names both; files of the same
    size only are read, so the scan itself costs nothing more."""
    root = write_tiny_dataset(
        tmp_path / "t", fabrics=3, drapes=2, fold_presses=1, flat_presses=0, frames=2
    )
    color = root / "color"
    shutil.copy(color / "F0002_2.png", color / "F0002_2 copy.png")
    shutil.copy(color / "F0001_1.png", color / "F0003_9.png")
    catalog = scan(root)
    assert catalog.problems == ()  # the scan reads names and headers only
    assert [(p.path, p.severity, p.message) for p in duplicate_files(catalog.fabrics)] == [
        (
            color / "F0002_2 copy.png",
            "warning",
            "the same bytes as color/F0002_2.png, also of fabric 2: one image counted twice, so "
            "a query can find its own copy; delete one",
        ),
        (
            color / "F0003_9.png",
            "warning",
            "the same bytes as color/F0001_1.png, of fabric 1, but named as fabric 3's here: one "
            "image counted twice, under two names; delete the wrong one",
        ),
    ]

    videos = _videos(tmp_path / "rec", ["egg_0.mov", "ball_0.mov"], "object\negg\nball\n")
    shutil.copy(videos / "videos" / "egg_0.mov", videos / "videos" / "egg_3.mp4")
    (warning,) = duplicate_files(scan(videos).fabrics)
    assert (warning.path, warning.message) == (
        videos / "videos" / "egg_3.mp4",
        "the same bytes as videos/egg_0.mov, also of object 'egg': one video counted twice, so "
        "a query can find its own copy; delete one",
    )
    # A press of frames is a copy when every frame is.
    touch = root / "touch"
    for frame in (1, 2):
        shutil.copy(touch / f"F0001_fold_0{frame}_100.png", touch / f"F0001_fold_0{frame}_1000.png")
    press = [p for p in duplicate_files(scan(root).fabrics) if p.path.parent == touch]
    assert [(p.path.name, p.message) for p in press] == [
        (
            "F0001_fold_01_1000.png",
            "the same frames, byte for byte, as the press of touch/F0001_fold_01_100.png, also of "
            "fabric 1: one press counted twice, so a query can find its own copy; delete one",
        )
    ]
    (touch / "F0001_fold_02_1000.png").write_bytes((touch / "F0002_fold_02_200.png").read_bytes())
    assert [p for p in duplicate_files(scan(root).fabrics) if p.path.parent == touch] == []


def test_a_lowercase_f_names_a_fabric_in_depth_and_colour_as_in_touch_and_labels(
    tmp_path: Path,
):
    """QA: ``f0001_1.jpg`` was refused ("must begin F<id>_") though labels.csv reads ``f0001``
    and a touch file's name is read in any case (``f0001_fold_01_100.png``)."""
    root = write_tiny_dataset(tmp_path / "t", fabrics=3, drapes=1, fold_presses=1, flat_presses=0)
    for folder in ("color", "depth", "touch"):
        for p in (root / folder).glob("F0001_*"):
            p.rename(p.with_name("f" + p.name[1:]))
    catalog = scan(root)
    assert catalog.problems == ()
    f1 = catalog.fabric(1)
    assert [it.path.name for it in f1.items[Modality.COLOR]] == ["f0001_1.png"]
    assert [it.path.name for it in f1.items[Modality.DEPTH]] == ["f0001_Depth_New_000000.png"]
    assert f1.labels["thickness_mm"] == 0.5
    (root / "color" / "x0001_2.png").write_bytes((root / "color" / "f0001_1.png").read_bytes())
    assert [p.message for p in scan(root).errors] == [
        "color file name must begin F<id>_ (e.g. F0012_1.png)"
    ]


def test_a_sense_some_fabrics_lack_says_which_train_views_train_without_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    """QA: `train` stopped with "4 of the 8 fabrics (3, 6, 7, 8) have no color item" and no
    fix, though ``--set "train.views=[depth,touch]"`` trains. The line now gives it: the
    senses every fabric has (one sense twice: a Siamese run), or the items to add."""
    data = write_tiny_dataset(tmp_path / "partial", 8, drapes=2, fold_presses=2, flat_presses=0)
    for f in (3, 6, 7, 8):
        for p in (data / "color").glob(f"F{f:04d}_*"):
            p.unlink()
    line = (
        f"{data / 'color'}: 4 of the 8 fabrics (3, 6, 7, 8) have no color item; every fabric has "
        'depth and touch: --set "train.views=[depth,touch]" trains without color, or add their '
        "color items"
    )
    with pytest.raises(DatasetError) as info:
        scan(data, require=list(Modality), strict=True)
    assert str(info.value) == line
    argv = ["train", "--config", "tiny", "--data", str(data), "--out", str(tmp_path / "r")]
    assert main(argv) == 1
    assert capsys.readouterr().err.strip().splitlines() == [f"lookfeel: {line}"]
    quick = ["--set", "train.steps=2", "--set", "train.val_every=0"]
    assert main([*argv, "--set", "train.views=[depth,touch]", *quick]) == 0
    capsys.readouterr()

    # A catalog's own check (`Catalog.require`, a training split's) gives the same fix.
    with pytest.raises(DatasetError) as info:
        scan(data, require=[]).subset([1, 3, 6, 7, 8]).require([Modality.COLOR])
    assert str(info.value) == line.replace("4 of the 8", "4 of the 5")

    # Without a run's needs (`data check`), the line says what it said; one fabric: "its".
    assert scan(data).errors[0].message == (
        "4 of the 8 fabrics (3, 6, 7, 8) have no color item (other fabrics have; a run that "
        "uses it cannot)"
    )
    for p in (data / "depth").glob("F0002_*"):
        p.unlink()
    (depth,) = [p.message for p in scan(data, require=[Modality.DEPTH]).errors]
    assert depth == (
        'fabric 2 has no depth item; every fabric has touch: --set "train.views=[touch,touch]" '
        "trains without depth, or add its depth items"
    )
    # No sense that every fabric has: the items to add.
    shutil.rmtree(data / "touch")
    errors = [p.message for p in scan(data, require=[Modality.DEPTH, Modality.COLOR]).errors]
    assert errors[0] == (
        "fabric 2 has no depth item; add its depth items (no sense is held by every fabric)"
    )
