"""The real GelFabric depth data and labels (skipped when ../shared is absent)."""

from pathlib import Path

import numpy as np
import pytest

from lookfeel.config import DataConfig
from lookfeel.data import (
    ImageLoader,
    check_dataset,
    decode_depth,
    kmeans_clusters,
    paper_split,
    scan,
    stratified_fabric_split,
)
from lookfeel.modality import Modality

pytestmark = pytest.mark.real_data


def test_summary_matches_the_dataset_readme(real_data: Path):
    s = scan(real_data).summary()
    assert s["fabrics"] == 100
    assert s["items"] == {"depth": 1104}
    assert s["fabrics_with_physical_labels"] == 82
    assert s["fabrics_with_cluster"] == 100
    assert s["errors"] == 0
    assert s["labelled_without_images"] == [
        3,
        7,
        16,
        24,
        30,
        35,
        39,
        42,
        43,
        44,
        52,
        56,
        70,
        71,
        75,
        78,
        87,
        97,
        107,
    ]


def test_real_depth_decodes_in_millimetres(real_data: Path):
    item = scan(real_data).items(Modality.DEPTH)[0]
    d = decode_depth(item.path)
    assert d.shape == (224, 224) and d.dtype == np.uint16
    valid = d[d > 0]
    assert valid.min() > 600 and valid.max() < 1600
    x = ImageLoader(DataConfig()).load(item)
    assert x.shape == (1, 227, 227) and 0.0 <= float(x.min()) <= float(x.max()) <= 1.0


def test_real_data_checks_clean(real_data: Path):
    catalog = check_dataset(real_data)
    assert catalog.errors == ()
    assert len(catalog.warnings) == 19  # the held-back test fabrics and fabric 107


def test_paper_split_and_cluster_stratified_folds(real_data: Path):
    catalog = scan(real_data)
    split = paper_split(catalog)
    assert len(split.train) == 100 and split.test == ()
    clusters = catalog.clusters()
    fold = stratified_fabric_split(catalog.ids, clusters, n_test=18, seed=0)
    assert len(fold.test) == 18
    assert {clusters[i] for i in fold.test} == set(range(8))


def test_kmeans_on_real_labels(real_data: Path):
    catalog = scan(real_data)
    ours = kmeans_clusters(catalog, k=8, seed=0)
    labelled = [f.id for f in catalog.fabrics if f.has_physical_labels]
    assert len(labelled) == 82
    assert all(ours[i] is not None for i in labelled)
    assert all(ours[f.id] is None for f in catalog.fabrics if not f.has_physical_labels)
    assert len({ours[i] for i in labelled}) == 8


def test_real_depth_config_trains_embeds_and_evaluates(real_data: Path, tmp_path: Path, capsys):
    """The issue-7 workflow on the real data, at a few steps: train on all 100 fabrics, embed
    fabrics, evaluate the embeddings file."""
    import json

    from lookfeel.cli import main

    config = Path(__file__).resolve().parents[1] / "configs" / "real_depth.yaml"
    run, emb, rep = tmp_path / "run", tmp_path / "emb.npz", tmp_path / "report"
    fast = ["--set", "train.steps=4", "--set", "train.batch_size=8"]
    # Registered depth (since #12): the cache lets `embed` reuse training's registrations.
    fast += ["--set", f"data.cache_dir={tmp_path / 'cache'}"]
    args = ["--config", str(config), "--data", str(real_data), "--out", str(run), *fast]
    assert main(["train", *args]) == 0
    split = json.loads((run / "split.json").read_text(encoding="utf-8"))
    assert len(split["train"]) == 100 and split["val"] == []
    ckpt = str(run / "checkpoints" / "last.pt")
    assert (
        main(
            [
                "embed",
                "--checkpoint",
                ckpt,
                "--data",
                str(real_data),
                "--out",
                str(emb),
                "--split",
                "all",
            ]
        )
        == 0
    )
    with np.load(emb) as z:
        # The recipe's three networks side by side, 128 dimensions each.
        assert z["embeddings_depth"].shape == (1104, 3 * 128)
    assert (
        main(
            [
                "evaluate",
                "--embeddings",
                str(emb),
                "--data",
                str(real_data),
                "--out",
                str(rep),
                "--set",
                "n_boot=20",
            ]
        )
        == 0
    )
    metrics = json.loads((rep / "metrics.json").read_text(encoding="utf-8"))
    assert "depth_to_depth" in json.dumps(metrics)
