"""Every shipped config loads strictly; the paper's cite the table or figure they reproduce."""

from pathlib import Path

import pytest

from lookfeel.config import RunConfig, load_config
from lookfeel.modality import Modality, PressKind

CONFIGS = sorted((Path(__file__).resolve().parents[1] / "configs").rglob("*.yaml"))
PAPER = {p.stem: p for p in CONFIGS if p.parent.name == "paper"}


@pytest.mark.parametrize("path", CONFIGS, ids=[p.stem for p in CONFIGS])
def test_config_loads(path: Path):
    assert isinstance(load_config(RunConfig, path), RunConfig)


def test_paper_configs_cover_the_tables():
    assert set(PAPER) == {
        "flat",
        "cross_modal",
        "auxiliary",
        "multi_input",
        "cross_modal_aug",
        "multi_input_aug",
        "snn_depth",
        "cross_modal_depth_touch",
    }
    for path in PAPER.values():
        header = path.read_text().split("\n\n")[0]
        assert "Table" in header or "Figure" in header, path


def test_paper_configs_say_what_the_paper_says():
    c = {name: load_config(RunConfig, p) for name, p in PAPER.items()}
    for cfg in c.values():
        assert (cfg.train.lr, cfg.train.batch_size, cfg.train.steps) == (1e-3, 128, 25_000)
        assert cfg.model.backbone == "alexnet" and cfg.model.resolved_freeze == "to_fc6"
        assert cfg.loss.kind == "contrastive" and cfg.loss.margin == 2.0
    assert c["flat"].data.touch_kinds == (PressKind.FLAT,)
    assert not c["cross_modal"].model.cluster_head and c["auxiliary"].model.cluster_head
    assert c["multi_input"].data.presses == 3 and c["auxiliary"].data.presses == 1
    assert c["multi_input_aug"].data.augment[Modality.COLOR].gamma == (0.5, 2.0)
    assert c["snn_depth"].train.views == (Modality.DEPTH, Modality.DEPTH)
    assert c["cross_modal_depth_touch"].train.views == (Modality.DEPTH, Modality.TOUCH)
