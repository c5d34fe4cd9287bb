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
    # The dataset folder is data_root, here and in its summary (data info's), as index info says.
    assert report["data_root"] == report["summary"]["data_root"] == str(tiny_dataset)
    assert "root" not in report and "root" not in report["summary"]
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
    with open(tiny_dataset / "labels.csv", "a", encoding="utf-8") as f:
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


def test_depth_beyond_the_mapped_range_is_one_warning_naming_the_keys(tiny_dataset: Path):
    """Depth 0.8 m further than the range mapped to 0..1 (800-1,300 mm by default) reads as
    millimetres, yet every pixel saturates: one warning for the dataset, not per file. A room
    beyond the range (70% of the pixels at 1.6 m) while the cloth lies inside is no warning."""
    paths = sorted((tiny_dataset / "depth").glob("*.png"))
    for path in paths:
        d = np.asarray(Image.open(path)).astype(np.int64)
        d[:17] = 1600
        _write_depth_mm(path, d)
    assert check_dataset(tiny_dataset).problems == ()
    for path in paths:
        d = np.asarray(Image.open(path)).astype(np.int64)
        _write_depth_mm(path, np.where(d > 0, d + 800, 0))
    (warning,) = check_dataset(tiny_dataset).warnings
    assert warning.path == tiny_dataset / "depth"
    assert warning.message.startswith("only 0% of the valid depth pixels lie between 800 and ")
    assert "data.depth_min_mm 800, data.depth_range_mm 500: the defaults" in warning.message
    assert "median is 2,400 mm (5th-95th percentile 1,780-2,400)" in warning.message
    assert "data.depth_input: registered" in warning.message


def test_image_files_lookfeel_does_not_read_are_errors_saying_what_to_convert_to(
    tiny_dataset: Path, capsys
):
    """A depth map as a float TIFF (metres) was skipped and `data check` said OK; a press kept
    as a folder of frames likewise. Both are errors now, one line per folder."""
    depth = tiny_dataset / "depth"
    for path in sorted(depth.glob("F0001_*.png")):
        Image.fromarray(np.asarray(Image.open(path)).astype(np.float32) / 1000).save(
            path.with_suffix(".tif")
        )
        path.unlink()
    press = tiny_dataset / "touch" / "F0002_fold_200"
    press.mkdir()
    for frame in sorted((tiny_dataset / "touch").glob("F0002_fold_*_200.png")):
        frame.rename(press / frame.name.replace("F0002_fold_", "").replace("_200", ""))
    (depth / "old").mkdir()  # a copy set aside: still only skipped
    (depth / "old" / "F0003_Depth_New_000000.png").write_bytes(b"")
    catalog = check_dataset(tiny_dataset)
    errors = {p.path: p.message for p in catalog.errors}
    tif = depth / "F0001_Depth_New_000000.tif"
    assert set(errors) == {tif, press, depth}  # depth: fabric 1 has no depth item left
    assert errors[tif] == (
        "lookfeel does not read .tif files (and 2 more .tif in depth/): depth must be a 16-bit "
        "greyscale PNG in millimetres (0 = no reading); convert each (the scan skips these "
        "files, so runs read no depth from them)"
    )
    assert errors[press].startswith(
        "a subfolder of touch/ holding images (e.g. 01.png), which are not read (the layout is "
        "flat): put each frame in touch/ itself, named F<id>_<kind>_<frame>_<press>.png (here "
        "F0002_fold_01_200.png"
    )
    assert "or the press as one video in touch/ (F0002_fold_200.mp4)" in errors[press]
    assert [p.path for p in catalog.skipped] == [depth / "old"]
    assert main(["data", "check", str(tiny_dataset), "--no-leakage"]) == 1
    out = capsys.readouterr().out
    assert "SKIPPED" in out and ".tif" not in out.split("SKIPPED")[1]


def test_frames_of_another_shape_are_a_warning_naming_the_turned_one(tiny_dataset: Path):
    """A portrait press among landscape ones is resized to the same square: stretched
    differently, and most likely turned. Sizes of one shape are resized alike: no warning."""
    touch = tiny_dataset / "touch"
    for frame in sorted(touch.glob("F0003_flat_*_301.png")):
        write_rgb(frame, 3, 0, size=(24, 32))
    for frame in sorted(touch.glob("F0004_flat_*_401.png")):
        write_rgb(frame, 4, 0, size=(64, 48))  # larger, same shape
    (warning,) = check_dataset(tiny_dataset).warnings
    assert warning.path == touch / "F0003_flat_01_301.png"
    assert warning.message.startswith(
        "touch frames come in 3 sizes of different shape: 32x24 (28 presses), 24x32 (1 press), "
        "64x48 (1 press); each is resized to the network's one square input (data.image_size)"
    )
    assert "(this one is portrait among landscape ones: most likely turned)" in warning.message
    assert warning.message.endswith("record them alike, or turn or crop them to 32x24")


def test_a_constant_column_and_classes_of_one_fabric_are_a_warning_per_column(
    tiny_dataset: Path,
):
    """Every hardness 1, and silk and linen on one fabric each: `data check` said 0 warnings,
    yet no class head or probe can learn and score these on held-out fabrics. A column of
    all-different words (descriptions) and a varied number column are no warning."""
    labels = tiny_dataset / "labels.csv"
    labels.write_text(
        "fabric_id,material,hardness,density,thickness_mm,note\n"
        "1,cotton,1,0.25,0.5,first\n2,cotton,1,0.25,0.6,second\n3,wool,1,0.25,0.7,third\n"
        "4,wool,1,0.25,0.8,fourth\n5,silk,1,0.25,0.9,fifth\n6,linen,1,,1.0,sixth\n",
        encoding="utf-8",
    )
    catalog = check_dataset(tiny_dataset)
    assert catalog.errors == ()
    assert [(p.path, p.severity) for p in catalog.warnings] == [(labels, "warning")] * 3
    nothing = (
        "so there is nothing to tell apart: a class head (model.class_heads) refuses it, and a "
        "probe can neither learn nor score it on held-out fabrics; add fabrics that differ, or "
        "leave the column out"
    )
    assert [p.message for p in catalog.warnings] == [
        f"column 'hardness' is constant: every fabric with a value has '1' (6 of 6), {nothing}",
        f"column 'density' is constant: every fabric with a value has '0.25' (5 of 6), {nothing}",
        "column 'material': 2 class(es) of one fabric each, 'linen' (F0006), 'silk' (F0005): on "
        "whichever side of a split that fabric falls, its class is either never trained on or "
        "has no held-out fabric, so a class head (model.class_heads) or probe cannot learn and "
        "score it on held-out fabrics; label more fabrics of these classes, or merge them into "
        "others",
    ]
    labels.write_text(
        "fabric_id,material,hardness,note\n1,cotton,1,a\n2,cotton,2,b\n3,wool,1,c\n"
        "4,wool,2,d\n5,silk,0,e\n6,silk,1,f\n",
        encoding="utf-8",
    )
    assert check_dataset(tiny_dataset).problems == ()


def test_an_image_renamed_as_a_video_is_said_to_be_one_as_predict_says(tmp_path: Path):
    """QA: a PNG renamed .mp4 was "not a video container (QuickTime .mov, MP4, AVI or
    Matroska)" in `data check`, while `predict` said what it is. `data check` decodes it and
    says so in predict's words; the scan, which reads 16 bytes, keeps its own."""
    pytest.importorskip("av")
    from lookfeel.data import scan

    from ._tiny import write_recordings

    root = write_recordings(tmp_path / "rec", {"cork": 1, "felt": 1}, "object\ncork\nfelt\n")
    png, jpeg = root / "videos" / "cork_1.mp4", root / "videos" / "felt_1.mov"
    Image.fromarray(np.zeros((16, 16, 3), np.uint8)).save(png, format="PNG")
    Image.fromarray(np.zeros((16, 16, 3), np.uint8)).save(jpeg, format="JPEG")
    junk = root / "videos" / "felt_2.mkv"
    junk.write_bytes(bytes(range(64)))
    said = {p.path: p.message for p in scan(root).errors}
    scanned = "not a video container (QuickTime .mov, MP4, AVI or Matroska)"
    assert said[png] == said[jpeg] == said[junk] == scanned
    said = {p.path: p.message for p in check_dataset(root, workers=1).errors}
    assert said[png] == "cannot decode video: the file is an image (png_pipe), not a video"
    assert said[jpeg] == "cannot decode video: the file is an image (jpeg_pipe), not a video"
    assert said[junk] == "cannot decode video: not a video file FFmpeg can read"


@pytest.mark.parametrize("action", ["info", "check", "leakage"])
def test_every_data_action_s_help_describes_both_layouts(
    action: str, capsys: pytest.CaptureFixture[str]
):
    """QA: `data info --help` described ROOT as "(depth/, color/, touch/, labels.csv)", never
    the recordings layout (videos/<object>_<n>.mov) that the scan reads as well."""
    with pytest.raises(SystemExit) as e:
        main(["data", action, "--help"])
    assert e.value.code == 0
    text = " ".join(capsys.readouterr().out.split())  # argparse wraps lines
    assert "depth/, color/, touch/" in text
    assert "videos/ (<object>_<n>.mov)" in text and "keyed by fabric_id or object" in text


def test_grey_press_videos_among_colour_ones_are_one_warning_naming_them(tmp_path: Path):
    """QA: a dataset mixing grey and colour press videos passed `data check` silently, yet a
    model reads a grey press (the same value in each channel) unlike a colour one. One warning
    names the grey one, or counts them and names a few; a dataset all grey gets one milder
    warning for the dataset; an all-colour one none."""
    pytest.importorskip("av")
    from ._tiny import write_recordings
    from ._video import PRESS, object_press, write_video

    def grey_warnings(root: Path) -> list[tuple[Path | None, str]]:
        said = check_dataset(root, workers=1).warnings
        return [(p.path, p.message) for p in said if "no colour" in p.message]

    why = (
        "(GelSight's and DIGIT's colours carry the surface's slopes, and a grey video gives the "
        "same value in each channel)"
    )
    names = ["a", "b", "c", "d", "e", "f"]
    root = write_recordings(tmp_path / "rec", {}, "object\n" + "\n".join(names) + "\n")
    videos = root / "videos"
    for k, name in enumerate(names[:2]):
        write_video(videos / f"{name}_0.mov", object_press(k, PRESS, t=14, seed=k))
    assert grey_warnings(root) == []
    # one video of a single grey channel (FFmpeg's "gray" pixel format)
    one = write_video(videos / "c_0.mkv", object_press(2, PRESS, t=14), "ffv1", "gray")
    assert grey_warnings(root) == [
        (
            one,
            "this touch press video has no colour (grey), unlike the other 2: a model reads it "
            f"unlike them {why}; record it in colour, or leave it out",
        )
    ]
    # grey frames stored as colour (red, green and blue equal) are grey too
    for k, name in enumerate(names[3:], start=3):
        frames = object_press(k, PRESS, t=14, seed=k).mean(axis=-1, keepdims=True)
        write_video(videos / f"{name}_0.mov", np.repeat(frames.astype(np.uint8), 3, axis=-1))
    assert grey_warnings(root) == [
        (
            one,
            "4 of the 6 touch press videos have no colour (grey), unlike the other 2: c_0.mkv, "
            f"d_0.mov, e_0.mov and 1 more; a model reads them unlike the others {why}; record "
            "them in colour, or leave them out",
        )
    ]
    for name in names[:2]:
        (videos / f"{name}_0.mov").unlink()
    assert grey_warnings(root) == [
        (
            root,
            "all 4 touch press videos have no colour (grey): a model trains on them, but one "
            f"trained on colour presses does not read them as it reads those {why}",
        )
    ]
