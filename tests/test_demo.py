"""The demo's checks: what it is asked is refused before it renders or trains anything."""

from __future__ import annotations

from pathlib import Path

import pytest

import lookfeel.demo as demo
from lookfeel.cli import main
from lookfeel.config import ConfigError


class _Generated(Exception):
    """Raised by the stand-in for the world's rendering: the checks let the demo start."""


@pytest.fixture
def no_world(monkeypatch: pytest.MonkeyPatch) -> None:
    def fake_generate(config, world, progress):
        raise _Generated

    monkeypatch.setattr(demo, "generate", fake_generate)


def test_a_bad_override_is_refused_before_the_world_is_made(tmp_path: Path, no_world, capsys):
    out = tmp_path / "demo"
    with pytest.raises(ConfigError, match="unknown key train.stepz"):
        demo.run_demo(out, fabrics=20, overrides=["train.stepz=1"], log=lambda line: None)
    # A value that only one of the runs' configs refuses is caught too.
    with pytest.raises(ConfigError, match="train.steps"):
        demo.run_demo(out, fabrics=20, overrides=["train.steps=0"], log=lambda line: None)
    assert main(["demo", "--out", str(out), "--fabrics", "20", "--set", "train.stepz=1"]) == 1
    assert "unknown key train.stepz" in capsys.readouterr().err
    assert not out.exists()
    with pytest.raises(_Generated):  # good overrides pass
        demo.run_demo(out, fabrics=20, overrides=["train.steps=2"], log=lambda line: None)


def test_a_world_too_small_for_the_runs_is_refused_with_its_true_numbers(
    tmp_path: Path, no_world, capsys
):
    out = tmp_path / "demo"
    # 5 fabrics: 2 held out, 3 to train on; with fewer than 10 held out the reproduction
    # validates on 2 of those 3, and its runs draw 3 different fabrics per training tuple.
    assert main(["demo", "--out", str(out), "--fabrics", "5"]) == 1
    assert capsys.readouterr().err == (
        "lookfeel: demo: 5 fabrics with 2 held out: the flat run trains on 1 fabric(s) (it "
        "validates on 2 of the 3 not held out, as the reproduction does with fewer than 10 held "
        "out) and draws 3 different fabrics for each training tuple; use --fabrics 7 or more "
        "(--fabrics, --test-fabrics)\n"
    )
    # With 10 held out the runs train on all the others: 2 are too few, 3 enough.
    want = r"12 fabrics with 10 held out: the flat run trains on 2 fabric\(s\) and draws 3 .*"
    with pytest.raises(ConfigError, match=want + "use --fabrics 13 or more"):
        demo.run_demo(out, fabrics=12, test_fabrics=10, log=lambda line: None)
    assert not out.exists()
    for fabrics, held in ((7, None), (13, 10)):  # the smallest worlds that run get going
        with pytest.raises(_Generated):
            demo.run_demo(out, fabrics=fabrics, test_fabrics=held, log=lambda line: None)
