"""What a press's contact statistics say about how an object feels, beside the network.

Issue #13's class targets are not met, hardness least of all (the network's head: 0.45, raw
pixels 0.52). This asks where hardness is. For every PhysiCLeAR press with a label, its views
as ``configs/physiclear.yaml`` embeds them (the deepest frame and 12 across the contact span,
difference images at 64 px, `ImageLoader.embed_array`) give 27 **contact statistics**: per
view, the mean absolute change from the no-contact frame, the share of pixels changed by more
than 4 and 12 grey levels, the 95th percentile of the change and its spread; taken at the
deepest frame, as mean and spread over the 12 across the span, and as the ratio of changed area
to mean change per view (how wide against how deep the gel is pushed as the press deepens: a
soft object gives way).

A logistic probe (standardised features, C = 0.1, fixed beforehand) is fitted on each fold's
training objects and scored per held-out press, over the same 5 object-disjoint folds as
``lookfeel cv`` (`stratified_fabric_folds`, split seed 0), beside the training majority class.
With ``--cv CV`` (a ``lookfeel cv`` folder of ``configs/physiclear.yaml``), the same probe on
each fold's seed-0 network embedding (averaged over the views), and on both together.
Accuracy with a 95% interval resampling held-out objects (`bootstrap_ci`).

    python -m benchmarks.bench_touch_contact [--data ../shared/data/physiclear] [--cv CV]
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from benchmarks.bench_decode_video import DEFAULT_VIDEOS

DEFAULT_DATA = DEFAULT_VIDEOS.parent
LABELS = ("hardness", "roughness", "bumpiness")
C = 0.1
"""The probe's inverse regularisation, chosen before any score was seen and never tuned."""


def contact_statistics(views: np.ndarray) -> np.ndarray:
    """(27,) statistics of one press's (V, S, S, 3) uint8 difference views (the deepest first,
    then V - 1 across the span, in time order; 128 is no change)."""
    change = np.abs(views.astype(np.float32) - 128.0).mean(-1)  # (V, S, S) grey levels
    per_view = np.stack(
        [
            change.mean((1, 2)),
            (change > 4).mean((1, 2)),
            (change > 12).mean((1, 2)),
            np.percentile(change, 95, axis=(1, 2)),
            change.std((1, 2)),
        ],
        axis=1,
    )  # (V, 5)
    span = per_view[1:]
    area_per_depth = span[:, 1] / (span[:, 0] + 1e-3)
    return np.concatenate([per_view[0], span.mean(0), span.std(0), area_per_depth])


def _probe(x: np.ndarray, y: np.ndarray, train: np.ndarray, test: np.ndarray) -> np.ndarray:
    from sklearn.linear_model import LogisticRegression
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    clf = make_pipeline(StandardScaler(), LogisticRegression(C=C, max_iter=3000))
    clf.fit(x[train], y[train])
    return np.asarray(clf.predict(x[test]))


def run(data: Path | None, physiclear: Path | None = None, cv: Path | None = None) -> dict:
    """Measure; the `benchmarks` runner's entry point (``data``: a GelFabric root, whose
    sibling ``physiclear`` is used, else ../shared/data/physiclear)."""
    import torch

    from lookfeel.checkpoint import load_model
    from lookfeel.config import RunConfig, load_config
    from lookfeel.data import ImageLoader, scan
    from lookfeel.data.recordings import drop_unpressed
    from lookfeel.data.splits import stratified_fabric_folds
    from lookfeel.metrics import bootstrap_ci
    from lookfeel.metrics.classes import majority_class
    from lookfeel.modality import Modality

    root = physiclear
    if root is None:
        sibling = None if data is None else data.parent / "physiclear"
        root = sibling if sibling is not None and sibling.is_dir() else DEFAULT_DATA
    if not (root / "videos").is_dir():
        return {"skipped": f"real press videos not found at {root / 'videos'}", "met": None}
    config = load_config(RunConfig, Path(__file__).parents[1] / "configs" / "physiclear.yaml")
    loader = ImageLoader(config.data)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the 3 videos without a press
        catalog = drop_unpressed(scan(root), loader)  # decodes every press's views, once
    items = catalog.items(Modality.TOUCH)
    fabrics = {f.id: f for f in catalog.fabrics}
    object_of = np.array([it.fabric_id for it in items])
    stats = np.stack([contact_statistics(loader.embed_array(it)) for it in items])
    t = config.train
    folds = stratified_fabric_folds(
        catalog.ids, catalog.clusters(), t.folds, seed=t.split_seed, fold_size=t.fold_size
    )
    features: dict[str, list[np.ndarray]] = {"contact_statistics": [stats] * len(folds)}
    if cv is not None:
        views = torch.from_numpy(np.stack([loader.embed_array(it) for it in items]))
        x = views.permute(0, 1, 4, 2, 3).float().div_(255.0).unsqueeze(1)  # (N, 1, V, 3, S, S)
        emb = []
        for f in range(len(folds)):
            lm = load_model(cv / f"seed0-fold{f}" / "checkpoints" / "last.pt")
            if sorted(lm.split["val"]) != sorted(folds[f].test):
                raise SystemExit(f"{cv}: fold {f} holds out other objects than these folds")
            with torch.inference_mode():
                emb.append(lm.model({"touch": x})["touch"].numpy())
        features["embedding"] = emb
        features["embedding_and_contact_statistics"] = [np.hstack([e, stats]) for e in emb]
    result: dict[str, object] = {
        "presses": len(items),
        "objects": len(set(object_of.tolist())),
        "folds": len(folds),
        "probe": f"logistic regression, standardised, C={C}",
        "labels": {},
    }
    for col in LABELS:
        y = np.array([fabrics[int(o)].labels.get(col, np.nan) for o in object_of], float)
        known = ~np.isnan(y)
        per: dict[str, object] = {}
        for name, per_fold in [*features.items(), ("majority", [])]:
            hits, groups = [], []
            for f, split in enumerate(folds):
                train = known & np.isin(object_of, split.train)
                test = known & np.isin(object_of, split.test)
                if name == "majority":
                    guess = majority_class(y[train].astype(int), 3)
                    predicted = np.full(int(test.sum()), guess)
                else:
                    predicted = _probe(per_fold[f], y.astype(int, copy=False), train, test)
                hits.append(predicted == y[test])
                groups.append(object_of[test])
            h = np.concatenate(hits).astype(np.float64)
            low, high = bootstrap_ci(h, np.concatenate(groups), n_boot=1000, seed=0)
            ci = [round(float(low), 3), round(float(high), 3)]
            per[name] = {"accuracy": round(float(h.mean()), 3), "ci95": ci}
        result["labels"][col] = per  # type: ignore[index]
    result["met"] = None  # a measurement, not a target
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_touch_contact")
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA, help="PhysiCLeAR root")
    parser.add_argument("--cv", type=Path, default=None, help="a `lookfeel cv` folder")
    parser.add_argument("--out", type=Path, default=None, help="write the JSON here")
    args = parser.parse_args(argv)
    from benchmarks.__main__ import write_standalone

    started = time.time()
    result = run(None, args.data, args.cv)
    return write_standalone("touch_contact", started, result, args.out)


if __name__ == "__main__":
    sys.exit(main())
