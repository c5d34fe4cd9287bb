"""`lookfeel data leakage`: a planted session fingerprint is found, a clean set is not."""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from lookfeel.data import scan
from lookfeel.data.files import ImageError
from lookfeel.data.leakage import (
    MaskError,
    format_leakage,
    leakage_problems,
    leakage_report,
    load_pooled,
    parse_mask_options,
    static_mask,
)
from lookfeel.modality import Modality

from ._tiny import LABELS_HEADER

_WALL_ROWS = 8
_SIZE = 32


def _write_rig(root: Path, leak: bool, fabrics: int = 12, drapes: int = 4) -> Path:
    """Depth drapes: a wall in the top rows, cloth below that moves by centimetres per drape.

    The cloth's mean depth carries the fabric (the material signal). With ``leak`` every
    fabric's session puts the wall at its own offset (2 mm apart, as GelFabric's sessions do);
    without, the wall is the same for all and only sensor noise differs.
    """
    rng = np.random.default_rng(7)
    offsets = rng.permutation(np.arange(-12, 12, 2))[:fabrics]
    yy, xx = np.mgrid[0:_SIZE, 0:_SIZE]
    for f in range(1, fabrics + 1):
        for k in range(drapes):
            d = np.empty((_SIZE, _SIZE))
            wall = 1300.0 + (offsets[f - 1] if leak else 0.0)
            d[:_WALL_ROWS] = wall + rng.normal(0.0, 0.4, (_WALL_ROWS, _SIZE))
            cx, cy = rng.uniform(4, 28), rng.uniform(12, 28)
            blob = 80.0 * np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / 40.0)
            cloth = 900.0 + 40.0 * f + rng.normal(0.0, 8.0) - blob
            d[_WALL_ROWS:] = cloth[_WALL_ROWS:]
            path = root / "depth" / f"F{f:04d}_Depth_New_{k:06d}.png"
            path.parent.mkdir(parents=True, exist_ok=True)
            Image.fromarray(np.rint(d).astype(np.uint16)).save(path)
    lines = [LABELS_HEADER] + [f"{f},{f % 3},1,1,1,0,train\n" for f in range(1, fabrics + 1)]
    (root / "labels.csv").write_text("".join(lines), encoding="utf-8")
    return root


@pytest.fixture
def leaky(tmp_path: Path) -> Path:
    return _write_rig(tmp_path / "leaky", leak=True)


@pytest.fixture
def clean(tmp_path: Path) -> Path:
    return _write_rig(tmp_path / "clean", leak=False)


def test_static_rule_finds_the_wall(leaky: Path):
    report = leakage_report(scan(leaky), n_boot=200)
    (depth,) = report.modalities
    assert depth.mask_source == "static"
    assert depth.background_fraction == pytest.approx(_WALL_ROWS / _SIZE)
    assert depth.pool == 1 and depth.pooled_shape == (_SIZE, _SIZE)


def test_threads_decode_the_same_pixels_and_name_the_first_bad_file(leaky: Path):
    items = scan(leaky).items(Modality.DEPTH)
    serial, shape, k = load_pooled(items, workers=1)
    threaded, shape2, k2 = load_pooled(items, workers=2)
    assert len(items) > 17  # enough for the thread pool
    np.testing.assert_array_equal(serial, threaded)
    assert (shape, k) == (shape2, k2)
    for it in (items[30], items[20]):
        it.path.write_bytes(it.path.read_bytes()[:60])  # truncated
    with pytest.raises(ImageError) as e:
        load_pooled(items, workers=2)
    assert e.value.path == items[20].path


def test_static_mask_is_per_pixel_median_rule():
    stack = np.zeros((20, 2, 2, 1), np.float32)
    stack[:, 0, 0] = 5.0  # always still
    stack[:1, 0, 1] = 100.0  # moves in 1 of 20 images: still in 95%
    stack[:2, 1, 0] = 100.0  # moves in 2 of 20: not still in 95%
    stack[:, 1, 1, 0] = np.arange(20) * 50.0  # cloth: moves every time
    mask = static_mask(stack, tolerance=10.0, static_fraction=0.95)
    assert mask.tolist() == [[True, True], [False, False]]


def test_planted_leak_is_flagged(leaky: Path):
    report = leakage_report(scan(leaky), n_boot=200)
    (depth,) = report.modalities
    assert depth.chance == pytest.approx(0.1)
    assert depth.background_top1 > 0.9
    assert depth.background_ci95[0] > 2 * depth.chance
    assert depth.leak and report.leaks == (depth,)
    assert "LEAK" in format_leakage(report)
    (problem,) = leakage_problems(report)
    assert problem.severity == "warning" and problem.path == leaky / "depth"
    assert "identifies the fabric" in problem.message


def test_clean_set_is_not_flagged_but_its_cloth_still_identifies(clean: Path):
    report = leakage_report(scan(clean), n_boot=200)
    (depth,) = report.modalities
    assert depth.background_fraction == pytest.approx(_WALL_ROWS / _SIZE)
    assert depth.background_top1 < 0.25  # chance is 0.1
    assert not depth.leak and leakage_problems(report) == []
    assert depth.whole_top1 > 0.5  # the material signal is in the cloth
    assert "no leak found" in format_leakage(report)


def test_user_mask_replaces_the_rule(leaky: Path, tmp_path: Path):
    mask = np.zeros((64, 64), np.uint8)  # another size than the images: resized
    mask[:8] = 255  # the top 4 of 32 rows
    path = tmp_path / "mask.png"
    Image.fromarray(mask).save(path)
    report = leakage_report(scan(leaky), masks={Modality.DEPTH: path}, n_boot=200)
    (depth,) = report.modalities
    assert depth.mask_source == str(path)
    assert depth.background_fraction == pytest.approx(4 / _SIZE)
    assert depth.leak


def test_bad_masks_name_the_file(leaky: Path, tmp_path: Path):
    missing = tmp_path / "nope.png"
    with pytest.raises(MaskError, match="nope.png: mask file not found"):
        leakage_report(scan(leaky), masks={Modality.DEPTH: missing})
    black = tmp_path / "black.png"
    Image.fromarray(np.zeros((8, 8), np.uint8)).save(black)
    with pytest.raises(MaskError, match="black.png: mask has no white"):
        leakage_report(scan(leaky), masks={Modality.DEPTH: black})


def test_parse_mask_options():
    got = parse_mask_options(["all.png", "depth=room.png"])
    assert got[Modality.DEPTH] == Path("room.png") and got[Modality.COLOR] == Path("all.png")
    with pytest.raises(MaskError, match="no path after 'depth='"):
        parse_mask_options(["depth="])


def test_report_json_and_every_modality(tiny_dataset: Path):
    report = leakage_report(scan(tiny_dataset), n_boot=100)
    d = json.loads(json.dumps(report.to_dict()))
    assert d["data_root"] == str(tiny_dataset) and "root" not in d  # as `data info` names it
    assert set(d["modalities"]) == {"depth", "color", "touch"}
    for entry in d["modalities"].values():
        assert {"whole_top1", "background_top1", "chance", "leak"} <= set(entry)
        # Every interval as two numbers named after its top-1, as evaluate's metrics.json.
        for top1 in ("whole_top1", "background_top1", "input_top1"):
            assert {f"{top1}_ci_low", f"{top1}_ci_high"} <= set(entry), top1
        assert not [k for k in entry if "ci95" in k]
    depth = report.modalities[0]
    got = d["modalities"][depth.modality.value]
    low, high = depth.whole_ci95
    assert (got["whole_top1_ci_low"], got["whole_top1_ci_high"]) == (round(low, 4), round(high, 4))
    assert got["whole_top1_ci_low"] <= got["whole_top1"] <= got["whole_top1_ci_high"]
    keys = list(got)  # each pair just after its top-1, as the fields stand
    at = keys.index("whole_top1")
    assert keys[at : at + 3] == ["whole_top1", "whole_top1_ci_low", "whole_top1_ci_high"]


def test_too_few_fabrics_is_skipped_with_reason(leaky: Path):
    catalog = scan(leaky).subset([1])
    report = leakage_report(catalog, n_boot=50)
    assert report.modalities == () and "two fabrics" in report.skipped["depth"]


def test_cli_data_leakage(leaky: Path, clean: Path, capsys):
    from lookfeel.cli import main

    assert main(["data", "leakage", str(leaky), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["leak"] is True and d["modalities"]["depth"]["leak"] is True
    assert main(["data", "leakage", str(clean)]) == 0
    assert "no leak found" in capsys.readouterr().out


@pytest.mark.slow
def test_real_depth_wall_leak_is_flagged(real_data: Path):
    """Issue #12's target: the shared depth's background alone scores >= 0.4 (chance 0.1)."""
    report = leakage_report(scan(real_data), modalities=[Modality.DEPTH], n_boot=200)
    (depth,) = report.modalities
    assert depth.leak and depth.background_top1 >= 0.4
    assert depth.chance == pytest.approx(0.1)


@pytest.mark.parametrize(
    ("flag", "value", "message"),
    [
        ("--tolerance", "-5", "argument --tolerance: must be >= 0, got -5"),
        ("--static-fraction", "2", "argument --static-fraction: must be in (0, 1], got 2"),
        ("--static-fraction", "0", "argument --static-fraction: must be in (0, 1], got 0"),
        ("--pool", "0", "argument --pool: must be >= 1, got 0"),
        ("--pool", "1.5", "argument --pool: expected int, got '1.5'"),
        ("--workers", "0", "argument --workers: must be >= 1, got 0"),
    ],
)
def test_cli_data_leakage_names_the_flag_of_a_bad_setting(
    clean: Path, capsys, flag: str, value: str, message: str
):
    from lookfeel.cli import main

    with pytest.raises(SystemExit) as e:
        main(["data", "leakage", str(clean), flag, value])
    assert e.value.code == 2
    assert capsys.readouterr().err.strip().endswith(message)


def test_cli_data_check_warns_of_a_leak(leaky: Path, clean: Path, capsys):
    from lookfeel.cli import main

    assert main(["data", "check", str(leaky)]) == 0
    out = capsys.readouterr().out
    assert f"WARNING  {leaky / 'depth'}: depth background" in out
    assert "identifies the fabric" in out
    assert main(["data", "check", str(clean)]) == 0
    assert "identifies the fabric" not in capsys.readouterr().out


def _write_posts(root: Path, moved: bool, fabrics: int = 10, drapes: int = 4) -> Path:
    """Rendered drapes in one room and camera (no background leak), each fabric's post at its
    own place (``moved``: the session's offset, 27 mm apart, plus 3 mm of jitter) or every
    post at one place (4 mm of jitter). The post is about as high for all (290-300 mm); the
    drape's spread varies per drape."""
    from ._scene import Scene

    rng = np.random.default_rng(3)
    places = rng.permutation(np.linspace(-120.0, 120.0, fabrics))
    for f in range(1, fabrics + 1):
        for k in range(drapes):
            jitter = rng.normal(0.0, 3.0 if moved else 4.0, 2)
            ox, oy = (places[f - 1] if moved else 0.0) + jitter[0], jitter[1]
            scene = Scene(
                size=40,
                f=90.0 * 40 / 64,
                peak_mm=float(rng.uniform(290.0, 300.0)),
                spread_mm=float(rng.uniform(80.0, 110.0)),
                cloth_offset=(float(ox), float(oy)),
                seed=100 * f + k,
            )
            path = root / "depth" / f"F{f:04d}_Depth_New_{k:06d}.png"
            path.parent.mkdir(parents=True, exist_ok=True)
            Image.fromarray(scene.render()["depth"]).save(path)
    lines = [LABELS_HEADER] + [f"{f},{f % 3},1,1,1,0,train\n" for f in range(1, fabrics + 1)]
    (root / "labels.csv").write_text("".join(lines), encoding="utf-8")
    return root


def test_position_of_the_drape_is_flagged_when_posts_moved_with_the_session(tmp_path, capsys):
    """The room is the same for every fabric (no background leak), but each session put the
    drape somewhere else in the image: `position_leakage` finds it; one place for all: not."""
    from lookfeel.cli import main
    from lookfeel.data.leakage import position_leakage

    moved = scan(_write_posts(tmp_path / "moved", moved=True))
    still = scan(_write_posts(tmp_path / "still", moved=False))
    got = position_leakage(moved, n_boot=200)
    assert not isinstance(got, str)
    assert got.n_items == 40 and got.n_fabrics == 10 and got.image_px == (40, 40)
    assert got.post_uv.top1 > 0.9 and got.post_uv.ci95[0] > 2 * got.chance and got.leak
    assert got.post_uv.within_fabric_px < 0.5 * got.post_uv.overall_px
    clean = position_leakage(still, n_boot=200)
    assert not isinstance(clean, str)
    assert clean.post_uv.top1 < 0.25 and not clean.leak
    report = leakage_report(moved, n_boot=100, position=True)
    assert report.position is not None and report.position.leak
    assert not report.leaks  # the background does not leak: only the position does
    (problem,) = leakage_problems(report)
    assert "where the drape lies" in problem.message and problem.severity == "warning"
    assert "LEAK: where the drape lies" in format_leakage(report)
    assert leakage_report(still, n_boot=100, position=True).position is not None
    assert main(["data", "leakage", str(moved.root), "--position", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["leak"] is True and d["position"]["post_uv"]["top1"] > 0.8
    assert d["modalities"]["depth"]["leak"] is False
    assert "two fabrics" in str(position_leakage(moved.subset([1])))


def test_position_names_the_depth_file_it_cannot_register(tmp_path, capsys):
    from lookfeel.cli import main
    from lookfeel.data.leakage import position_leakage
    from lookfeel.data.register import RegistrationError

    root = _write_posts(tmp_path / "posts", moved=True, fabrics=10, drapes=2)
    bad = root / "depth" / "F0003_Depth_New_000001.png"
    Image.fromarray(np.zeros((40, 40), np.uint16)).save(bad)  # no reading anywhere
    with pytest.raises(RegistrationError) as e:
        position_leakage(scan(root), n_boot=50)
    msg = str(e.value)
    assert msg.startswith(f"{bad}: cannot register depth") and "\n" not in msg
    assert main(["data", "leakage", str(root), "--position"]) != 0
    err = capsys.readouterr().err
    assert str(bad) in err and "Traceback" not in err


def test_position_names_the_depth_images_whose_floor_the_cloth_hides(tmp_path):
    """A drape spread over the whole floor leaves registration no floor to fit: the position
    check says how many images that is and names one, in its text and as a warning."""
    from lookfeel.data.leakage import position_leakage

    from ._scene import Scene

    root = _write_posts(tmp_path / "posts", moved=False, fabrics=10, drapes=2)
    hidden = root / "depth" / "F0004_Depth_New_000001.png"
    scene = Scene(size=40, f=90.0 * 40 / 64, peak_mm=200.0, spread_mm=400.0, seed=5)
    Image.fromarray(scene.render()["depth"]).save(hidden)
    got = position_leakage(scan(root), n_boot=50)
    assert not isinstance(got, str)
    assert got.no_floor == (str(hidden),)
    report = leakage_report(scan(root), n_boot=50, position=True)
    text = format_leakage(report)
    assert "no floor found in 1 of 20 depth images" in text and str(hidden) in text
    (problem,) = [p for p in leakage_problems(report) if "no floor" in p.message]
    assert problem.path == hidden and problem.severity == "warning"
    assert report.to_dict()["position"]["no_floor"] == [str(hidden)]
    # Every floor in view: nothing to say.
    clean = position_leakage(scan(_write_posts(tmp_path / "clean", moved=False)), n_boot=50)
    assert not isinstance(clean, str) and clean.no_floor == ()


def _write_presses(root: Path, sessions: bool, fabrics: int = 6, presses: int = 3) -> Path:
    """Press videos ``touch/F<id>_fold_<press>.mp4``: each fabric's texture pressed in. With
    ``sessions``, each fabric was recorded in its own session, whose sensor light is a few grey
    levels off the others' (PhysiCLeAR's drift); without, one light for all. Fabric 1's last
    video holds no press."""
    from ._video import PRESS, object_press, write_video

    rng = np.random.default_rng(5)
    light = rng.permutation(np.arange(-15, 15, 5))[:fabrics] if sessions else np.zeros(fabrics)
    (root / "touch").mkdir(parents=True)
    for f in range(1, fabrics + 1):
        for p in range(presses):
            depth = {} if (f, p) == (1, presses - 1) else PRESS
            frames = object_press(f, depth, 16, seed=10 * f + p).astype(np.float32)
            frames = np.clip(frames + light[f - 1], 0, 255).astype(np.uint8)
            write_video(root / "touch" / f"F{f:04d}_fold_{100 * f + p}.mp4", frames)
    return root


def test_press_videos_are_scored_with_their_no_contact_frame_as_the_background(tmp_path, capsys):
    """Press videos were not scored at all ("cannot decode"): the sensor's light before the
    press is their background, and a light that differs per session is a leak."""
    from lookfeel.cli import main

    leaky = _write_presses(tmp_path / "sessions", sessions=True)
    report = leakage_report(scan(leaky), n_boot=100)
    assert report.skipped == {}
    (touch,) = report.modalities
    assert touch.press_videos and touch.mask_source == "no-contact"
    assert touch.n_items == 17 and touch.left_out == 1 and touch.n_fabrics == 6
    assert touch.background_fraction == 1.0 and touch.pooled_shape == (48, 64)
    assert touch.background_top1 > 0.9 and touch.leak
    assert touch.whole_top1 > 0.5 and touch.input_top1 > 0.5  # the texture is in the press
    text = format_leakage(report)
    assert "17 press videos of 6 fabrics (1 with no press left out" in text
    assert "LEAK: the sensor with nothing touching it identifies the fabric" in text
    (problem,) = leakage_problems(report)
    assert problem.path == leaky / "touch" and "no-contact frame" in problem.message
    assert report.noun == "fabric"  # numbered fabrics; data naming its objects says objects
    objects = dataclasses.replace(report, noun="object")
    text = format_leakage(objects)
    assert "[95% over objects]" in text and "17 press videos of 6 objects" in text
    assert "identifies the object at" in text and "fabric" not in text
    assert "identifies the object at" in leakage_problems(objects)[0].message

    one_light = _write_presses(tmp_path / "one_light", sessions=False)
    (touch,) = leakage_report(scan(one_light), n_boot=100).modalities
    assert touch.background_top1 < 0.4 and not touch.leak  # chance is 1/6
    assert touch.input_top1 > 0.5
    assert main(["data", "check", str(leaky)]) == 0
    out = capsys.readouterr().out
    assert f"WARNING  {leaky / 'touch'}: touch: the no-contact frame" in out
    assert main(["data", "leakage", str(one_light), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)["modalities"]["touch"]
    assert d["press_videos"] is True and d["leak"] is False and d["input_top1"] > 0.5


# ---- the words: each verdict states its rule; no "nan" in the text, null in the JSON --------


def _position(top: tuple[float, float, float], centroid: tuple[float, float, float], leak: bool):
    from lookfeel.data.leakage import PositionLeakage, PositionScore

    return PositionLeakage(
        n_items=80,
        n_fabrics=10,
        image_px=(200, 200),
        post_uv=PositionScore(top[0], (top[1], top[2]), 5.2, 6.9),
        drape_centroid=PositionScore(centroid[0], (centroid[1], centroid[2]), 12.2, 14.5),
        chance=0.1,
        leak=leak,
    )


def test_position_verdict_states_the_interval_rule_it_applies(tmp_path: Path):
    """A QA rig's drape's top scored 0.235 [0.19, 0.30], 2.35x chance 0.1, and the verdict
    read "position top-1 is not far above chance (2x)", as if 0.235 were not: the rule is the
    interval's lower end, and the line now says so."""
    from lookfeel.data.leakage import LeakageReport

    clean = LeakageReport(
        tmp_path, (), position=_position((0.235, 0.1873, 0.2989), (0.1688, 0.1201, 0.23), False)
    )
    text = format_leakage(clean)
    assert "not far above chance" not in text
    assert (
        "  no leak found: the 95% intervals' lower ends of the drape's top and drape's "
        "centroid, 0.19 and 0.12, are below 2x chance 0.20\n"
    ) in text + "\n"
    leak = LeakageReport(
        tmp_path, (), position=_position((0.40, 0.33, 0.47), (0.169, 0.12, 0.23), True)
    )
    text = format_leakage(leak)
    assert (
        "  LEAK: where the drape lies identifies the fabric (the drape's top's 95% interval's "
        "lower end 0.33 is above 2x chance 0.20): the camera or post moved"
    ) in text
    assert "centroid's" not in text  # only the cue that leaks is named in the verdict
    # A lower end that two decimals print as the limit is shown with enough to tell them apart.
    near = LeakageReport(
        tmp_path, (), position=_position((0.25, 0.199, 0.3), (0.2, 0.2, 0.3), False)
    )
    assert (
        "no leak found: the drape's top's 95% interval's lower end 0.199 is below 2x chance "
        "0.200; the drape's centroid's 95% interval's lower end 0.200 is at 2x chance 0.200, "
        "not above it"
    ) in format_leakage(near)


def test_background_verdicts_state_the_interval_rule_they_apply(leaky: Path, clean: Path):
    report = leakage_report(scan(clean), n_boot=200)
    (depth,) = report.modalities
    lo = depth.background_ci95[0]
    assert not depth.leak and lo < 0.2
    text = format_leakage(report)
    assert (
        f"  no leak found: the background's 95% interval's lower end {lo:.2f} is below 2x "
        "chance 0.20"
    ) in text
    assert "not far above chance" not in text
    report = leakage_report(scan(leaky), n_boot=200)
    (depth,) = report.modalities
    times = depth.background_top1 / depth.chance
    assert (
        f"{times:.1f}x chance (its 95% interval's lower end {depth.background_ci95[0]:.2f} is "
        "above 2x chance 0.20); a model can learn"
    ) in format_leakage(report)


def test_press_video_verdicts_state_the_interval_rule(tmp_path: Path):
    report = leakage_report(scan(_write_presses(tmp_path / "one_light", sessions=False)), n_boot=50)
    (touch,) = report.modalities
    assert not touch.leak
    limit = 2 * touch.chance
    assert (
        f"  no leak found: the no-contact frame's 95% interval's lower end "
        f"{touch.background_ci95[0]:.2f} is below 2x chance {limit:.2f}"
    ) in format_leakage(report)


def test_no_background_pixel_reads_n_a_with_why_never_nan_and_json_null(tmp_path: Path):
    """Colour photos of cloth filling the frame: no pixel holds still, so there is no
    background to score; the text printed "background only   nan [ n/a ]"."""
    rng = np.random.default_rng(3)
    for f in range(1, 5):
        for k in range(3):
            path = tmp_path / "rig" / "color" / f"F{f:04d}_{k + 1}.png"
            path.parent.mkdir(parents=True, exist_ok=True)
            Image.fromarray(rng.integers(0, 256, (16, 16, 3), dtype=np.uint8)).save(path)
    report = leakage_report(scan(tmp_path / "rig"), n_boot=50)
    (color,) = report.modalities
    assert color.background_fraction == 0.0 and np.isnan(color.background_top1)
    text = format_leakage(report)
    assert "nan" not in text.lower()
    assert "  background only   n/a (no pixel is still across images)\n" in text
    assert "nothing to check: with no background pixel, there is no background to score" in text
    # A mask that marks no pixel once pooled says so, not "still".
    masked = dataclasses.replace(color, mask_source="room.png", pool=4)
    assert "n/a (mask room.png marks no pixel once pooled 4x4)" in format_leakage(
        dataclasses.replace(report, modalities=(masked,))
    )
    d = json.loads(json.dumps(report.to_dict(), allow_nan=False))  # strict JSON: no NaN
    entry = d["modalities"]["color"]
    assert entry["background_top1"] is None
    assert entry["background_top1_ci_low"] is None and entry["background_top1_ci_high"] is None
    assert entry["leak"] is False
    # A position with no score (no image with cloth) reads n/a too, and is null in the JSON.
    nothing = _position((float("nan"),) * 3, (float("nan"),) * 3, False)
    nothing = dataclasses.replace(
        nothing,
        post_uv=dataclasses.replace(nothing.post_uv, within_fabric_px=float("nan")),
    )
    text = format_leakage(dataclasses.replace(report, position=nothing))
    assert "nan" not in text.lower()
    assert "drape's top       n/a (no image with a drape's top found)   spread n/a / 6.9" in text
    assert "the drape's top has no 95% interval" in text
    d = json.loads(
        json.dumps(dataclasses.replace(report, position=nothing).to_dict(), allow_nan=False)
    )
    assert d["position"]["post_uv"]["top1"] is None
    assert d["position"]["post_uv"]["top1_ci_low"] is None


def test_a_background_above_chance_but_under_the_flag_is_said_to_be(clean: Path):
    """QA: "no leak found" was all a background read whose interval lay wholly above chance but
    under 2x chance: a weaker cue, said so now; one whose interval reaches chance is not."""
    import dataclasses

    from lookfeel.data.leakage import _verdict

    report = leakage_report(scan(clean), n_boot=200)
    (depth,) = report.modalities
    weak = dataclasses.replace(
        depth, background_top1=0.15, background_ci95=(0.12, 0.19), chance=0.1, leak=False
    )
    assert _verdict(weak, 2.0) == (
        "no leak found: the background's 95% interval's lower end 0.12 is below 2x chance "
        "0.20; yet the background scores above chance (0.15 top-1, its interval from 0.12, "
        "chance 0.10): a weaker session cue, which a model's background control would show"
    )
    none = dataclasses.replace(weak, background_ci95=(0.08, 0.19))
    assert "yet" not in _verdict(none, 2.0)


def test_a_leak_warning_names_the_pick_its_data_allows(tmp_path: Path):
    """QA: on 4 objects `data check` warned "pick-1-of-10 top-1 0.94 ... vs chance 0.25": a
    draw there offers the 4 objects, and the words now say pick 1 of 4."""
    from lookfeel.data.leakage import LeakageReport, ModalityLeakage
    from lookfeel.modality import Modality

    def touch(chance: float) -> ModalityLeakage:
        return ModalityLeakage(
            Modality.TOUCH, 12, round(1 / chance), (48, 64), 4, "no-contact", 1.0, 0.9,
            (0.8, 1.0), 0.94, (0.88, 1.0), chance, True, press_videos=True, input_top1=0.58,
        )  # fmt: skip

    four = LeakageReport(tmp_path, (touch(0.25),), noun="object")
    (problem,) = leakage_problems(four)
    assert "identifies the object at pick-1-of-4 top-1 0.94 [0.88, 1.00] vs chance 0.25" in (
        problem.message
    )
    assert format_leakage(four).startswith(
        f"Leak check of {tmp_path}: pick 1 of 4 top-1 [95% over objects] from raw pixels\n"
    )
    depth = dataclasses.replace(
        touch(0.1), modality=Modality.DEPTH, press_videos=False, mask_source="static"
    )
    both = LeakageReport(tmp_path, (depth, touch(0.25)), noun="object")
    assert [p.message.split(" top-1 ")[0].rsplit(" ", 1)[1] for p in leakage_problems(both)] == [
        "pick-1-of-10",
        "pick-1-of-4",
    ]
    assert format_leakage(both).startswith(
        f"Leak check of {tmp_path}: pick 1 of 10 (or of every object, where a modality has "
        "fewer) top-1 [95% over objects]"
    )
    position = _position((0.9, 0.8, 1.0), (0.2, 0.1, 0.3), True)
    (problem,) = leakage_problems(LeakageReport(tmp_path, (), position=position))
    assert "identifies the fabric at pick-1-of-10 top-1 0.90 vs chance 0.10" in problem.message


@pytest.mark.parametrize("holds", ["nothing", "no image", "labels only"])
def test_cli_data_leakage_refuses_a_folder_with_no_image_as_data_check_does(
    tmp_path: Path, capsys, holds: str
):
    """QA: ``data leakage EMPTY`` exited 0 with "background: none scored" (and ``--json`` an
    empty ``modalities``), a report of nothing that reads as no leak, where ``data check``
    fails in one line. Now the same line, exit 1, nothing on stdout, with or without
    ``--json``; one fabric still gets its report, each modality saying why it is not
    scored."""
    from lookfeel.cli import main

    root = tmp_path / "data"
    root.mkdir()
    if holds == "no image":
        (root / "depth").mkdir()
        (root / "notes.txt").write_text("to do\n", encoding="utf-8")
    elif holds == "labels only":
        (root / "labels.csv").write_text(
            LABELS_HEADER + "1,0,0.5,0.2,1,1,train\n", encoding="utf-8"
        )
    assert main(["data", "check", str(root), "--quiet"]) == 1
    (error,) = [line for line in capsys.readouterr().out.splitlines() if line.startswith("ERROR")]
    said = error.removeprefix("ERROR").strip()
    assert said.startswith(f"{root}: no usable image found: ")
    for json_flag in ([], ["--json"]):
        assert main(["data", "leakage", str(root), *json_flag]) == 1
        out, err = capsys.readouterr()
        assert out == "" and err == f"lookfeel: {said}\n"


def test_data_leakage_of_one_fabric_says_why_per_modality(tiny_dataset: Path, tmp_path, capsys):
    """One fabric with images: nothing can be scored, and each modality says why in one line
    (exit 0, as before)."""
    from lookfeel.cli import main

    root = tmp_path / "one"
    for sub in ("depth", "color", "touch"):
        (root / sub).mkdir(parents=True)
        for p in (tiny_dataset / sub).glob("F0001_*"):
            (root / sub / p.name).write_bytes(p.read_bytes())
    assert main(["data", "leakage", str(root)]) == 0
    out = capsys.readouterr().out
    for m in ("depth", "color", "touch"):
        assert f"\n{m}: not scored: needs two fabrics, one of them with two or more images" in out


def test_two_fabrics_are_too_few_to_decide_not_no_leak(tmp_path: Path, capsys):
    """QA: on 2 fabrics ``data leakage`` said "no leak found", though its bar (2x chance 0.50
    = 1.00) can never be passed: it now says the check cannot decide, in the text and the
    JSON (a verdict of its own); 3 fabrics (2x chance 0.67) are decided."""
    from lookfeel.cli import main
    from lookfeel.data.leakage import NO_LEAK, TOO_FEW, decidable

    two = _write_rig(tmp_path / "two", leak=True, fabrics=2)
    report = leakage_report(scan(two), n_boot=50)
    (depth,) = report.modalities
    assert depth.chance == 0.5 and depth.background_top1 == 1.0 and not depth.leak
    assert not decidable(depth.chance, 2.0) and depth.verdict() == TOO_FEW
    text = format_leakage(report)
    assert "no leak found" not in text
    assert (
        "\n  too few fabrics to decide (2): no top-1 can lie above 2x chance 1.00, so no leak "
        "could be found; 3 or more fabrics can tell"
    ) in text
    assert main(["data", "leakage", str(two)]) == 0
    assert "too few fabrics to decide (2)" in capsys.readouterr().out
    assert main(["data", "leakage", str(two), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["verdict"] == "too few fabrics" and d["leak"] is False
    assert d["modalities"]["depth"]["verdict"] == "too few fabrics"
    # data check warns of leaks only: nothing is said of one it cannot decide
    assert leakage_problems(report) == []
    # three fabrics can be decided: a leak is found; a clean background is "no leak"
    three = leakage_report(scan(_write_rig(tmp_path / "three", leak=True, fabrics=3)), n_boot=50)
    assert three.modalities[0].leak and three.verdict() == "leak"
    clean = leakage_report(scan(_write_rig(tmp_path / "clean3", leak=False)), n_boot=50)
    assert clean.verdict() == NO_LEAK == clean.to_dict()["modalities"]["depth"]["verdict"]


def test_a_position_of_two_fabrics_is_too_few_to_decide(tmp_path: Path):
    from lookfeel.data.leakage import LeakageReport

    whole = _position((1.0, 1.0, 1.0), (1.0, 1.0, 1.0), False)
    two = dataclasses.replace(whole, chance=0.5, n_fabrics=2)
    report = LeakageReport(tmp_path, (), position=two)
    text = format_leakage(report)
    assert "no leak found" not in text
    assert "  too few fabrics to decide (2): no top-1 can lie above 2x chance 1.00" in text
    d = report.to_dict()
    assert d["verdict"] == d["position"]["verdict"] == "too few fabrics"
    # Each position's interval as two numbers beside its top-1, no ``ci95`` pair.
    for cue in ("post_uv", "drape_centroid"):
        assert list(d["position"][cue]) == [
            "top1",
            "top1_ci_low",
            "top1_ci_high",
            "within_fabric_px",
            "overall_px",
        ]
    assert (d["position"]["post_uv"]["top1_ci_low"], d["data_root"]) == (1.0, str(tmp_path))
