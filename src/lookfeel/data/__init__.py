"""The data layer: scan files in the one layout into a `Catalog`, check them, decode and
preprocess images (cached), split fabrics, and draw training tuples.

    >>> catalog = scan("../shared/data/gelfabric")
    >>> catalog.summary()["fabrics"]
    100
"""

from lookfeel.data.augment import AugmentDraw, Augmenter
from lookfeel.data.catalog import PHYSICAL_LABELS, Catalog, Fabric, Item
from lookfeel.data.check import check_dataset
from lookfeel.data.datasets import TupleDataset
from lookfeel.data.images import (
    ImageError,
    ImageLoader,
    decode_depth,
    decode_rgb,
    depth_to_unit,
    fill_holes,
)
from lookfeel.data.labels import read_labels
from lookfeel.data.layout import parse_touch_name, scan
from lookfeel.data.problems import DatasetError, Problem
from lookfeel.data.recordings import drop_unpressed
from lookfeel.data.splits import (
    PAPER_EXCLUDED_IDS,
    PAPER_TEST_IDS,
    FabricSplit,
    SplitError,
    kmeans_clusters,
    paper_split,
    seen_fabric_split,
    stratified_fabric_folds,
    stratified_fabric_split,
)
from lookfeel.data.tensors import ImageStore

__all__ = [
    "PAPER_EXCLUDED_IDS",
    "PAPER_TEST_IDS",
    "PHYSICAL_LABELS",
    "AugmentDraw",
    "Augmenter",
    "Catalog",
    "DatasetError",
    "Fabric",
    "FabricSplit",
    "ImageError",
    "ImageLoader",
    "ImageStore",
    "Item",
    "Problem",
    "SplitError",
    "TupleDataset",
    "check_dataset",
    "decode_depth",
    "decode_rgb",
    "depth_to_unit",
    "drop_unpressed",
    "fill_holes",
    "kmeans_clusters",
    "paper_split",
    "parse_touch_name",
    "read_labels",
    "scan",
    "seen_fabric_split",
    "stratified_fabric_folds",
    "stratified_fabric_split",
]
