"""Every subcommand in-process through `main(argv)`."""

import json
import re
from pathlib import Path

import pytest

from lookfeel.cli import main


def test_data_info_text_and_json(tiny_dataset: Path, capsys):
    assert main(["data", "info", str(tiny_dataset)]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^  fabrics +6 \(ids 1-6\)$", out, re.M)
    assert re.search(
        r"^  touch +30 presses \(5-5 per fabric\): flat 12, fold 18; 90 frames$", out, re.M
    )
    assert main(["data", "info", str(tiny_dataset), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["fabrics"] == 6
    assert info["items"] == {"depth": 18, "color": 18, "touch": 30}
    assert info["fabrics_with_physical_labels"] == 6


def test_bad_arguments_exit_2(capsys):
    with pytest.raises(SystemExit) as e:
        main(["data", "check", "x", "--require", "smell"])
    assert e.value.code == 2
    assert "unknown modality 'smell'" in capsys.readouterr().err
    assert main([]) == 2


def test_version(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.startswith("lookfeel 0.")


def test_demo_runs_end_to_end(tmp_path: Path, capsys):
    """The demo on a small world with 2-step runs (the real one: `make demo`)."""
    args = ["demo", "--out", str(tmp_path / "demo"), "--fabrics", "10", "--data", str(tmp_path)]
    assert main([*args, "--set", "train.steps=2", "--set", "data.image_size=24"]) == 0
    out = capsys.readouterr().out
    assert "Generating a synthetic world of 10 fabrics" in out
    assert "touch->depth top-1" in out and "Report:" in out and "Evaluation:" in out
    assert (tmp_path / "demo" / "evaluate" / "figures").is_dir()
    report = (tmp_path / "demo" / "reproduce" / "report.md").read_text()
    assert "## Table 4" in report
    assert main([*args, "--set", "train.steps=2", "--set", "data.image_size=24"]) == 0
    assert "Reusing the synthetic world" in capsys.readouterr().out
