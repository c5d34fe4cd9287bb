"""What ``index build`` and ``index info`` say of a library's calibration (QA, session 54).

Each pair's line printed ``top1 0.042`` without its chance, so a user could not see that 0.042
among 24 fabrics is chance and 0.000 below it; and the numbers are fitted and scored on the
library's own items (the threshold chosen so that the false-accept rate meets its target on the
very queries it is counted on), which the legend did not say.
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from lookfeel.cli import main
from lookfeel.index import Library, calibrate_pair
from lookfeel.index.calibrate import PairCalibration
from lookfeel.modality import Modality

IN_SAMPLE = (
    "(in-sample: fitted and scored on the library itself, its own items as the queries, each "
    "with the item itself left out; c, the threshold and how a pair is matched were chosen on "
    "these same queries, so false accept is the target met on the queries the threshold was "
    "fitted on, not a rate measured on new data; held-out numbers with intervals: "
    "`lookfeel evaluate` or `lookfeel cv`)"
)


def test_calibration_records_the_chance_of_its_top1():
    """A query's best match is ranked among all the gallery's fabrics: chance 1 / fabrics."""
    rng = np.random.default_rng(0)
    q = rng.normal(size=(30, 4))
    qf = np.repeat(np.arange(6), 5)
    g = rng.normal(size=(20, 4))
    gf = np.repeat(np.arange(1, 5), 5)  # 4 gallery fabrics, 3 of them the queries' too
    pc = calibrate_pair(q, qf, g, gf, Modality.TOUCH, Modality.DEPTH, folds=2)
    assert pc is not None and pc.fabrics == 4 and pc.chance == 0.25
    same = calibrate_pair(q, qf, q, qf, Modality.DEPTH, Modality.DEPTH, folds=3)
    assert same is not None and same.chance == pytest.approx(1 / 6)
    assert same.to_dict()["chance"] == pytest.approx(1 / 6)
    assert PairCalibration.from_dict(json.loads(json.dumps(same.to_dict()))) == same


@pytest.fixture(scope="module")
def built(run, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[str]]:
    """(LIB, what `index build` printed): a library of the tiny run, built once."""
    import contextlib
    import io

    data, ckpt = run
    out = tmp_path_factory.mktemp("calibration-text") / "lib"
    argv = ["index", "build", "--checkpoint", str(ckpt), "--data", str(data), "--out", str(out)]
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert main([*argv, "--quiet"]) == 0
    return out, printed.getvalue().splitlines()


def test_build_and_info_print_each_pairs_chance_and_say_the_numbers_are_in_sample(
    built: tuple[Path, list[str]], capsys: pytest.CaptureFixture[str]
):
    out, printed = built
    assert f"  {IN_SAMPLE}" in printed
    pairs = [line for line in printed if " top1 " in line]
    assert len(pairs) == 9  # depth, colour and touch against each other
    for line in pairs:  # 6 fabrics in each gallery
        assert " (chance 1/6 = 0.167)  c " in line and "unknown below P " in line
    assert main(["index", "info", str(out)]) == 0
    shown = capsys.readouterr().out.splitlines()
    assert f"    {IN_SAMPLE}" in shown
    lines = [line for line in shown if " top1 " in line]
    assert len(lines) == 9 and all(" (chance 1/6 = 0.167)  c " in x for x in lines)
    assert main(["index", "info", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    chances = [p["chance"] for p in info["calibration"]["pairs"].values()]
    assert len(chances) == 9 and all(c == pytest.approx(1 / 6) for c in chances)


def test_a_library_built_before_the_chance_was_recorded_reads_it_as_one_over_its_fabrics(
    built: tuple[Path, list[str]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    old = shutil.copytree(built[0], tmp_path / "old")
    manifest = json.loads((old / "manifest.json").read_text(encoding="utf-8"))
    for p in manifest["calibration"]["pairs"].values():
        assert math.isclose(p.pop("chance"), 1 / p["fabrics"])
    (old / "manifest.json").write_text(json.dumps(manifest), encoding="utf-8")
    cal = Library.open(old).calibration
    assert cal == Library.open(built[0]).calibration
    assert all(p.chance == 1 / p.fabrics for p in cal.pairs.values())
    assert main(["index", "info", str(old)]) == 0
    assert capsys.readouterr().out.count(" (chance 1/6 = 0.167)  c ") == 9
