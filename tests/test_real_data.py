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
