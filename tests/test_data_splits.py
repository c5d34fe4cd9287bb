import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest

from lookfeel.cli import main
from lookfeel.config import RunConfig, load_config
from lookfeel.data import (
    PAPER_TEST_IDS,
    SplitError,
    kmeans_clusters,
    paper_split,
    scan,
    seen_fabric_split,
    stratified_fabric_folds,
    stratified_fabric_split,
)
from lookfeel.data.catalog import Catalog, Fabric, Item
from lookfeel.modality import Modality
from lookfeel.train import select_split

from ._tiny import write_tiny_dataset

TINY = Path(__file__).resolve().parents[1] / "src" / "lookfeel" / "configs" / "tiny.yaml"


def _catalog(n: int, clusters: int) -> Catalog:
    return Catalog(Path("."), tuple(Fabric(i, cluster=i % clusters) for i in range(1, n + 1)))


def _authors_catalog(n: int) -> Catalog:
    """Fabrics 1..n with one drape each in GelFabric's own depth folder, no labels."""
    depth = Path("kinect_depth_new")
    return Catalog(
        Path("."),
        tuple(
            Fabric(i, items={Modality.DEPTH: (Item(Modality.DEPTH, i, (depth / f"F{i}_0.png",)),)})
            for i in range(1, n + 1)
        ),
    )


def test_paper_split_from_column_or_builtin(tiny_dataset: Path):
    catalog = scan(tiny_dataset)
    assert paper_split(catalog).train == (1, 2, 3, 4, 5, 6)
    assert paper_split(catalog).test == ()
    assert paper_split(catalog).source == "labels"
    with pytest.warns(UserWarning, match=r"built-in list .* 3, 7, 16, .*, 97; 107 excluded; a "):
        builtin = paper_split(_authors_catalog(119))
    assert builtin.test == PAPER_TEST_IDS and builtin.source == "builtin"
    assert len(builtin.train) == 100 and 107 not in builtin.train


def _numbered(root: Path, test: tuple[int, ...] | None) -> Path:
    """8 fabrics in depth/, color/, touch/ with a user's own labels: a ``paper_split`` column
    marking ``test`` held out, or (None) no such column."""
    data = write_tiny_dataset(root, fabrics=8, drapes=2, fold_presses=1, flat_presses=0, frames=1)
    if test is None:
        rows = [f"{f},{0.7 * f:.2f},{f % 3}\n" for f in range(1, 9)]
        (data / "labels.csv").write_text(
            "fabric_id,bend_score,softness_rank\n" + "".join(rows), encoding="utf-8"
        )
    else:
        rows = [f"{f},{0.7 * f:.2f},{'test' if f in test else 'train'}\n" for f in range(1, 9)]
        (data / "labels.csv").write_text(
            "fabric_id,bend_score,paper_split\n" + "".join(rows), encoding="utf-8"
        )
    return data


def test_a_numbered_dataset_without_a_paper_split_column_holds_out_no_fabric(tmp_path: Path):
    """QA: GelFabric's built-in test ids (3, 7, ...) were held back from any numbered dataset
    whose labels.csv had no paper_split column: fabrics 3 and 7 silently in neither side."""
    catalog = scan(_numbered(tmp_path / "rig", test=None))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing is said: nothing is held back
        paper = paper_split(catalog)
    assert (paper.train, paper.test, paper.source) == (tuple(range(1, 9)), (), None)
    config = load_config(RunConfig, TINY, ["train.split=stratified", "train.val_fabrics=2"])
    train, val, info = select_split(catalog, config)
    assert val is not None and len(val.ids) == 2
    assert sorted(train.ids + val.ids) == list(range(1, 9))  # fabrics 3 and 7 included
    assert sorted(info["train"] + info["val"]) == list(range(1, 9))
    too_many = load_config(RunConfig, TINY, ["train.split=stratified", "train.val_fabrics=18"])
    with pytest.raises(SplitError, match=r"hold out 18 of 8 fabrics: .*\(train.val_fabrics\)$"):
        select_split(catalog, too_many)  # and no word of paper_split=test fabrics
    with pytest.raises(Exception, match="no fabric of this dataset is marked paper_split=test"):
        select_split(catalog, load_config(RunConfig, TINY, ["train.split=paper"]))


def test_a_paper_split_column_still_holds_out_its_test_fabrics(tmp_path: Path):
    catalog = scan(_numbered(tmp_path / "rig", test=(3, 7)))
    paper = paper_split(catalog)
    assert (paper.train, paper.test, paper.source) == ((1, 2, 4, 5, 6, 8), (3, 7), "labels")
    _, val, info = select_split(catalog, load_config(RunConfig, TINY, ["train.split=paper"]))
    assert val is not None and info["val"] == [3, 7]
    config = load_config(RunConfig, TINY, ["train.split=stratified", "train.val_fabrics=2"])
    train, val, _ = select_split(catalog, config)
    assert val is not None and not {3, 7} & set(train.ids + val.ids)  # never trained on
    with pytest.raises(SplitError, match=r"\(2 more fabric\(s\) marked paper_split=test in "):
        select_split(catalog, load_config(RunConfig, TINY, ["train.val_fabrics=18"]))
    seen = load_config(RunConfig, TINY, ["train.split=seen"])
    assert select_split(catalog, seen)[2]["novel"] == [3, 7]  # Table 4's novel fabrics


def test_gelfabric_in_its_authors_folders_keeps_the_built_in_list_and_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    data = _numbered(tmp_path / "gf", test=None)
    shutil.move(data / "depth", data / "kinect_depth_new")  # as the authors released it
    (data / "labels.csv").unlink()
    catalog = scan(data)
    with pytest.warns(UserWarning, match=r"has no labels.csv: .* never trained on: 3, 7;"):
        paper = paper_split(catalog)
    assert (paper.test, paper.source) == ((3, 7), "builtin")
    with pytest.warns(UserWarning), pytest.raises(SplitError, match="built-in test list"):
        select_split(catalog, load_config(RunConfig, TINY, ["train.val_fabrics=18"]))
    # `data info` shows the split training makes, and why.
    with pytest.warns(UserWarning, match="built-in list"):
        assert main(["data", "info", str(data)]) == 0
    assert "paper split  train 6, test 2" in capsys.readouterr().out


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
    (root / "labels.csv").write_text("".join(lines), encoding="utf-8")
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
