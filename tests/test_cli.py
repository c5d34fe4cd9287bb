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


def test_demo_on_real_data(real_data: Path, capsys):
    assert main(["demo", "--data", str(real_data)]) == 0
    out = capsys.readouterr().out
    assert "1104 images" in out and "100 of 100 fabrics" in out
