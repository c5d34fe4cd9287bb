"""Fabric splits and clusters: the paper's split, cluster-stratified fabric-disjoint splits and
folds, the within-fabric "seen fabrics" split of Table 4, and k-means clusters from labels."""

from __future__ import annotations

import math
import warnings
from collections import defaultdict
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from lookfeel.data.catalog import PHYSICAL_LABELS, Catalog, Item
from lookfeel.data.layout import FOLDER_ALIASES
from lookfeel.data.problems import DatasetError
from lookfeel.errors import LookfeelError

__all__ = [
    "AUTHORS_FOLDERS",
    "PAPER_EXCLUDED_IDS",
    "PAPER_TEST_IDS",
    "FabricSplit",
    "SplitError",
    "is_authors_gelfabric",
    "kmeans_clusters",
    "paper_split",
    "seen_fabric_split",
    "stratified_fabric_folds",
    "stratified_fabric_split",
]

PAPER_TEST_IDS = (3, 7, 16, 24, 30, 35, 39, 42, 43, 44, 52, 56, 70, 71, 75, 78, 87, 97)
"""The paper's 18 test fabrics, "selected evenly from the 8 clusters" (section 5)."""
PAPER_EXCLUDED_IDS = (107,)
"""Fabric 107, which the authors' code always excludes."""
AUTHORS_FOLDERS = frozenset(
    name
    for names in FOLDER_ALIASES.values()
    for name in names
    if name not in ("depth", "color", "touch", "videos")
)
"""GelFabric's own folder names, as its authors released it (``kinect_depth_new``, ``canon``,
``image_fold`` ...; ``image_rand*`` too): a dataset read through one of them is GelFabric, and
its paper split without a ``paper_split`` column is the built-in list."""


class SplitError(LookfeelError):
    """Fabrics cannot be split as asked (too few for the held-out count or folds); the message
    says how many there are and how many the split needs."""


@dataclass(frozen=True)
class FabricSplit:
    """Fabric ids on each side of a fabric-disjoint split.

    Attributes:
        train: the training side.
        test: the held-out side.
        source: for `paper_split`, where its test fabrics came from: ``"labels"`` (labels.csv's
            ``paper_split`` column) or ``"builtin"`` (`PAPER_TEST_IDS`, on GelFabric as its
            authors released it); None for any other split, and for data with no paper split.
    """

    train: tuple[int, ...]
    test: tuple[int, ...]
    source: Literal["labels", "builtin"] | None = None

    def __post_init__(self) -> None:
        both = set(self.train) & set(self.test)
        if both:
            raise ValueError(f"fabric(s) {sorted(both)} are on both sides of the split")


def is_authors_gelfabric(catalog: Catalog) -> bool:
    """Whether ``catalog`` was read through GelFabric's own folder names (`AUTHORS_FOLDERS`):
    GelFabric as its authors released it, whose test fabrics the built-in list names."""
    for f in catalog.fabrics:
        for items in f.items.values():
            folder = items[0].path.parent.name.lower() if items else ""
            if folder in AUTHORS_FOLDERS or folder.startswith("image_rand"):
                return True
    return False


def paper_split(catalog: Catalog) -> FabricSplit:
    """The paper's 100/18 split of the fabrics present in ``catalog``.

    Where the test fabrics come from:

    - the ``paper_split`` column of labels.csv, when any fabric has it (the shared GelFabric
      data, a ``lookfeel synth`` world): ``train`` fabrics train, ``test`` ones are held out,
      ``excluded`` ones are on neither side;
    - else, for GelFabric as its authors released it (read through their folder names,
      `is_authors_gelfabric`), the built-in list of the 18 test ids (`PAPER_TEST_IDS`), fabric
      107 excluded, with a warning naming the fabrics held out;
    - else none: every fabric is on the train side. A dataset of your own (numbered fabrics
      in depth/, color/, touch/, or named objects in videos/) is never split by GelFabric's ids;
      mark fabrics ``paper_split=test`` in labels.csv to hold them out so.

    Test fabrics absent from the data (as in the shared real data, which holds them back)
    simply do not appear. ``source`` of the result says which of the first two applied.

    Warns:
        UserWarning: the built-in list holds fabrics back (the second case).
    """
    labelled = {f.id: f.paper_split for f in catalog.fabrics if f.paper_split is not None}
    if labelled:
        train = tuple(i for i in catalog.ids if labelled.get(i) == "train")
        test = tuple(i for i in catalog.ids if labelled.get(i) == "test")
        return FabricSplit(train, test, "labels")
    if not is_authors_gelfabric(catalog):
        return FabricSplit(tuple(catalog.ids), ())
    train = tuple(i for i in catalog.ids if i not in PAPER_TEST_IDS + PAPER_EXCLUDED_IDS)
    test = tuple(i for i in catalog.ids if i in PAPER_TEST_IDS)
    dropped = [i for i in catalog.ids if i in PAPER_EXCLUDED_IDS]
    if test or dropped:
        held = ", ".join(map(str, test)) or "none"
        also = f"; {', '.join(map(str, dropped))} excluded" if dropped else ""
        lacks = (
            "its labels.csv has no paper_split column"
            if (catalog.root / "labels.csv").exists()
            else "it has no labels.csv"
        )
        warnings.warn(
            f"{catalog.root} is GelFabric in its authors' folders and {lacks}: the paper's test "
            f"fabrics on the built-in list are held out, never trained on: {held}{also}; a "
            "paper_split column in labels.csv (train, test or excluded per fabric) chooses them "
            "instead",
            stacklevel=2,
        )
    return FabricSplit(train, test, "builtin")


def _by_cluster(
    fabric_ids: Sequence[int], clusters: Mapping[int, int | None]
) -> dict[int, list[int]]:
    groups: dict[int, list[int]] = defaultdict(list)
    for i in sorted(set(fabric_ids)):
        c = clusters.get(i)
        groups[-1 if c is None else int(c)].append(i)  # unclustered fabrics form one stratum
    return dict(sorted(groups.items()))


def stratified_fabric_split(
    fabric_ids: Sequence[int],
    clusters: Mapping[int, int | None],
    n_test: int | None = None,
    test_fraction: float = 0.18,
    seed: int = 0,
    excluded: int = 0,
    warn: bool = True,
    excluded_by: Literal["labels", "builtin"] = "labels",
) -> FabricSplit:
    """A fabric-disjoint split with test fabrics spread evenly over clusters (as the paper).

    Each cluster gets a share of the ``n_test`` test fabrics proportional to its size (largest
    remainder; every cluster with at least two fabrics gets one when ``n_test`` allows), and
    its test fabrics are drawn at random with ``seed``.

    Args:
        fabric_ids: the fabrics to split.
        clusters: fabric id -> cluster (``None``: an "unclustered" stratum).
        n_test: number of test fabrics; default ``round(test_fraction * len(fabric_ids))``.
        test_fraction: used when ``n_test`` is None.
        seed: random seed.
        excluded: how many fabrics the caller kept out of ``fabric_ids`` beforehand (the
            paper's test fabrics); errors say so, since the user counts every fabric.
        excluded_by: who held those back (`FabricSplit.source` of the paper split): labels.csv's
            ``paper_split`` column, or GelFabric's built-in list; errors name it.
        warn: warn when fewer fabrics are left to train on than are held out (off where the
            held-out side is not what trains, e.g. choosing cross-validation's tested fabrics).

    Raises:
        SplitError: ``n_test`` is not between 1 and one less than the number of fabrics.

    Warns:
        UserWarning: fewer fabrics are left to train on than are held out.
    """
    ids = sorted(set(fabric_ids))
    n = len(ids)
    k = round(test_fraction * n) if n_test is None else n_test
    if not 0 < k < n:
        if n < 2:
            raise SplitError(
                f"{n} fabric(s) cannot be split into training and held-out fabrics; a "
                f"fabric-disjoint split needs at least 2{_left_out(excluded, excluded_by)}"
            )
        raise SplitError(
            f"cannot hold out {k} of {n} fabrics: n_test must be between 1 and {n - 1} "
            f"(train.val_fabrics){_left_out(excluded, excluded_by)}"
        )
    groups = _by_cluster(ids, clusters)
    sizes = {c: len(g) for c, g in groups.items()}
    quota = {c: k * s / n for c, s in sizes.items()}
    take = {c: math.floor(q) for c, q in quota.items()}
    eligible = [c for c in groups if sizes[c] >= 2]
    if k >= len(eligible):  # evenly: every cluster that can spare a fabric gives one
        for c in eligible:
            take[c] = max(take[c], 1)
    rng = np.random.default_rng(seed)
    order = sorted(groups, key=lambda c: (-(quota[c] - math.floor(quota[c])), rng.random()))
    # Top up by remainder order, first keeping a training fabric in every cluster; only when
    # that cannot reach n_test (e.g. clusters of one fabric) may a cluster go wholly to test.
    for spare in (1, 0):
        while sum(take.values()) < k and any(take[c] < sizes[c] - spare for c in order):
            for c in order:
                if sum(take.values()) < k and take[c] < sizes[c] - spare:
                    take[c] += 1
    floor_of = {c: 1 if c in eligible and k >= len(eligible) else 0 for c in groups}
    while sum(take.values()) > k:  # the forced ones overshot: trim the most over-served cluster
        c = max((c for c in take if take[c] > floor_of[c]), key=lambda c: take[c] - quota[c])
        take[c] -= 1
    test: list[int] = []
    for c, g in groups.items():
        if take[c]:
            test.extend(int(x) for x in rng.choice(g, size=take[c], replace=False))
    test_set = set(test)
    if warn and n - k < k:
        warnings.warn(
            f"holding out {k} of {n} fabrics leaves {n - k} to train on"
            f"{_left_out(excluded, excluded_by)}; lower train.val_fabrics to train on more",
            stacklevel=2,
        )
    return FabricSplit(tuple(i for i in ids if i not in test_set), tuple(sorted(test_set)))


def _left_out(excluded: int, by: Literal["labels", "builtin"]) -> str:
    """What an error adds about the ``excluded`` paper test fabrics a caller left out."""
    if not excluded:
        return ""
    held_by = (
        "on the paper's built-in test list (GelFabric in its authors' folders)"
        if by == "builtin"
        else "marked paper_split=test in labels.csv"
    )
    return f" ({excluded} more fabric(s) {held_by} are never trained on and are not counted)"


def stratified_fabric_folds(
    fabric_ids: Sequence[int],
    clusters: Mapping[int, int | None],
    n_folds: int = 5,
    seed: int = 0,
    fold_size: int | None = None,
    excluded: int = 0,
    excluded_by: Literal["labels", "builtin"] = "labels",
) -> list[FabricSplit]:
    """K fabric-disjoint folds, each cluster's fabrics dealt evenly across the folds.

    Without ``fold_size`` every fabric is in exactly one fold's test side and fold sizes differ
    by at most one. With it, each fold tests exactly ``fold_size`` fabrics: ``n_folds *
    fold_size`` fabrics are first chosen evenly over the clusters (as `stratified_fabric_split`
    chooses a test set; e.g. 5 folds of 18 of 100 fabrics, as the paper's 18 test fabrics), the
    rest are on the training side of every fold.

    ``excluded`` and ``excluded_by`` are as in `stratified_fabric_split`.

    Raises:
        SplitError: too few fabrics for ``n_folds`` (of ``fold_size``).
    """
    ids = sorted(set(fabric_ids))
    if not 2 <= n_folds <= len(ids):
        raise SplitError(
            f"{n_folds} folds of {len(ids)} fabric(s): train.folds must be between 2 and {len(ids)}"
            if len(ids) >= 2
            else f"{len(ids)} fabric(s) cannot be split into folds; at least 2 are needed"
        )
    tested = ids
    if fold_size is not None:
        if fold_size < 1 or n_folds * fold_size > len(ids):
            raise SplitError(
                f"{n_folds} folds of {fold_size} fabrics need {n_folds * fold_size} training "
                f"fabrics (train.folds x train.fold_size, cv's --folds x --fold-size); there "
                f"are {len(ids)}"
                + _left_out(excluded, excluded_by)
                + (
                    f"; train.fold_size={len(ids) // n_folds} (--fold-size {len(ids) // n_folds}) "
                    "fits"
                    if len(ids) >= n_folds
                    else ""
                )
            )
        if n_folds * fold_size < len(ids):
            # Choosing the fabrics that are ever tested: each fold trains on all but its own.
            chosen = stratified_fabric_split(
                ids, clusters, n_test=n_folds * fold_size, seed=seed, warn=False
            )
            tested = list(chosen.test)
    rng = np.random.default_rng(seed)
    folds: list[list[int]] = [[] for _ in range(n_folds)]
    # Deal the clusters' shuffled members round-robin, the deal continuing from one cluster to
    # the next: per fold, each cluster's count and the total differ by at most one.
    dealt = 0
    for _, group in _by_cluster(tested, clusters).items():
        for fid in rng.permutation(group):
            folds[dealt % n_folds].append(int(fid))
            dealt += 1
    out = []
    for test in folds:
        t = set(test)
        out.append(FabricSplit(tuple(i for i in ids if i not in t), tuple(sorted(t))))
    return out


def seen_fabric_split(
    catalog: Catalog, train_fraction: float = 0.8, seed: int = 0
) -> tuple[Catalog, Catalog]:
    """The "seen fabrics" split of Table 4: within every fabric and modality, a random
    ``train_fraction`` of the items for training and the rest for testing.

    A fabric with at least two items of a modality keeps at least one on each side.

    Returns:
        (train catalog, test catalog), with the same fabrics and disjoint items.
    """
    if not 0.0 < train_fraction < 1.0:
        raise ValueError(f"train_fraction must be in (0, 1), got {train_fraction}")
    rng = np.random.default_rng(seed)
    train: list[Item] = []
    test: list[Item] = []
    for f in catalog.fabrics:
        for m in sorted(f.items, key=lambda m: m.value):
            items = list(f.items[m])
            order = rng.permutation(len(items))
            n_train = round(train_fraction * len(items))
            if len(items) >= 2:
                n_train = min(max(n_train, 1), len(items) - 1)
            train.extend(items[i] for i in order[:n_train])
            test.extend(items[i] for i in order[n_train:])
    return catalog.with_items(train), catalog.with_items(test)


def kmeans_clusters(
    catalog: Catalog,
    k: int = 8,
    columns: Iterable[str] = PHYSICAL_LABELS,
    seed: int = 0,
) -> dict[int, int | None]:
    """Cluster fabrics by k-means on standardised labels (the paper's 8 clusters, section 3).

    Each column is standardised to zero mean and unit variance over the fabrics that have it;
    a fabric's unknown cells are then set to 0 (the column mean). Fabrics with no known value in
    ``columns`` get ``None``. Clusters are numbered by increasing mean of the first column, so
    the numbering does not depend on the k-means initialisation.

    Raises:
        DatasetError: fewer labelled fabrics than clusters, or no such label column.
    """
    from sklearn.cluster import KMeans

    cols = list(columns)
    missing_cols = [c for c in cols if c not in catalog.label_columns]
    if missing_cols:
        raise DatasetError(
            f"no label column(s) {', '.join(missing_cols)} in labels.csv "
            f"(have: {', '.join(catalog.label_columns) or 'none'})",
            catalog.root,
        )
    matrix = catalog.label_matrix(cols)
    ids = [i for i, row in matrix.items() if not all(math.isnan(v) for v in row)]
    if len(ids) < k:
        raise DatasetError(
            f"k-means into {k} clusters needs at least {k} labelled fabrics, found {len(ids)}",
            catalog.root,
        )
    x = np.array([matrix[i] for i in ids], dtype=np.float64)
    mean = np.nanmean(x, axis=0)
    std = np.nanstd(x, axis=0)
    std[~(std > 0)] = 1.0
    z = np.nan_to_num((x - mean) / std, nan=0.0)
    km = KMeans(n_clusters=k, n_init=10, random_state=seed).fit(z)
    order = np.argsort(km.cluster_centers_[:, 0], kind="stable")
    rename = {int(old): new for new, old in enumerate(order)}
    out: dict[int, int | None] = {i: None for i in catalog.ids}
    out.update({i: rename[int(c)] for i, c in zip(ids, km.labels_, strict=True)})
    return out
