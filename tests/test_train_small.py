"""Training on data too small to validate every pair: one depth image per fabric.

A pair whose held-out items give no query an item of its own fabric to find is "not scored",
with the reason, and the run finishes (it used to end in a traceback, or print ``nan``).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from lookfeel.cli import main
from lookfeel.config import RunConfig, load_config
from lookfeel.train import train

from ._tiny import write_tiny_dataset

TINY = Path(__file__).resolve().parents[1] / "configs" / "tiny.yaml"
SAME = "fewer than two held-out items per fabric"


@pytest.fixture(scope="module")
def one_drape(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Six fabrics, one depth image and one photo each (and several touch presses)."""
    return write_tiny_dataset(tmp_path_factory.mktemp("small") / "data", fabrics=6, drapes=1)


def _config(*overrides: str) -> RunConfig:
    return load_config(RunConfig, TINY, ["train.steps=4", *overrides])


@pytest.mark.parametrize(
    "pairs", [[], ["train.val_pairs=[depth_to_depth]"]], ids=["default", "asked"]
)
def test_a_seen_split_of_one_image_per_fabric_is_not_scored_and_writes_no_best(
    one_drape: Path, tmp_path: Path, pairs: list[str]
):
    """train.split=seen keeps a fabric's only depth image for training: nothing is held out.
    Without val_pairs this was an IndexError, with them (as `lookfeel reproduce`'s SNN) a
    KeyError; now the pair is not scored, best.pt is not written and the run says so."""
    config = _config("train.views=[depth,depth]", "train.split=seen", *pairs)
    why = f"no held-out depth item ({SAME})"
    with pytest.warns(UserWarning) as caught:
        result = train(config, one_drape, tmp_path / "run")
    said = [str(w.message) for w in caught if "not scored" in str(w.message)]
    assert said == [
        f"validation: depth_to_depth not scored: {why}; best.pt is not written "
        "(depth_to_depth picks it): use last.pt"
    ]
    assert result.validation == {"depth_to_depth_not_scored": why}
    assert result.best_checkpoint is None and result.last_checkpoint.is_file()
    assert not (tmp_path / "run" / "checkpoints" / "best.pt").exists()
    lines = (tmp_path / "run" / "metrics.jsonl").read_text(encoding="utf-8").splitlines()
    assert json.loads(lines[-1]) == {"step": 4, "val/depth_to_depth_not_scored": why}


def test_a_same_modality_pair_of_one_item_per_fabric_is_not_scored_not_nan(
    one_drape: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    """Held-out fabrics with one depth image each: depth to depth has nothing to find. It was
    printed as ``nan``; now it carries its reason, and the other pairs (touch to depth picks
    best.pt) are scored as before."""
    args = ["train", "--config", str(TINY), "--data", str(one_drape), "--out", str(tmp_path / "r")]
    with pytest.warns(UserWarning, match="not scored") as caught:
        assert main([*args, "--set", "train.steps=4"]) == 0
    printed = capsys.readouterr().out
    assert "nan" not in printed and "val touch_to_depth_top1" in printed
    assert (
        "  val depth_to_depth_top1      not scored: no held-out fabric has a second depth "
        f"item for a query to find ({SAME})"
    ) in printed.splitlines()
    (said,) = [str(w.message) for w in caught if "not scored" in str(w.message)]
    assert said == (
        f"validation: depth_to_depth not scored: no held-out fabric has a second depth item for "
        f"a query to find ({SAME}); color_to_color not scored: no held-out fabric has a second "
        f"color item for a query to find ({SAME})"
    )
    lines = (tmp_path / "r" / "metrics.jsonl").read_text(encoding="utf-8").splitlines()
    val = json.loads(lines[-1])
    assert "val/depth_to_depth_top1" not in val and "val/color_to_color_top3" not in val
    assert val["val/depth_to_depth_not_scored"].endswith(f"({SAME})")
    assert val["val/touch_to_depth_top1"] >= 0 and val["val/touch_to_touch_top1"] >= 0
    assert (tmp_path / "r" / "checkpoints" / "best.pt").is_file()
