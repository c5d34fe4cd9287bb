"""`lookfeel data info` (`format_summary`, `Catalog.summary`): what it says about datasets that
`data check` fails, labels it cannot read, and named objects."""

import json
import re
from pathlib import Path

import pytest

from lookfeel.cli import main
from lookfeel.data import scan

from ._tiny import write_recordings, write_tiny_dataset


def _info(root: Path, capsys: pytest.CaptureFixture[str]) -> str:
    assert main(["data", "info", str(root)]) == 0
    return capsys.readouterr().out


def _info_json(root: Path, capsys: pytest.CaptureFixture[str]) -> dict[str, object]:
    assert main(["data", "info", str(root), "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_info_on_a_videos_folder_reports_check_s_error_and_no_empty_ids(tmp_path: Path, capsys):
    # The user gave ROOT/videos instead of ROOT: info used to print "fabrics 0 (ids )" and
    # "0 errors" while `data check` failed.
    labels = "object,hardness\nsponge,0\ncork,1\n"
    videos = write_recordings(tmp_path / "rec", {"sponge": 2}, labels) / "videos"
    out = _info(videos, capsys)
    assert "(ids )" not in out
    assert re.search(r"^  fabrics +0$", out, re.M)
    assert re.search(
        r"^  error +no usable image found: .* holds 2 press video\(s\) directly "
        r"\(e\.g\. sponge_0\.mov\); they belong in .*videos/videos/ \(is this the videos/ "
        r"folder\? give its parent\)$",
        out,
        re.M,
    )
    assert re.search(r"^  problems +1 error, 0 warnings in names and headers", out, re.M)
    assert _info_json(videos, capsys)["errors"] == 1


def test_info_on_one_fabric_reports_what_check_reports(tmp_path: Path, capsys):
    one = write_tiny_dataset(tmp_path / "one", fabrics=1, drapes=1)
    out = _info(one, capsys)
    assert re.search(r"^  fabrics +1 \(ids 1\)$", out, re.M)
    assert re.search(r"^  error +only one fabric \(id 1\) has usable images", out, re.M)
    assert main(["data", "check", str(one), "--no-leakage"]) == 1
    assert "only one fabric (id 1) has usable images" in capsys.readouterr().out


def test_problems_row_says_it_covers_names_and_headers_only(tmp_path: Path, capsys):
    # A file whose header is intact but whose pixels are cut off: info cannot see it (it reads
    # no pixels), so its "0 errors" must say what it covers and point to `data check`.
    root = write_tiny_dataset(tmp_path / "t", fabrics=2, drapes=2)
    png = root / "depth" / "F0001_Depth_New_000000.png"
    png.write_bytes(png.read_bytes()[:80])
    out = _info(root, capsys)
    assert re.search(
        r"^  problems +0 errors, 0 warnings in names and headers "
        r"\(`lookfeel data check` decodes every file\)$",
        out,
        re.M,
    )
    assert main(["data", "check", str(root), "--no-leakage"]) == 1
    assert "file is truncated" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("content", "why"),
    [
        (
            "object,hardness\nsponge,0\n".encode("latin-1") + "éponge,1\n".encode("latin-1"),
            "not a text CSV in UTF-8 (byte 25",
        ),
        (b"", "labels file is empty"),
        (b"object;hardness\nsponge;0\ncork;1\n", "separated by semicolons (;), not commas"),
    ],
    ids=["latin1", "empty", "semicolons"],
)
def test_unreadable_labels_csv_is_not_reported_as_absent(
    tmp_path: Path, capsys, content: bytes, why: str
):
    root = write_recordings(tmp_path / "rec", {"sponge": 1, "cork": 1}, "")
    (root / "labels.csv").write_bytes(content)
    out = _info(root, capsys)
    (labels,) = [line for line in out.splitlines() if line.startswith("  labels ")]
    assert "no labels.csv" not in labels
    assert "labels.csv exists but cannot be read: " in labels and why in labels
    assert "lookfeel data check" in labels


def test_labels_csv_that_is_a_folder_is_reported_by_info(tmp_path: Path, capsys):
    root = write_tiny_dataset(tmp_path / "t", fabrics=2, drapes=1, labels=False)
    (root / "labels.csv").mkdir()
    out = _info(root, capsys)
    assert "labels.csv exists but cannot be read: labels.csv is a folder, not a file" in out
    assert re.search(r"^  problems +1 error, ", out, re.M)


def test_labelled_objects_without_videos_are_named(tmp_path: Path, capsys):
    labels = "object,hardness\nsponge,0\ncork,1\nghost,2\n"
    root = write_recordings(tmp_path / "rec", {"sponge": 2, "cork": 1}, labels)
    out = _info(root, capsys)
    assert re.search(r"^  no videos +1 labelled objects: ghost$", out, re.M)
    assert "no images" not in out
    s = _info_json(root, capsys)
    ids = {name: int(i) for i, name in s["object_names"].items()}  # type: ignore[union-attr]
    assert set(ids) == {"cork", "ghost", "sponge"}
    assert s["labelled_without_images"] == [ids["ghost"]]  # the numeric list is kept
    assert s["labelled_without_images_names"] == ["ghost"]
    assert sorted(s["fabric_ids"]) == sorted([ids["cork"], ids["sponge"]])  # type: ignore[arg-type]


def test_numbered_fabrics_get_no_object_names(tiny_dataset: Path):
    with open(tiny_dataset / "labels.csv", "a", encoding="utf-8") as f:
        f.write("50,0,1,1,1,0,test\n")
    s = scan(tiny_dataset).summary()
    assert s["labelled_without_images"] == [50]
    assert "object_names" not in s and "labelled_without_images_names" not in s


def test_labels_row_counts_fabrics_with_a_dataset_s_own_numeric_columns(tmp_path: Path, capsys):
    """``bend_score`` on every fabric was reported as "0 fabrics with physical labels": only
    the paper's four columns were counted. Any numeric column counts; the paper's four alone
    keep their name."""
    root = write_tiny_dataset(
        tmp_path / "own", fabrics=3, drapes=1, fold_presses=1, flat_presses=0, frames=1,
        labels=False,
    )  # fmt: skip
    labels = "fabric_id,bend_score,material\n1,0.8,wool\n2,1.5,silk\n3,,x\n"
    (root / "labels.csv").write_text(labels, encoding="utf-8")
    (labels,) = [line for line in _info(root, capsys).splitlines() if "bend_score" in line]
    assert labels.endswith("bend_score; 2 fabrics with numeric labels")
    paper = write_tiny_dataset(tmp_path / "paper", fabrics=3, drapes=1, fold_presses=0)
    out = _info(paper, capsys)
    assert "thickness_mm, density, stiffness, stretchiness; 3 fabrics with physical labels" in out


def test_info_counts_the_files_check_fails_as_errors_not_as_skipped(tmp_path: Path, capsys):
    """QA: a 16-bit TIFF beside a fabric's depth PNGs was listed by info under "skipped" with
    "0 errors", while `data check` failed on it. Info now reports it as check does: an error
    with check's reason; what check only skips (a text file) stays skipped in both."""
    import numpy as np
    from PIL import Image

    root = write_tiny_dataset(tmp_path / "t", fabrics=2, drapes=2)
    depth = root / "depth"
    png = depth / "F0001_Depth_New_000000.png"
    Image.fromarray(np.asarray(Image.open(png))).save(depth / "F0001_extra.tif")
    (depth / "notes.txt").write_text("taken on Tuesday", encoding="utf-8")
    out = _info(root, capsys)
    why = (
        "lookfeel does not read .tif files: depth must be a 16-bit greyscale PNG in millimetres "
        "(0 = no reading); convert it (the scan skips these files, so runs read no depth from "
        "them)"
    )
    assert re.search(rf"^  error +depth/F0001_extra\.tif: {re.escape(why)}$", out, re.M)
    assert re.search(r"^  skipped +1 not in the layout: notes\.txt$", out, re.M)
    assert re.search(r"^  problems +1 error, 0 warnings in names and headers", out, re.M)
    s = _info_json(root, capsys)
    assert (s["errors"], s["skipped"]) == (1, 1)
    assert main(["data", "check", str(root), "--no-leakage", "--json"]) == 1
    check = json.loads(capsys.readouterr().out)
    assert [(e["path"], e["message"]) for e in check["errors"]] == [
        (str(depth / "F0001_extra.tif"), why)
    ]
    assert [p["path"] for p in check["skipped"]] == [str(depth / "notes.txt")]


def _split_row(out: str) -> str:
    (row,) = [line for line in out.splitlines() if line.startswith("  paper split ")]
    return row


def test_paper_split_row_is_always_there_and_says_why_none(tmp_path: Path, capsys):
    """README: `data info`'s `paper split` line shows which fabrics the paper split holds out.
    Without a paper_split column the line was missing; it now says none, and why."""
    root = write_tiny_dataset(tmp_path / "t", fabrics=3, drapes=1, fold_presses=0, labels=False)
    (root / "labels.csv").write_text(
        "fabric_id,stiffness,material\n1,2,wool\n2,3,silk\n", encoding="utf-8"
    )
    none = (
        "none ({why}): no fabric is held out as a test set; a run validates on the fabrics its "
        "train.split holds out"
    )
    assert _split_row(_info(root, capsys)).endswith(
        none.format(why="labels.csv has no paper_split column")
    )
    (root / "labels.csv").write_text(
        "fabric_id , paper_split\n1,\n2,\n", encoding="utf-8"
    )  # a column, empty
    assert _split_row(_info(root, capsys)).endswith(
        none.format(why="labels.csv's paper_split column marks no fabric")
    )
    (root / "labels.csv").unlink()
    assert _split_row(_info(root, capsys)).endswith(none.format(why="no labels.csv"))
    (root / "labels.csv").mkdir()  # there, but not a file: not "no labels.csv"
    assert _split_row(_info(root, capsys)).endswith(none.format(why="labels.csv cannot be read"))
    (root / "labels.csv").rmdir()
    (root / "labels.csv").write_bytes("fabric_id,paper_split\n1,test\n".encode("utf-16"))
    assert _split_row(_info(root, capsys)).endswith(none.format(why="labels.csv cannot be read"))
    (root / "labels.csv").write_text(
        "fabric_id,paper_split\n1,train\n2,train\n3,test\n", encoding="utf-8"
    )
    assert _split_row(_info(root, capsys)) == "  paper split  train 2, test 1"
    assert _info_json(root, capsys)["paper_split"] == {"train": 2, "test": 1}


def test_paper_split_row_of_named_objects_says_objects(tmp_path: Path, capsys):
    root = write_recordings(tmp_path / "rec", {"sponge": 2, "cork": 2}, "object,hardness\n")
    assert _split_row(_info(root, capsys)).endswith(
        "none (labels.csv has no paper_split column): no object is held out as a test set; a "
        "run validates on the objects its train.split holds out"
    )


def test_labels_read_despite_a_header_problem_are_not_said_unreadable(tmp_path: Path, capsys):
    """QA: with an unnamed column in labels.csv, `data info` showed the labels as read and
    "paper split none (labels.csv cannot be read)". One rule for both rows now: the file is
    unreadable only when none of its columns could be read. An empty unnamed column (a
    spreadsheet's trailing comma) is no error at all."""
    labels = "object,hardness,paper_split,\nsponge,0,train,x\ncork,1,test,\nfelt,2,train,\n"
    root = write_recordings(tmp_path / "rec", {"sponge": 1, "cork": 1, "felt": 1}, labels)
    out = _info(root, capsys)
    assert re.search(r"^  labels +hardness; 3 objects labelled$", out, re.M)
    assert _split_row(out) == "  paper split  train 2, test 1"
    (root / "labels.csv").write_text(
        "object,hardness,\nsponge,0,x\ncork,1,\nfelt,2,\n", encoding="utf-8"
    )
    assert _split_row(_info(root, capsys)).endswith(
        "none (labels.csv has no paper_split column): no object is held out as a test set; a "
        "run validates on the objects its train.split holds out"
    )
    (root / "labels.csv").write_text(
        "object,hardness,\nsponge,0,\ncork,1,\nfelt,2,\n", encoding="utf-8"
    )
    out = _info(root, capsys)
    assert re.search(r"^  labels +hardness; 3 objects labelled$", out, re.M)
    assert "labels.csv has no paper_split column" in _split_row(out)
    assert re.search(r"^  problems +0 errors, 1 warning in names and headers", out, re.M)
