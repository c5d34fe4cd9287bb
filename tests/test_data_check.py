"""`lookfeel data check`: every problem with its path, exit status, nothing modified."""

import json
from pathlib import Path

import numpy as np
from PIL import Image

from lookfeel.cli import main
from lookfeel.data import check_dataset

from ._tiny import write_rgb
from .conftest import tree_digest


def _break(root: Path) -> dict[str, Path]:
    """The issue's four faults: truncated PNG, 8-bit depth, unparsable touch name, unlabelled."""
    depth = root / "depth"
    truncated = depth / "F0001_Depth_New_000000.png"
    truncated.write_bytes(truncated.read_bytes()[:80])
    eight = depth / "F0002_Depth_New_000099.png"
    Image.fromarray(np.full((24, 24), 120, np.uint8)).save(eight)
    bad_name = root / "touch" / "F12_fold_x.jpg"
    write_rgb(bad_name, 12, 0)
    unlabelled = depth / "F0009_Depth_New_000001.png"
    unlabelled.write_bytes((depth / "F0003_Depth_New_000000.png").read_bytes())
    return {"truncated": truncated, "eight": eight, "name": bad_name, "unlabelled": unlabelled}


def test_check_names_all_four_faults_and_changes_nothing(tiny_dataset: Path, capsys):
    paths = _break(tiny_dataset)
    before = tree_digest(tiny_dataset)
    status = main(["data", "check", str(tiny_dataset), "--require", "depth"])
    out = capsys.readouterr().out
    assert status == 1
    errors = [line for line in out.splitlines() if line.startswith("ERROR")]
    for path in paths.values():
        assert any(str(path) in line for line in errors), path
    assert f"ERROR    {paths['truncated']}: file is truncated" in out
    assert "FAILED: 4 error(s)" in out
    assert tree_digest(tiny_dataset) == before


def test_check_json_and_clean_exit(tiny_dataset: Path, capsys):
    assert main(["data", "check", str(tiny_dataset), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["ok"] is True and report["errors"] == []
    assert report["summary"]["items"] == {"depth": 18, "color": 18, "touch": 30}
    _break(tiny_dataset)
    assert main(["data", "check", str(tiny_dataset), "--json", "--require", "depth"]) == 1
    report = json.loads(capsys.readouterr().out)
    assert len(report["errors"]) == 4
    assert {e["severity"] for e in report["errors"]} == {"error"}


def test_decode_failures_drop_their_items(tiny_dataset: Path):
    _break(tiny_dataset)
    catalog = check_dataset(tiny_dataset, require=[])
    names = {it.path.name for f in catalog.fabrics for its in f.items.values() for it in its}
    assert "F0001_Depth_New_000000.png" not in names
    assert "F0001_Depth_New_000001.png" in names


def test_warnings_fail_only_when_strict(tiny_dataset: Path, capsys):
    with open(tiny_dataset / "labels.csv", "a") as f:
        f.write("50,0,1,1,1,0,test\n")
    assert main(["data", "check", str(tiny_dataset)]) == 0
    assert "WARNING  " in capsys.readouterr().out
    assert main(["data", "check", str(tiny_dataset), "--strict"]) == 1


def test_missing_root_exits_1_with_message(tmp_path: Path, capsys):
    assert main(["data", "check", str(tmp_path / "nope")]) == 1
    assert "does not exist" in capsys.readouterr().err
