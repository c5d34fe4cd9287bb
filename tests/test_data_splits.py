from pathlib import Path

import numpy as np
import pytest

from lookfeel.data import (
    PAPER_TEST_IDS,
    kmeans_clusters,
    paper_split,
    scan,
    seen_fabric_split,
    stratified_fabric_folds,
    stratified_fabric_split,
)
from lookfeel.data.catalog import Catalog, Fabric
from lookfeel.modality import Modality

from ._tiny import write_tiny_dataset


def _catalog(n: int, clusters: int) -> Catalog:
    return Catalog(Path("."), tuple(Fabric(i, cluster=i % clusters) for i in range(1, n + 1)))


def test_paper_split_from_column_or_builtin(tiny_dataset: Path):
    catalog = scan(tiny_dataset)
    assert paper_split(catalog).train == (1, 2, 3, 4, 5, 6)
    assert paper_split(catalog).test == ()
    builtin = paper_split(_catalog(119, 8))
    assert builtin.test == PAPER_TEST_IDS
    assert len(builtin.train) == 100 and 107 not in builtin.train


def test_stratified_split_is_disjoint_even_and_seeded():
    catalog = _catalog(100, 8)
    clusters = catalog.clusters()
    split = stratified_fabric_split(catalog.ids, clusters, n_test=18, seed=3)
    assert len(split.test) == 18 and len(split.train) == 82
    assert not set(split.test) & set(split.train)
    per_cluster = np.bincount([clusters[i] for i in split.test], minlength=8)
    assert per_cluster.min() >= 2 and per_cluster.max() <= 3  # 18 over 8 equal clusters
    assert split == stratified_fabric_split(catalog.ids, clusters, n_test=18, seed=3)
    assert split != stratified_fabric_split(catalog.ids, clusters, n_test=18, seed=4)
    with pytest.raises(ValueError, match="n_test must be between 1 and 99"):
        stratified_fabric_split(catalog.ids, clusters, n_test=100)


def test_every_cluster_is_represented_even_when_small():
    clusters = {i: 0 for i in range(1, 41)} | {41: 1, 42: 1, 43: 2, 44: 2}
    split = stratified_fabric_split(list(clusters), clusters, n_test=4, seed=0)
    assert {clusters[i] for i in split.test} == {0, 1, 2}


def test_singleton_clusters_still_give_test_fabrics():
    clusters = {i: i for i in range(1, 9)}  # every fabric its own cluster
    split = stratified_fabric_split(list(clusters), clusters, n_test=2, seed=0)
    assert len(split.test) == 2 and len(split.train) == 6


def test_folds_partition_the_fabrics():
    catalog = _catalog(100, 8)
    folds = stratified_fabric_folds(catalog.ids, catalog.clusters(), n_folds=5, seed=0)
    tests = [set(f.test) for f in folds]
    assert sorted(len(t) for t in tests) == [20] * 5
    assert set().union(*tests) == set(catalog.ids)
    assert sum(len(t) for t in tests) == 100
    for f in folds:
        counts = np.bincount([i % 8 for i in f.test], minlength=8)
        assert counts.max() - counts.min() <= 1


def test_seen_fabric_split_keeps_fabrics_and_splits_items(tmp_path: Path):
    catalog = scan(write_tiny_dataset(tmp_path / "d", fabrics=4, drapes=5))
    train, test = seen_fabric_split(catalog, 0.8, seed=0)
    assert train.ids == test.ids == catalog.ids
    for fid in catalog.ids:
        a = set(train.fabric(fid).items[Modality.DEPTH])
        b = set(test.fabric(fid).items[Modality.DEPTH])
        assert len(a) == 4 and len(b) == 1 and not a & b
    assert seen_fabric_split(catalog, 0.8, seed=0) == (train, test)


def test_kmeans_recovers_separated_groups_and_skips_unlabelled(tmp_path: Path):
    root = tmp_path / "d"
    write_tiny_dataset(root, fabrics=9, drapes=1, fold_presses=1, flat_presses=0, frames=1)
    lines = ["fabric_id,thickness_mm,density\n"]
    for f in range(1, 9):
        group = (f - 1) % 3
        lines.append(f"{f},{10 * group + 0.1 * f},{-5 * group}\n")
    lines.append("9,,\n")
    (root / "labels.csv").write_text("".join(lines))
    catalog = scan(root)
    clusters = kmeans_clusters(catalog, k=3, columns=["thickness_mm", "density"], seed=0)
    assert clusters[9] is None
    groups = {}
    for f in range(1, 9):
        groups.setdefault(clusters[f], set()).add((f - 1) % 3)
    assert all(len(v) == 1 for v in groups.values()) and len(groups) == 3
    assert clusters[1] == 0 and clusters[3] == 2  # numbered by increasing thickness
    assert kmeans_clusters(catalog, k=3, columns=["thickness_mm", "density"], seed=5) == clusters
    with pytest.raises(Exception, match="no label column.* stiffness"):
        kmeans_clusters(catalog, k=3, columns=["stiffness"])
    with pytest.raises(Exception, match="needs at least 12 labelled fabrics, found 8"):
        kmeans_clusters(catalog, k=12, columns=["thickness_mm"])
