"""`lookfeel data check`: every problem with its path, exit status, nothing modified."""

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from lookfeel.cli import main
from lookfeel.data import check_dataset
from lookfeel.data.check import PLAUSIBLE_DEPTH_MM, _depth_unit_problem
from lookfeel.data.images import decode_depth
from lookfeel.modality import Modality

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
    out = capsys.readouterr().out
    assert "WARNING  " in out and f"Checked {tiny_dataset}: 6 fabrics, " in out
    assert main(["data", "check", str(tiny_dataset), "--strict"]) == 1


def test_missing_root_exits_1_with_message(tmp_path: Path, capsys):
    assert main(["data", "check", str(tmp_path / "nope")]) == 1
    assert "does not exist" in capsys.readouterr().err


def test_an_empty_dataset_s_error_names_every_folder_the_layout_reads(tmp_path: Path):
    (tmp_path / "empty").mkdir()
    (error,) = check_dataset(tmp_path / "empty").errors
    assert error.message.startswith("no usable image found: a dataset holds depth/, color/ or ")
    assert "a videos/ folder of <object>_<n> press videos" in error.message


def test_press_videos_given_directly_are_pointed_to_their_videos_folder(tmp_path: Path):
    # The user gave ROOT/videos as the dataset: its videos lie directly in the root.
    videos = tmp_path / "rec" / "videos"
    videos.mkdir(parents=True)
    for name in ("sponge_0.mov", "sponge_1.mov", "cork_0.mp4"):
        (videos / name).write_bytes(b"\x00\x00\x00\x14ftypqt  " + bytes(64))
    (error,) = check_dataset(videos).errors
    assert error.path == videos
    assert error.message == (
        f"no usable image found: {videos} holds 3 press video(s) directly (e.g. cork_0.mp4); "
        f"they belong in {videos / 'videos'}/ (is this the videos/ folder? give its parent)"
    )


def test_images_given_directly_are_pointed_to_their_modality_folders(tiny_dataset: Path):
    (error,) = check_dataset(tiny_dataset / "depth").errors
    assert "holds 18 F<id>_ image(s) directly (e.g. F0001_Depth_New_000000.png)" in error.message
    assert "belong in its depth/, color/ or touch/ folder" in error.message


def _write_depth_mm(path: Path, depth_mm: np.ndarray) -> None:
    Image.fromarray(depth_mm.astype(np.uint16)).save(path)


@pytest.mark.parametrize(
    ("median", "warned"),
    [(150, True), (199, True), (200, False), (1040, False), (8000, False), (8001, True)],
)
def test_depth_unit_bounds_truth_table(median: int, warned: bool):
    # Holes (0) are not readings: a map 60% holes still reads at its valid pixels' median.
    depth = np.zeros((10, 10), np.uint16)
    depth[:4] = median
    assert (_depth_unit_problem(Path("d.png"), depth) is not None) is warned
    assert PLAUSIBLE_DEPTH_MM == (200, 8000)


def test_depth_in_centimetres_or_tenths_of_mm_is_a_warning_naming_the_file(tiny_dataset: Path):
    # A camera writing centimetres (1 m reads 100) or 0.1 mm units (1 m reads 10,000).
    depth = tiny_dataset / "depth"
    cm, tenth = depth / "F0001_Depth_New_000000.png", depth / "F0002_Depth_New_000000.png"
    _write_depth_mm(cm, np.asarray(Image.open(cm)) // 10)
    _write_depth_mm(tenth, np.asarray(Image.open(tenth)).astype(np.int64) * 10)
    catalog = check_dataset(tiny_dataset)
    assert catalog.errors == ()
    warned = {p.path: p.message for p in catalog.warnings}
    assert set(warned) == {cm, tenth}
    assert warned[cm].startswith("median of the valid pixels is 9")
    assert "implausible as millimetres: lookfeel reads depth in mm" in warned[cm]
    assert "(centimetres?)" in warned[cm]
    assert warned[tenth].startswith("median of the valid pixels is 9,")
    assert "(0.1 mm units, or saturated?)" in warned[tenth]


def test_real_depth_reads_as_millimetres(real_data: Path):
    # GelFabric's Kinect depth (medians ~1,000-1,090 mm) must raise no unit warning.
    files = sorted((real_data / "depth").glob("*.png"))[::10]
    assert len(files) > 50
    for path in files:
        assert _depth_unit_problem(path, decode_depth(path)) is None, path


def test_synthetic_depth_reads_as_millimetres(tmp_path: Path):
    # `lookfeel synth` renders depth as a Kinect sees it: no unit warning on any drape.
    from lookfeel.synth import SIZE_PRESETS, SynthConfig, generate

    config = SynthConfig(
        fabrics=6, drapes=2, modalities=(Modality.DEPTH,), contact_sheet=False, reprints=0,
        workers=1, **SIZE_PRESETS["tiny"],
    )  # fmt: skip
    generate(config, tmp_path / "world", progress=False)
    files = sorted((tmp_path / "world" / "depth").glob("*.png"))
    assert len(files) == 12
    for path in files:
        assert _depth_unit_problem(path, decode_depth(path)) is None, path
