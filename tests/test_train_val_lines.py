"""What ``lookfeel train``'s validation lines are measured on (QA, session 54).

They printed ``val touch_to_depth_top1 0.500 (chance 0.500)`` and no more, while `lookfeel
evaluate` of the same checkpoint on the same fabrics gave other numbers: validation scores
single presses, evaluate pools the run's ``data.presses`` of them (and gives intervals). The
block now says once over how many held-out fabrics it is and that a touch query is one press.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from lookfeel.cli import main

from ._tiny import write_tiny_dataset

TINY = Path(__file__).resolve().parents[1] / "configs" / "tiny.yaml"


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_tiny_dataset(tmp_path_factory.mktemp("val_lines") / "data", fabrics=6, drapes=3)


def test_the_validation_block_says_what_it_was_measured_on(
    data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    out = tmp_path / "run"
    args = ["train", "--config", str(TINY), "--data", str(data), "--out", str(out)]
    assert main([*args, "--set", "train.steps=4", "--set", "train.val_every=2"]) == 0
    lines = capsys.readouterr().out.splitlines()
    header = (
        "  validation on 2 held-out fabrics (one press a touch query; `lookfeel evaluate` pools "
        "2 presses a query, the run's data.presses, and gives intervals):"
    )
    assert lines.count(header) == 1  # tiny.yaml: train.val_fabrics 2, data.presses 2
    val = [i for i, line in enumerate(lines) if line.startswith("  val ")]
    assert len(val) == 9 and lines.index(header) == val[0] - 1
    assert "  val touch_to_depth_top1      0.500  (chance 0.500)" in lines  # 1 of 2 fabrics
    # the counts behind it, in metrics.jsonl beside the numbers
    last = json.loads((out / "metrics.jsonl").read_text(encoding="utf-8").splitlines()[-1])
    assert last["val/touch_to_depth_fabrics"] == 2 and last["val/depth_to_depth_fabrics"] == 2
    assert last["val/touch_to_depth_queries"] == 6  # 3 fold presses of each fabric, one a query
    assert len(json.loads((out / "split.json").read_text(encoding="utf-8"))["val"]) == 2


def test_the_header_for_other_splits_and_presses(tmp_path: Path):
    from lookfeel.cli.train import _held_out_fabrics, validation_header

    pairs = ["depth_to_depth", "touch_to_depth"]
    assert validation_header(3, "seen", 1, pairs) == (
        "  validation on the held-out items of 3 training fabrics (one press a touch query; "
        "`lookfeel evaluate` gives intervals):"
    )
    assert validation_header(1, "stratified", 3, ["depth_to_depth"]) == (
        "  validation on 1 held-out fabric (one image a query; `lookfeel evaluate` gives "
        "intervals):"
    )
    # the most fabrics any pair's queries came from; without the counts, the run's split.json
    val = {"a_to_b_top1": 0.5, "a_to_b_fabrics": 4, "b_to_a_top1": 0.2, "b_to_a_fabrics": 3}
    assert _held_out_fabrics(val, tmp_path) == 4
    assert _held_out_fabrics({"a_to_b_top1": 0.5}, tmp_path) is None
    (tmp_path / "split.json").write_text(
        json.dumps({"kind": "fold", "val": [3, 5, 8]}), encoding="utf-8"
    )
    assert _held_out_fabrics({"a_to_b_top1": 0.5}, tmp_path) == 3


def test_a_pair_with_queries_from_fewer_fabrics_says_so(
    data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
):
    import lookfeel.train
    from lookfeel.train import TrainResult

    def fake(config, data, out, resume=False):  # what validate returns, two pairs
        val = {
            "touch_to_depth_top1": 0.25,
            "touch_to_depth_chance": 0.25,
            "touch_to_depth_fabrics": 4,
            "depth_to_depth_top1": 0.5,
            "depth_to_depth_chance": 0.5,
            "depth_to_depth_fabrics": 2,
        }
        ck = out / "checkpoints" / "last.pt"
        return TrainResult(out, 4, ck, None, val)

    monkeypatch.setattr(lookfeel.train, "train", fake)
    args = ["train", "--config", str(TINY), "--data", str(data), "--out", str(tmp_path / "r")]
    assert main(args) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "  validation on 4 held-out fabrics (one press a touch query;" in lines[2]
    assert lines[3] == (
        "  val depth_to_depth_top1      0.500  (chance 0.500; queries from 2 of the 4 fabrics)"
    )
    assert lines[4] == "  val touch_to_depth_top1      0.250  (chance 0.250)"
