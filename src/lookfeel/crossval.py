"""Fabric-disjoint cross-validation: train one config on every fold (and seed), score the fabrics
each fold held out, and put the model beside the raw-pixel baseline and chance.

The folds are ``train.folds`` cluster-stratified folds of ``train.fold_size`` fabrics (5 of 18:
five test sets chosen as the paper chose its 18); each must hold out at least 2 fabrics (or
objects: `MIN_HELD_OUT`), else cv refuses before training. Each run trains on the other
fabrics, is scored by its *last* checkpoint (no choice is made on the held-out fabrics), and
reports, per pair:

- pick 1 of 10 among the held-out fabrics (exact expectation), top-1 and top-3; touch pools
  ``presses`` presses of one fabric when that is above 1 (the Multi-input Net: default the
  config's ``data.presses``; each fabric's presses in seeded disjoint groups, embedded by the
  model's own press pooling, as `lookfeel evaluate` does), as a query and as the candidates
  of another sense's queries (the paper's Multi-input Net takes three presses wherever it
  embeds touch); touch to touch picks among single presses;
- the same for raw pixels (nearest neighbour on the preprocessed images; same-modality pairs);
- chance;
- for a model with a depth branch, the **background control** (on by default): the same
  queries scored again with every depth image's background replaced by another fabric's, the
  cloth kept (`lookfeel.data.background_swap.BackgroundControl`), for the model and for raw pixels
  (``model_swapped_top1``, ``raw_pixels_swapped_top1`` ...). A model that reads the cloth, not
  the room, scores the same; one that reads the capture session drops. When the rooms cannot
  be fitted the control is skipped and the summary says why (``background_control``). For
  registered depth also the **room control**: every depth image registered against the room
  fitted on its partner's own image, with no refit of a composite (``model_room_top1``,
  ``raw_pixels_room_top1`` ...): another session's registration of the same cloth;
- for touch recorded as press videos, the **untouched control** (always on): the same queries
  with every press replaced by a moment of its video with no contact
  (`lookfeel.data.touch_control.UntouchedControl`; ``model_untouched_top1``,
  ``raw_pixels_untouched_top1`` ...). The sensor's own light and drift identify a recording
  session; a model that reads the contact falls to chance there;
- when the fabrics have labels, the same queries matched in **label space**
  (``model_labels_top1``, `lookfeel.metrics.label_space`): each modality's embeddings mapped
  onto the labels by a ridge fitted on the run's training fabrics only, a query matched to the
  gallery item whose predicted labels are nearest;
- for pairs of two modalities, the same queries matched through a **cross-modal map**
  (``model_mapped_top1``, `lookfeel.metrics.cross_map`; no labels needed): each modality's
  embeddings carried into the other's by linear maps fitted on the run's training fabrics.

Over runs, each number gets its mean, its spread over runs, and a 95% interval from a bootstrap
that resamples the held-out fabrics (all their queries together). A pair none of whose queries has
an item of its own fabric to find (touch to touch when every held-out fabric's presses all went
into its query) gets no numbers but the reason (``not_scored`` in ``cv.json``). Each held-out
fabric (or object) also gets its own top-1 over every query it made in every run, beside raw pixels
(``per_item`` in ``cv.json``; the worst few in ``cv.md``): which items the model cannot tell apart.
Physical properties are predicted from the fabric-mean embeddings of the held-out fabrics by a
ridge probe fitted on the training fabrics of the same fold (R^2 and Spearman per label), again
beside raw pixels and, with depth and the background control on, beside the **room alone**
(`RoomProbe`: the same probe on each raw depth image's background pixels, no cloth). Where the
background follows the labels (as when each fabric was captured in its own session), the room
predicts them, and a model's probe is only as good as its lead over the room's.
For a model with class heads (``model.class_heads``: hardness 0/1/2, material ...), each held-out
press's class is read from the heads, one press at a time and with every press of an object
pooled, beside a 5-nearest-neighbour probe on the embeddings and on raw pixels and the training
majority class: accuracy (95% interval resampling held-out objects) and macro-F1.

What cv writes is strict JSON: a number no run could score is ``null``
(`lookfeel.atomic.finite_or_null`), and ``cv.md`` says ``n/a`` and why.

Every run lives in ``OUT/seed{S}-fold{F}/`` and its scores in ``result.json`` there; a rerun
skips finished runs and resumes an interrupted one, so a killed cross-validation loses at most
the steps since a run's last checkpoint.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from lookfeel.atomic import atomic_write_json, atomic_write_text, finite_or_null
from lookfeel.checkpoint import LoadedModel, load_model
from lookfeel.config import RunConfig
from lookfeel.config._core import ConfigError, to_dict
from lookfeel.data import (
    Catalog,
    ImageLoader,
    Item,
    SplitError,
    paper_split,
    scan,
    stratified_fabric_folds,
)
from lookfeel.data.background_swap import BackgroundControl
from lookfeel.data.images import stack_views
from lookfeel.data.leakage import room_pixels
from lookfeel.data.recordings import drop_unpressed
from lookfeel.data.touch_control import UntouchedControl
from lookfeel.embedding import EmbeddedItems, embed_items, press_pooler, raw_pixels
from lookfeel.errors import LookfeelError
from lookfeel.evaluate.core import no_query_scored, press_queries
from lookfeel.metrics import (
    EXACT_PICK,
    PairScore,
    QuerySet,
    bootstrap_ci,
    mean_and_spread,
    property_probe,
    score_distances,
    score_pairs,
)
from lookfeel.metrics.calibration import expected_calibration_error
from lookfeel.metrics.classes import (
    accuracy,
    knn_classes,
    logit_temperature,
    macro_f1,
    majority_class,
    softmax,
)
from lookfeel.metrics.cross_map import HUB_NEIGHBOURS, CrossMap, fit_cross_maps
from lookfeel.metrics.label_space import MIN_FABRICS, LabelSpace, fit_label_spaces
from lookfeel.modality import Modality, Pair
from lookfeel.train import run_started, select_split, train
from lookfeel.train.loop import as_trained
from lookfeel.train.validate import default_pairs

__all__ = ["RoomProbe", "cross_validate", "format_cv_summary", "score_checkpoint"]

RESULT = "result.json"
SUMMARY = "cv.json"
REPORT = "cv.md"
_KS = (1, 3)
_METHODS = (
    "model",
    "model_labels",
    "model_labels_swapped",
    "model_mapped",
    "model_mapped_swapped",
    "model_mapped_room",
    "raw_pixels",
    "model_swapped",
    "raw_pixels_swapped",
    "model_room",
    "model_labels_room",
    "raw_pixels_room",
    "model_untouched",
    "raw_pixels_untouched",
)
CONTROL_SEED = 0
"""Seeds the background control's pairing of images with other fabrics' backgrounds."""


def _run_config(config: RunConfig, fold: int, seed: int) -> RunConfig:
    t = dataclasses.replace(config.train, split="fold", fold=fold, seed=seed)
    return dataclasses.replace(config, train=t)


def _write_json(path: Path, data: Any, indent: int | None = None) -> None:
    """``data`` as strict JSON (`lookfeel.atomic.finite_or_null`), written atomically."""
    atomic_write_json(path, data, indent)


def _noun(catalog: Catalog) -> str:
    """What the data's items are called: ``object`` where the data names them (videos/
    sponge_0.mov), else ``fabric`` (as `lookfeel data info` says)."""
    return "object" if any(f.name is not None for f in catalog.fabrics) else "fabric"


def _count(n: int, noun: str) -> str:
    """``1 object``, ``3 objects``."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


MIN_HELD_OUT = 2
"""Fabrics (objects) a fold must hold out: among one, pick 1 of 10 and every probe is moot."""


def _fold_plan(catalog: Catalog, config: RunConfig, fold_list: Sequence[int]) -> dict[str, Any]:
    """Which fabrics (or objects) the folds hold out, checked before anything is trained: the
    same folds `lookfeel.train.select_split` makes, of the fabrics not kept for the paper's
    test (`paper_split`). Returns what ``cv.md``'s first line reports (``coverage`` in
    ``cv.json``): the held-out items of the folds run, the folds not run, the fabrics that no
    fold holds out (a ``train.fold_size``) and those never used, with why.

    Raises:
        SplitError: fewer than 2 folds, or a fold holding out fewer than `MIN_HELD_OUT` (one
            line naming ``--folds`` / ``--fold-size`` and how many there are), or folds too
            big for the fabrics (`stratified_fabric_folds`).
    """
    t = config.train
    noun = _noun(catalog)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # select_split says it, once, right after
        paper = paper_split(catalog)
    pool = list(paper.train) or catalog.ids
    never = [i for i in catalog.ids if i not in set(pool)]
    n = len(pool)
    kept = (
        ""
        if not never
        else f" ({_count(len(never), noun)} more, kept for the paper's test, never used)"
    )
    if t.folds < 2:
        raise SplitError(
            f"--folds {t.folds} (train.folds): cross-validation needs at least 2 folds"
        )
    if n < 2 * MIN_HELD_OUT:
        raise SplitError(
            f"{catalog.root} has {_count(n, noun)} to hold out{kept}; cross-validation needs at "
            f"least {2 * MIN_HELD_OUT}: 2 folds of {MIN_HELD_OUT} (a fold holding out one "
            f"{noun} finds it among itself alone, always right)"
        )
    if t.fold_size is not None and t.fold_size < MIN_HELD_OUT:
        raise SplitError(
            f"--fold-size {t.fold_size} (train.fold_size): a fold must hold out at least "
            f"{MIN_HELD_OUT} {noun}s to be scored (among one, pick 1 of 10 is always right); "
            f"use --fold-size {MIN_HELD_OUT} or more (at most {n // t.folds} for {t.folds} folds "
            f"of the {n} {noun}s)"
        )
    if t.fold_size is not None and t.folds * t.fold_size > n and n // t.folds < MIN_HELD_OUT:
        raise SplitError(  # `stratified_fabric_folds` would suggest a size of 1 or 0
            f"--folds {t.folds} of --fold-size {t.fold_size} (train.folds, train.fold_size) hold "
            f"out {t.folds * t.fold_size} {noun}s; {catalog.root} has {n}{kept}: use --folds "
            f"{n // MIN_HELD_OUT} or fewer with --fold-size {MIN_HELD_OUT}"
        )
    if t.fold_size is None and n // t.folds < MIN_HELD_OUT:
        raise SplitError(
            f"--folds {t.folds} (train.folds) of the {n} {noun}s of {catalog.root}{kept} "
            f"leaves {n // t.folds} held out in some fold; a fold must hold out at least "
            f"{MIN_HELD_OUT} to be scored (among one, pick 1 of 10 is always right): use "
            f"--folds {n // MIN_HELD_OUT} or fewer"
        )
    folds = stratified_fabric_folds(
        pool,
        catalog.clusters(),
        t.folds,
        seed=t.split_seed,
        fold_size=t.fold_size,
        excluded=len(paper.test),
        excluded_by=paper.source or "labels",
    )
    names = {f.id: f.display_name for f in catalog.fabrics}
    tested = [sorted(folds[f].test) for f in fold_list]
    not_run = [f for f in range(t.folds) if f not in fold_list]
    if paper.source == "builtin":
        why = "GelFabric's built-in list of the paper's test fabrics (and fabric 107, excluded)"
    else:
        marks = [catalog.fabric(i).paper_split for i in never]
        why = ", ".join(
            f"{marks.count(k)} marked paper_split={k}" if k else f"{marks.count(k)} unmarked"
            for k in dict.fromkeys(marks)
        )
        why += " in labels.csv (cv holds out and trains on the paper_split=train ones only)"
    return {
        "noun": noun,
        "items": len(catalog.ids),
        "held_out": sorted({i for test in tested for i in test}),
        "fold_sizes": [len(test) for test in tested],
        "folds_total": t.folds,
        "not_run": {
            "folds": not_run,
            "items": sorted({i for f in not_run for i in folds[f].test}),
        },
        "train_only": sorted(set(pool) - {i for f in folds for i in f.test}),
        "never_used": {
            "ids": never,
            "items": [names[i] for i in never],
            "why": why if never else None,
        },
    }


_NO_EFFECT = ("checkpoint_every", "log_every", "progress")
"""Train keys that do not change a run's result: runs differing only in them are the same."""


_NO_EFFECT_MODEL = ("class_temperature",)
"""Model keys that change neither training nor the cv's scores (`predict` reads them)."""


def _result_config(config: RunConfig) -> dict[str, Any]:
    """The config as plain data, without the keys that do not change the result."""
    d = to_dict(config)
    d["train"] = {k: v for k, v in d["train"].items() if k not in _NO_EFFECT}
    d["model"] = {k: v for k, v in d["model"].items() if k not in _NO_EFFECT_MODEL}
    return d


def _same_run(trained: RunConfig, asked: RunConfig) -> bool:
    """Whether a trained run's config is ``asked`` (what training resolves from the labels,
    `as_trained`, is no difference)."""
    return _result_config(trained) == _result_config(as_trained(asked, trained))


def _pairs(config: RunConfig) -> list[Pair]:
    return list(config.train.val_pairs) or default_pairs(config.train.modalities)


def _modalities(pairs: Sequence[Pair]) -> list[Modality]:
    """The modalities the pairs use, in name order."""
    return sorted({m for p in pairs for m in (p.query, p.gallery)}, key=lambda m: m.value)


def _pick(
    emb: dict[Modality, np.ndarray],
    fab: dict[Modality, np.ndarray],
    pairs: Sequence[Pair],
    queries: dict[Modality, QuerySet] | None = None,
) -> dict[Pair, PairScore]:
    """Exact pick 1 of 10, top-1 and top-3 per query, of each pair (`EXACT_PICK`); ``queries``:
    pooled sets of a modality (multi-press touch), its queries and another modality's
    candidates alike; else every item is a query and a candidate."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # fewer than 10 fabrics: chance says so
        return score_pairs(emb, fab, EXACT_PICK, pairs, queries=queries, galleries=queries)


def _pooled(q: QuerySet, emb: np.ndarray) -> QuerySet:
    """The same groups as ``q`` over other per-item vectors (raw pixels): each group's mean."""
    return QuerySet(np.asarray(emb, np.float64)[q.members].mean(axis=1), q.fabric, q.members)


def _cross_maps(
    train: dict[Modality, tuple[np.ndarray, np.ndarray, np.ndarray]],
    pairs: Sequence[Pair],
    train_queries: dict[Modality, QuerySet] | None = None,
) -> dict[Pair, CrossMap]:
    """The cross-modal map of every pair of two modalities with training items
    (`lookfeel.metrics.cross_map`); ``train``: per modality (fabric ids, embeddings, pixels).
    A modality in ``train_queries`` (pooled touch) is fitted from those, on either side of a
    pair, as its held-out queries and candidates are pooled."""
    items = {m: (e, f) for m, (f, e, _) in train.items()}
    pooled = {m: (q.emb, q.fabric) for m, q in (train_queries or {}).items()}
    maps = fit_cross_maps(items | pooled, pairs)
    return {p: maps[p] for p in pairs if p in maps}


def _mapped(
    maps: dict[Pair, CrossMap],
    emb: dict[Modality, np.ndarray],
    fab: dict[Modality, np.ndarray],
    pairs: Sequence[Pair],
    queries: dict[Modality, QuerySet] | None = None,
) -> dict[Pair, PairScore]:
    """Exact pick 1 of 10 of each pair in ``pairs`` through its cross-modal map (``queries``:
    pooled sets of a modality, as `_pick`'s queries and galleries: the map joins two
    modalities, so a pooled modality is pooled on either side)."""
    out = {}
    sets = {m: QuerySet.single(emb[m], fab[m]) for m in emb} | (queries or {})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # fewer than 10 fabrics: chance says so
        for p in pairs:
            q, g = sets[p.query], sets[p.gallery]
            dist = maps[p].distances(q.emb, g.emb)
            out[p] = score_distances(dist, q.fabric, g.fabric, EXACT_PICK)
    return out


def _labels(catalog: Catalog, fabric_ids: np.ndarray) -> np.ndarray:
    """(N, L) labels of each row's fabric, in ``catalog.label_columns`` order, NaN if unknown."""
    rows = catalog.label_matrix(catalog.label_columns)
    cols = len(catalog.label_columns)
    return np.array([rows[int(i)] for i in fabric_ids], dtype=np.float64).reshape(-1, cols)


def _probe(
    catalog: Catalog,
    train_x: np.ndarray,
    train_f: np.ndarray,
    test_x: np.ndarray,
    test_f: np.ndarray,
) -> dict[str, dict[str, float]]:
    if not catalog.label_columns:
        return {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return property_probe(
            train_x,
            _labels(catalog, train_f),
            test_x,
            _labels(catalog, test_f),
            "ridge",
            names=list(catalog.label_columns),
            train_fabric=train_f,
            test_fabric=test_f,
        )


class RoomProbe:
    """The control of the depth property probes: `_probe` on the room alone.

    Each raw depth image's background pixels (`lookfeel.data.leakage.room_pixels`, found once
    over every depth image of the catalog), z-scored on a run's training fabrics, stand in for
    the embedding. ``None`` from `__call__` when no pixel holds still or nothing is labelled.

    Example:
        >>> room = RoomProbe(catalog)
        >>> room(split["train"], split["val"])  # {"thickness_mm": {"r2": ..., ...}, ...}
    """

    def __init__(self, catalog: Catalog, workers: int = 1) -> None:
        self.catalog = catalog
        self.workers = workers
        self._x: np.ndarray | None = None
        self._fabric = np.zeros(0, dtype=np.int64)

    def _pixels(self) -> np.ndarray:
        if self._x is None:
            items = self.catalog.items(Modality.DEPTH)
            self._x = room_pixels(items, self.workers) if items else np.zeros((0, 0))
            self._fabric = np.array([it.fabric_id for it in items], dtype=np.int64)
        return self._x

    @property
    def background_pixels(self) -> int:
        """How many (pooled) pixels of each depth image are the room's."""
        return int(self._pixels().shape[1])

    def __call__(
        self, train_ids: Sequence[int], held_ids: Sequence[int]
    ) -> dict[str, dict[str, float]] | None:
        x = self._pixels()
        if not self.catalog.label_columns or x.shape[1] == 0:
            return None
        tr = np.isin(self._fabric, np.asarray(train_ids, dtype=np.int64))
        te = np.isin(self._fabric, np.asarray(held_ids, dtype=np.int64))
        if not tr.any() or not te.any():
            return None
        mu, sd = x[tr].mean(axis=0), x[tr].std(axis=0) + 1e-6
        z = (x - mu) / sd
        return _probe(self.catalog, z[tr], self._fabric[tr], z[te], self._fabric[te])


def _score(
    lm: LoadedModel,
    catalog: Catalog,
    held_ids: Sequence[int],
    seen_ids: Sequence[int],
    pairs: Sequence[Pair],
    tta: bool,
    loader: ImageLoader,
    control: BackgroundControl | None = None,
    untouched: UntouchedControl | None = None,
    presses: int = 1,
) -> dict[str, Any]:
    """Per-query pick 1 of 10 of the model and of raw pixels on ``held_ids``' items (touch
    queries pooling ``presses`` presses when above 1: the module doc), and
    property probes fitted on ``seen_ids``' items (none when it is empty). ``loader`` must
    preprocess as the model's config says; it keeps its decoded images for the next call.
    With ``control`` (made with the same data config) and depth among the pairs, also the
    background-swapped scores (``*_swapped``) and, for registered depth, the room control's
    (``*_room``), or ``background_control_skipped`` saying why not. Press videos are also
    scored untouched (``*_untouched``), with ``untouched`` if given (made with the same data
    config, it keeps its images for the next call). With labels and training fabrics, also
    matched in label space (``model_labels``)."""
    cfg = lm.config
    held = catalog.subset(held_ids)
    seen = catalog.subset(seen_ids) if seen_ids else None
    emb: dict[Modality, np.ndarray] = {}
    pix: dict[Modality, np.ndarray] = {}
    fab: dict[Modality, np.ndarray] = {}
    props: dict[str, Any] = {}
    train: dict[Modality, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    queries: dict[Modality, QuerySet] = {}  # pooled touch queries (presses > 1)
    train_queries: dict[Modality, QuerySet] = {}
    touch = Modality.TOUCH
    pool = press_pooler(lm.model, loader, flip=tta) if presses > 1 else None
    for m in _modalities(pairs):
        items: list[Item] = held.items(m, cfg.data.touch_kinds)
        train_items: list[Item] = seen.items(m, cfg.data.touch_kinds) if seen else []
        loader.preload([*items, *train_items])
        emb[m] = embed_items(lm.model, items, loader, flip=tta)
        pix[m] = raw_pixels(items, loader)
        fab[m] = np.array([it.fabric_id for it in items], dtype=np.int64)
        if m is touch and pool is not None:
            held_touch = EmbeddedItems(m, emb[m], fab[m], tuple(items))
            queries[m] = press_queries(held_touch, presses, 0, pool)
            if not len(queries[m].fabric):
                kinds = ", ".join(k.value for k in cfg.data.touch_kinds)
                raise ConfigError(
                    f"presses: no held-out fabric has {presses} touch presses ({kinds}) to "
                    "pool into a query; use fewer"
                )
        if train_items:
            train_f = np.array([it.fabric_id for it in train_items], dtype=np.int64)
            train_e = embed_items(lm.model, train_items, loader, flip=tta)
            train_pix = raw_pixels(train_items, loader)
            train[m] = (train_f, train_e, train_pix)  # the class probes fit on them too
            if m is touch and pool is not None:
                seen_touch = EmbeddedItems(m, train_e, train_f, tuple(train_items))
                train_queries[m] = press_queries(seen_touch, presses, 0, pool)
            props[m.value] = {
                "model": _probe(catalog, train_e, train_f, emb[m], fab[m]),
                "raw_pixels": _probe(catalog, train_pix, train_f, pix[m], fab[m]),
            }
    out: dict[str, Any] = {"step": lm.step, "test_fabrics": list(held_ids), "pairs": {}}
    model = _pick(emb, fab, pairs, queries)
    others: dict[str, dict[Pair, Any]] = {}  # every other method's scores, by method
    spaces = _label_spaces(catalog, train)
    mapped = [p for p in pairs if p.query in spaces and p.gallery in spaces]

    def in_labels(e: dict[Modality, np.ndarray], wanted: list[Pair]) -> dict[Pair, PairScore]:
        """``wanted`` matched in label space: each modality's embeddings (and pooled queries)
        projected onto the labels."""
        lab = {m: s.project(e[m]) for m, s in spaces.items()}
        lab_q = {
            m: QuerySet(spaces[m].project(q.emb), q.fabric, q.members)
            for m, q in queries.items()
            if m in spaces
        }
        return _pick(lab, fab, wanted, lab_q)

    if mapped:
        others["model_labels"] = in_labels(emb, mapped)
    maps = _cross_maps(train, pairs, train_queries)
    if maps:
        others["model_mapped"] = _mapped(maps, emb, fab, list(maps), queries)
    raw_q = {m: _pooled(q, pix[m]) for m, q in queries.items()}
    raw = _pick(pix, fab, [p for p in pairs if p.same], raw_q)  # raw pixels: images of one kind
    depth_pairs = [p for p in pairs if Modality.DEPTH in (p.query, p.gallery)]
    if control is not None and depth_pairs:
        items = held.items(Modality.DEPTH)
        try:
            sw = control.loader(items)
        except LookfeelError as e:
            out["background_control_skipped"] = str(e)
        else:
            variants = {"swapped": sw}
            if control.has_room_control:  # registered in the partner's room, not refitted
                variants["room"] = control.room_loader(items)
            for name, ld in variants.items():
                emb_v = emb | {Modality.DEPTH: embed_items(lm.model, items, ld, flip=tta)}
                pix_v = pix | {Modality.DEPTH: raw_pixels(items, ld)}
                others[f"model_{name}"] = _pick(emb_v, fab, depth_pairs, queries)
                if mapped:  # label space, its depth maps read on the altered images
                    lab_pairs = [p for p in mapped if p in depth_pairs]
                    others[f"model_labels_{name}"] = in_labels(emb_v, lab_pairs)
                if maps:
                    map_pairs = [p for p in maps if p in depth_pairs]
                    others[f"model_mapped_{name}"] = _mapped(maps, emb_v, fab, map_pairs, queries)
                raw_pairs = [p for p in depth_pairs if p.same]
                others[f"raw_pixels_{name}"] = _pick(pix_v, fab, raw_pairs)
    touch_pairs = [p for p in pairs if Modality.TOUCH in (p.query, p.gallery)]
    touch_items = held.items(Modality.TOUCH, cfg.data.touch_kinds) if touch_pairs else []
    if UntouchedControl.applies(touch_items):
        # The sensor's own light: every press replaced by a moment of its video with no contact.
        still = (untouched or UntouchedControl(cfg.data)).loader(touch_items)
        emb_un = emb | {touch: embed_items(lm.model, touch_items, still, flip=tta)}
        pix_un = pix | {touch: raw_pixels(touch_items, still)}
        q_un: dict[Modality, QuerySet] = {}
        raw_un: dict[Modality, QuerySet] = {}
        if touch in queries:  # the same groups of presses, each of its still moments
            members = queries[touch].members
            still_touch = EmbeddedItems(touch, emb_un[touch], fab[touch], tuple(touch_items))
            pooled = press_pooler(lm.model, still, flip=tta)(still_touch, members)
            q_un[touch] = QuerySet(pooled, queries[touch].fabric, members)
            raw_un[touch] = _pooled(queries[touch], pix_un[touch])
        others["model_untouched"] = _pick(emb_un, fab, touch_pairs, q_un)
        others["raw_pixels_untouched"] = _pick(
            pix_un, fab, [p for p in touch_pairs if p.same], raw_un
        )
    for pair in pairs:
        entry: dict[str, Any] = {
            "query_fabric": (
                queries[pair.query].fabric if pair.query in queries else fab[pair.query]
            ).tolist(),
            "model": model[pair].pick.per_query.tolist(),
            "chance": [float(c) for c in model[pair].pick.chance],
        }
        if pair in raw:
            entry["raw_pixels"] = raw[pair].pick.per_query.tolist()
        for method, scores in others.items():
            if pair in scores:
                entry[method] = scores[pair].pick.per_query.tolist()
        out["pairs"][pair] = entry
    out["properties"] = props
    out["classes"] = _classes(lm, catalog, held, train, loader, emb, pix, fab)
    return out


def _label_spaces(
    catalog: Catalog, train: dict[Modality, tuple[np.ndarray, np.ndarray, np.ndarray]]
) -> dict[Modality, LabelSpace]:
    """Each modality's map onto the labels, fitted on its training items (`fit_label_spaces`:
    the columns every modality maps); empty without labels or training fabrics."""
    columns = list(catalog.label_columns)
    if not columns or not train:
        return {}
    return fit_label_spaces(
        {m: (train_e, train_f) for m, (train_f, train_e, _) in train.items()},
        catalog.label_matrix(columns),
        columns,
    )


def _classes(
    lm: LoadedModel,
    catalog: Catalog,
    held: Catalog,
    train: dict[Modality, tuple[np.ndarray, np.ndarray, np.ndarray]],
    loader: ImageLoader,
    emb: dict[Modality, np.ndarray],
    pix: dict[Modality, np.ndarray],
    fab: dict[Modality, np.ndarray],
) -> dict[str, Any]:
    """Per modality and class-head column, the held-out queries' true and predicted classes:
    ``model`` (the head, one press), ``model_pooled`` (one per object, every press pooled),
    ``probe``/``raw_pixels`` (5-NN on training embeddings / pixels), ``majority``. ``train``:
    per modality, the training items' (fabric ids, embeddings, raw pixels) from `_score`."""
    import torch

    from lookfeel.data.datasets import class_matrix
    from lookfeel.models import CLASSES, eval_mode

    cfg = lm.config.model
    if not cfg.class_heads or not train:
        return {}
    out: dict[str, Any] = {}
    kinds = lm.config.data.touch_kinds
    for m, e in emb.items():
        if m not in train:
            continue
        branch = lm.model.branch(m.value)
        train_f, train_e, train_pix = train[m]
        with torch.inference_mode():
            logits = branch.heads(torch.from_numpy(e))[CLASSES].split(cfg.class_sizes, dim=-1)
        objects = sorted(set(fab[m].tolist()))
        pooled = []
        with torch.inference_mode(), eval_mode(lm.model):
            for fid in objects:
                items = held.fabric(fid).items_of(m, kinds)
                x = stack_views([loader.load_embedded(it) for it in items])
                x = x.unsqueeze(0) if m is Modality.TOUCH else x
                z = lm.model({m.value: x}, heads=True)[f"{m.value}/{CLASSES}"]
                pooled.append(z.amax(0) if m is not Modality.TOUCH else z[0])
        pooled_logits = torch.stack(pooled).split(cfg.class_sizes, dim=-1)
        fabrics = {f.id: f for f in catalog.fabrics}
        per: dict[str, Any] = {}
        for h, col in enumerate(cfg.class_heads):
            n = len(cfg.classes[col])
            one = {col: cfg.classes[col]}
            truth = class_matrix([fabrics[int(i)] for i in fab[m]], one)[:, 0]
            train_c = class_matrix([fabrics[int(i)] for i in train_f], one)[:, 0]
            per[col] = {
                "classes": list(cfg.classes[col]),
                "query_fabric": fab[m].tolist(),
                "truth": truth.tolist(),
                "model": logits[h].argmax(-1).tolist(),
                "logits": np.round(logits[h].float().numpy(), 4).tolist(),
                "probe": knn_classes(train_e, train_c, e, n).tolist(),
                "raw_pixels": knn_classes(train_pix, train_c, pix[m], n).tolist(),
                "majority": [majority_class(train_c, n)] * len(truth),
                "object": objects,
                "object_truth": class_matrix([fabrics[i] for i in objects], one)[:, 0].tolist(),
                "model_pooled": pooled_logits[h].argmax(-1).tolist(),
            }
        out[m.value] = per
    return out


def score_checkpoint(
    checkpoint: str | Path,
    data: str | Path,
    *,
    pairs: Sequence[Pair | str] = (),
    tta: bool = False,
    n_boot: int = 1000,
    background_control: bool = True,
    presses: int | None = None,
) -> dict[str, Any]:
    """Score a trained model on every fabric of another dataset, beside raw pixels and chance.

    The transfer test of the synthetic world: a depth encoder trained on synthetic depth only,
    scored on real depth (pick 1 of 10 among all the dataset's fabrics).

    Args:
        checkpoint: a run's checkpoint.
        data: the dataset to score on (every fabric is a test fabric).
        pairs: pairs to score; default: the run's validation pairs, else every pair.
        tta: test-time pooling over each image and its mirror.
        n_boot: bootstrap resamples for the intervals.
        background_control: for depth pairs, also score with backgrounds swapped.
        presses: presses pooled into a touch query; default the run's ``data.presses``.

    Returns:
        ``{"pairs": {pair: {"model_top1": {"mean", "ci95", ...}, "raw_pixels_top1": ...,
        "model_swapped_top1": ..., "chance_top1": ...}}, "checkpoint", "data", "step",
        "background_control"}``.
    """
    lm = load_model(checkpoint)
    wanted = [Pair.parse(p) for p in pairs] or _pairs(lm.config)
    loader = ImageLoader(lm.config.data)
    catalog = drop_unpressed(scan(data, require=_modalities(wanted), strict=True), loader)
    control = BackgroundControl(lm.config.data, CONTROL_SEED) if background_control else None
    presses = lm.config.data.presses if presses is None else presses
    res = _score(lm, catalog, catalog.ids, [], wanted, tta, loader, control, None, presses)
    names = {f.id: f.display_name for f in catalog.fabrics}
    kinds = [k.value for k in lm.config.data.touch_kinds]

    def why(pair: Pair) -> str:
        return no_query_scored(pair, presses, kinds=kinds, option="presses=")

    summary = _summarise([res], wanted, n_boot, control is not None, names, why)
    return {
        "checkpoint": str(checkpoint),
        "data": str(data),
        "step": lm.step,
        "tta": tta,
        "presses": presses,
        "background_control": summary["background_control"],
        "pairs": summary["pairs"],
    }


def _evaluate_run(
    run_dir: Path,
    catalog: Catalog,
    pairs: Sequence[Pair],
    tta: bool,
    loader: ImageLoader,
    control: BackgroundControl | None,
    untouched: UntouchedControl,
    presses: int,
) -> dict:
    """Score a finished run's last checkpoint on its held-out fabrics."""
    lm = load_model(run_dir / "checkpoints" / "last.pt")
    split = lm.split
    return _score(
        lm, catalog, split["val"], split["train"], pairs, tta, loader, control, untouched, presses
    )


def _with_room(result: dict, run_dir: Path, room: RoomProbe | None) -> dict:
    """``result`` with the room-alone probe (`RoomProbe`) beside its depth probes, when the
    run has depth probes and the room has pixels to read; it depends only on the data and
    the split, so a kept result gets it without being scored again."""
    depth = result.get("properties", {}).get(Modality.DEPTH.value)
    if room is None or not depth:
        return result
    split = json.loads((run_dir / "split.json").read_text())
    probe = room(split["train"], split["val"])
    if probe is not None:
        depth["room"] = probe
    return result


def _control_status(results: list[dict], asked: bool) -> dict[str, Any]:
    """``{"on": bool, "seed": int, "skipped": reason or None}`` over the runs."""
    skipped = next(
        (r["background_control_skipped"] for r in results if "background_control_skipped" in r),
        None,
    )
    return {"on": asked and skipped is None, "seed": CONTROL_SEED, "skipped": skipped}


PER_ITEM_METHODS = ("model", "raw_pixels", "model_swapped")
"""The methods `_per_item` breaks down by held-out item (where a run scored them)."""


def _per_item(
    results: list[dict], pair: Pair, names: Mapping[int, str] | None
) -> list[dict[str, Any]]:
    """Each held-out item's top-1 as a query of ``pair``, over every query it made in every
    run: ``[{"item", "fabric_id", "queries", "runs", "model_top1", "raw_pixels_top1", ...}]``,
    worst model first (ties by name). Which fabrics or objects the model cannot tell apart,
    beside what raw pixels make of them; an item a query never came from is absent."""
    per = [r["pairs"][pair] for r in results]
    methods = [m for m in PER_ITEM_METHODS if all(m in p for p in per)]
    ids = np.concatenate([np.asarray(p["query_fabric"]) for p in per])
    runs = np.concatenate([np.full(len(p["query_fabric"]), i) for i, p in enumerate(per)])
    hits = {m: np.concatenate([np.asarray(p[m], np.float64)[:, 0] for p in per]) for m in methods}
    rows = []
    for fid in np.unique(ids):
        at = ids == fid
        scored = at & ~np.isnan(hits["model"])
        if not scored.any():
            continue
        row: dict[str, Any] = {
            "item": names.get(int(fid), f"F{int(fid):04d}") if names else f"F{int(fid):04d}",
            "fabric_id": int(fid),
            "queries": int(scored.sum()),
            "runs": len(np.unique(runs[scored])),
        }
        for m in methods:
            h = hits[m][at]
            row[f"{m}_top1"] = float(np.nanmean(h)) if np.any(~np.isnan(h)) else math.nan
        rows.append(row)
    rows.sort(key=lambda r: (r["model_top1"], r["item"]))
    return rows


def _summarise(
    results: list[dict],
    pairs: Sequence[Pair],
    n_boot: int,
    control: bool = True,
    names: Mapping[int, str] | None = None,
    why: Callable[[Pair], str] | None = None,
    label_values: Mapping[str, Sequence[float]] | None = None,
    noun: str = "fabric",
) -> dict[str, Any]:
    """The runs' scores pooled: per pair and method the mean over runs with a 95% interval
    resampling held-out items, each item's own top-1 (`_per_item`; ``names`` maps fabric ids
    to what the report calls them), the property probes (`_summarise_probes`; ``label_values``:
    each label's known values over the data) and the classes. A pair no query of which was
    scored in any run (none had an item of its own fabric to find) gets, instead of numbers,
    ``not_scored``: ``why(pair)`` (default `no_query_scored` of single presses). A method only
    some runs scored (label space where a fold had too few labelled training items) is left
    out, and ``missing_in`` names the runs without it. ``noun``: what the items are (fabric,
    object)."""
    summary: dict[str, Any] = {"runs": len(results), "pairs": {}, "properties": {}}
    summary["noun"] = noun
    summary["background_control"] = _control_status(results, control)
    seeds = {r.get("seed") for r in results}
    run_names = [
        f"fold {r.get('fold', i)}" + (f" seed {r['seed']}" if len(seeds) > 1 else "")
        for i, r in enumerate(results)
    ]
    for pair in pairs:
        entry: dict[str, Any] = {}
        groups = np.concatenate([r["pairs"][pair]["query_fabric"] for r in results])
        model = [np.asarray(r["pairs"][pair]["model"], np.float64).reshape(-1) for r in results]
        if all(np.isnan(v).all() for v in model):
            entry["not_scored"] = why(pair) if why else no_query_scored(pair, 1, fabrics="held-out")
        for method in _METHODS:
            if "not_scored" in entry or not all(method in r["pairs"][pair] for r in results):
                continue
            per_run = [np.asarray(r["pairs"][pair][method], dtype=np.float64) for r in results]
            pooled = np.concatenate(per_run)
            low, high = bootstrap_ci(pooled, groups, n_boot=n_boot, seed=0)
            for j, k in enumerate(_KS):
                runs = [_scored_mean(v[:, j]) for v in per_run]
                spread = mean_and_spread(runs)
                entry[f"{method}_top{k}"] = {
                    "mean": spread["mean"],
                    "std_over_runs": spread["std"],
                    "ci95": [float(low[j]), float(high[j])],
                    "per_run": runs,
                }
        for j, k in enumerate(_KS):
            entry[f"chance_top{k}"] = float(
                np.mean([r["pairs"][pair]["chance"][j] for r in results])
            )
        missing = {
            method: [
                n for n, r in zip(run_names, results, strict=True) if method not in r["pairs"][pair]
            ]
            for method in _METHODS
            if any(method in r["pairs"][pair] for r in results)
        }
        missing = {k: v for k, v in missing.items() if v}
        if missing and "not_scored" not in entry:
            entry["missing_in"] = missing
        entry["per_item"] = _per_item(results, pair, names)
        summary["pairs"][pair] = entry
    summary["properties"] = _summarise_probes(results, label_values, noun)
    summary["classes"] = _summarise_classes(results, n_boot)
    return summary


MIN_SPEARMAN = 3
"""Held-out items below which a run's Spearman is left out: over two it is +1 or -1 whatever
the probe predicts."""


def _summarise_probes(
    results: list[dict], label_values: Mapping[str, Sequence[float]] | None, noun: str
) -> dict[str, Any]:
    """The property probes over runs: per modality, method (model, raw pixels, room) and label,
    R² and Spearman's mean and std over the runs that could score them, how many did
    (``runs``, ``spearman_runs``, of ``runs_total``) and on how many labelled held-out items in
    all (``held_out``); where no run could, ``not_scored`` (or ``spearman_not_scored``) says why
    (`_probe_reason`). A run's Spearman over fewer than `MIN_SPEARMAN` items is left out."""
    out: dict[str, Any] = {}
    for m, per in results[0]["properties"].items():  # none when no run had training fabrics
        out[m] = {}
        for method in per:
            if not all(method in r["properties"].get(m, {}) for r in results):
                continue
            table: dict[str, dict[str, Any]] = {}
            for label in per[method]:
                cells = [r["properties"][m][method][label] for r in results]
                n_test = np.array([_num(c.get("n_test")) for c in cells])
                r2 = np.array([_num(c["r2"]) for c in cells])
                few = n_test < MIN_SPEARMAN  # NaN (unknown) compares False: kept
                sp = np.array(
                    [
                        math.nan if f else _num(c["spearman"])
                        for c, f in zip(cells, few, strict=True)
                    ]
                )
                row: dict[str, Any] = {}
                for score, vals in (("r2", r2), ("spearman", sp)):
                    spread = mean_and_spread(vals)
                    row[score] = spread["mean"]
                    row[f"{score}_std"] = spread["std"]
                scored = ~np.isnan(r2)
                row["runs"] = int(scored.sum())
                row["spearman_runs"] = int((~np.isnan(sp)).sum())
                row["runs_total"] = len(results)
                row["held_out"] = int(np.nansum(n_test[scored])) if scored.any() else 0
                if not scored.any():
                    row["not_scored"] = _probe_reason(label, cells, label_values, noun)
                elif not row["spearman_runs"]:
                    row["spearman_not_scored"] = (
                        f"at most {MIN_SPEARMAN - 1} labelled held-out {noun}s a fold: "
                        "their Spearman is ±1 whatever the probe predicts"
                        if few[scored].all()
                        else "the probe predicted one value"
                    )
                table[label] = row
            out[m][method] = table
    return out


def _num(x: Any) -> float:
    """A score as a float: NaN for None (a NaN that went through result.json) or missing."""
    return math.nan if x is None else float(x)


def _probe_reason(
    label: str,
    cells: Sequence[Mapping[str, Any]],
    label_values: Mapping[str, Sequence[float]] | None,
    noun: str,
) -> str:
    """Why no run's probe scored ``label``: ``cells``, each run's `property_probe` scores of
    it; ``label_values``: the label's known values over the data (None: not known here)."""
    known = label_values.get(label) if label_values is not None else None
    if known is not None and not known:
        return f"no {noun} labelled"
    if known is not None and len(set(known)) == 1:
        return f"every value {known[0]:g}"
    n_test = [_num(c.get("n_test")) for c in cells]
    n_train = [_num(c.get("n_train")) for c in cells]
    most = max((n for n in n_test if not math.isnan(n)), default=math.nan)
    if most == 0:
        return f"no labelled held-out {noun} in any fold"
    if most == 1:
        return f"at most 1 labelled held-out {noun} a fold"
    if max((n for n in n_train if not math.isnan(n)), default=2) < 2:
        return f"fewer than 2 labelled training {noun}s in every fold"
    return "the held-out values are alike within each fold"


CLASS_METHODS = ("model", "model_pooled", "probe", "raw_pixels", "majority")
"""How a held-out query's class is predicted in the class table (`_classes`)."""


CALIBRATION_BINS = 10
"""Equal-width bins of the expected calibration error of the class heads."""


def _calibration(
    runs: list[dict[str, Any]], folds: Sequence[int] | None = None
) -> dict[str, float]:
    """How far a class head's probability can be trusted on held-out objects, every run's
    held-out presses pooled: the mean probability of the predicted class (``confidence``)
    beside how often it is right (``accuracy``), their expected calibration error (``ece``),
    the temperature that fits them best (``temperature``: what a user would apply; NaN, with
    the edge in ``temperature_search_edge``, where the likelihood is best at the search's
    edge and no temperature was fitted: `lookfeel.metrics.classes.LogitTemperature`), and the
    same confidence and error under a temperature fitted on the runs of *other folds*
    (``*_cross_fitted``: an honest estimate of what the temperature buys, fitted on other
    objects than those it is applied to; NaN when every run is of one fold; applied even at
    the edge, ``cross_fitted_at_edge`` runs of ``cross_fitted_runs``). ``accuracy`` is over
    every held-out press of every run at once, where the classes table's is the mean over
    runs of each run's. ``folds``: each run's fold (default: every run its own)."""

    def known(r: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
        t = np.asarray(r["truth"], dtype=np.int64)
        z = np.asarray(r["logits"], dtype=np.float64).reshape(len(t), -1)
        return z[t >= 0], t[t >= 0]

    parts = [known(r) for r in runs]
    z = np.concatenate([p[0] for p in parts])
    t = np.concatenate([p[1] for p in parts])
    nan = float("nan")
    keys = ("confidence", "accuracy", "ece", "temperature", "temperature_search_edge")
    out = dict.fromkeys((*keys, "confidence_cross_fitted", "ece_cross_fitted"), nan)
    if not len(t):  # no held-out press of a known class
        return out
    hit = (z.argmax(1) == t).astype(np.float64)
    conf = softmax(z).max(1)
    fit = logit_temperature(z, t)
    out |= {
        "confidence": float(conf.mean()),
        "accuracy": float(hit.mean()),
        "ece": expected_calibration_error(conf, hit, CALIBRATION_BINS),
        "temperature": nan if fit.at_edge else fit.value,
        "temperature_search_edge": fit.value if fit.at_edge else nan,
    }
    fold_of = list(range(len(parts))) if folds is None else list(folds)
    if len(set(fold_of)) > 1:
        crossed = []
        edges = 0
        for i, (zi, _) in enumerate(parts):
            others = [p for j, p in enumerate(parts) if fold_of[j] != fold_of[i]]
            temp = logit_temperature(
                np.concatenate([p[0] for p in others]), np.concatenate([p[1] for p in others])
            )
            edges += temp.at_edge
            crossed.append(softmax(zi, temp.value).max(1) if len(zi) else np.zeros(0))
        c = np.concatenate(crossed)
        out["confidence_cross_fitted"] = float(c.mean())
        out["ece_cross_fitted"] = expected_calibration_error(c, hit, CALIBRATION_BINS)
        out["cross_fitted_at_edge"] = float(edges)
        out["cross_fitted_runs"] = float(len(parts))
    return out


def _summarise_classes(results: list[dict], n_boot: int) -> dict[str, Any]:
    """Accuracy (mean over runs, 95% interval resampling objects) and macro-F1 (mean and std
    over runs) of each class-prediction method, per modality and column."""
    out: dict[str, Any] = {}
    for m, per in results[0].get("classes", {}).items():
        out[m] = {}
        for col, first in per.items():
            entry: dict[str, Any] = {"classes": first["classes"]}
            runs = [r["classes"][m][col] for r in results]
            for method in CLASS_METHODS:
                pooled = method == "model_pooled"
                t_key, g_key = ("object_truth", "object") if pooled else ("truth", "query_fabric")
                truth = [np.asarray(r[t_key]) for r in runs]
                pred = [np.asarray(r[method]) for r in runs]
                hits = np.concatenate(
                    [
                        np.where(t >= 0, (t == p).astype(float), np.nan)
                        for t, p in zip(truth, pred, strict=True)
                    ]
                )
                groups = np.concatenate([np.asarray(r[g_key]) for r in runs])
                low, high = bootstrap_ci(hits, groups, n_boot=n_boot, seed=0)
                per_run = [accuracy(t, p) for t, p in zip(truth, pred, strict=True)]
                acc = mean_and_spread(per_run)
                f1 = mean_and_spread(
                    [
                        macro_f1(t, p, len(first["classes"]))
                        for t, p in zip(truth, pred, strict=True)
                    ]
                )
                entry[method] = {
                    "accuracy": acc["mean"],
                    "accuracy_std": acc["std"],
                    "per_run": per_run,
                    "ci95": [float(low), float(high)],
                    "macro_f1": f1["mean"],
                    "macro_f1_std": f1["std"],
                    "queries": int(np.sum(~np.isnan(hits))),
                }
            entry["chance"] = 1.0 / len(first["classes"])
            if all("logits" in r for r in runs):
                folds = [r.get("fold", i) for i, r in enumerate(results)]
                entry["calibration"] = _calibration(runs, folds)
            out[m][col] = entry
    return out


def _scored_mean(values: np.ndarray) -> float:
    """The mean over the queries that were scored (``np.nanmean``); NaN, without numpy's
    warning, when none was."""
    return float(np.nanmean(values)) if (~np.isnan(values)).any() else math.nan


def _fmt(x: dict[str, Any]) -> str:
    """``mean [low, high]``, with ``(k of n runs)`` where only k of the n runs scored it
    (``per_run`` NaN elsewhere); ``n/a`` where none did."""
    if x["mean"] is None or math.isnan(x["mean"]):
        return "n/a"
    lo, hi = x["ci95"]
    return f"{x['mean']:.3f} [{lo:.3f}, {hi:.3f}]" + _of_runs(x.get("per_run"))


def _of_runs(per_run: Sequence[float | None] | None) -> str:
    """`` (k of n runs)`` where only k of a number's n runs scored it, else nothing."""
    if not per_run:
        return ""
    k = sum(v is not None and not math.isnan(v) for v in per_run)
    return "" if k == len(per_run) else f" ({k} of {len(per_run)} runs)"


def _pm(scores: dict[str, Any], name: str) -> str:
    """``mean ± std`` over runs (just the mean for one run; ``n/a`` for none), with ``(k of
    n runs)`` where fewer runs than the row's scored it."""
    mean = scores[name]
    if mean is None or math.isnan(mean):
        return "n/a"
    std = scores[f"{name}_std"]
    text = f"{mean:.2f}" + ("" if std is None or math.isnan(std) else f" ± {std:.2f}")
    k, n = scores.get(f"{name}_runs" if name != "r2" else "runs"), scores.get("runs_total")
    return text + (f" ({k} of {n} runs)" if k is not None and n and k < n else "")


def _plural(noun: str) -> str:
    """``presses``, ``images``, ``objects``."""
    return noun + ("es" if noun.endswith(("s", "sh", "ch", "x")) else "s")


def _na_top3(summary: dict[str, Any]) -> list[str]:
    """The pairs whose top-3 says nothing: every fold held out 3 or fewer items to pick among
    (chance top-3 is 1), so every query's top-3 is right."""
    return [
        p
        for p, e in summary["pairs"].items()
        if e.get("chance_top3", 0.0) >= 1.0 - 1e-9 and "not_scored" not in e
    ]


def _pair_table(
    summary: dict[str, Any],
    intro: str,
    columns: tuple[tuple[str, str], ...],
    chance: bool = True,
    name: str = "",
) -> list[str]:
    """A table of every pair scored with ``columns[1]``'s key: one cell per (header, key)
    column (``-`` where a pair lacks it; a column no such pair has is left out; top-3 ``n/a``
    where it says nothing, `_na_top3`), then chance; nothing when no pair has it. Where some
    runs lacked that key's method (``missing_in``), a line says which, and that the table
    (``name``) leaves such pairs out."""
    key = columns[1][1]
    rows = [(p, e) for p, e in summary["pairs"].items() if key in e]
    method = key.rsplit("_top", 1)[0]
    lacking = [
        (p, e["missing_in"][method])
        for p, e in summary["pairs"].items()
        if method in e.get("missing_in", {})
    ]
    lines: list[str] = []
    if rows:
        columns = tuple(c for c in columns if any(c[1] in e for _, e in rows))
        headers = [h for h, _ in columns] + (["chance"] if chance else [])
        lines = ["", intro, "", f"| pair | {' | '.join(headers)} |"]
        lines.append("|---" * (len(headers) + 1) + "|")
        na3 = _na_top3(summary)
        for pair, e in rows:
            cells = [
                "-" if k not in e else "n/a" if pair in na3 and k.endswith("_top3") else _fmt(e[k])
                for _, k in columns
            ]
            if chance:
                cells.append(f"{e['chance_top1']:.3f}")
            lines.append(f"| {pair} | {' | '.join(cells)} |")
    if lacking and name:
        why = _MISSING_WHY.get(method, "").format(noun=summary.get("noun", "fabric"))
        said = "; ".join(f"{p.replace('_', ' ')}: {', '.join(runs)}" for p, runs in lacking)
        lines += [
            "",
            f"{name}: not shown for pairs some run could not score ({said}"
            + (f": {why}" if why else "")
            + "); a pair is shown only when every run scored it.",
        ]
    return lines


_MISSING_WHY = {
    "model_labels": (
        f"no label column had {MIN_FABRICS} or more labelled training {{noun}}s with differing "
        "values"
    ),
    "model_mapped": "no cross-modal map could be fitted on the training {noun}s",
}
"""Why a run has no scores of a method (`_pair_table`'s line); ``{noun}``: fabric, object."""


def _has(summary: dict[str, Any], key: str) -> bool:
    """Whether any pair of the summary has ``key``."""
    return any(key in e for e in summary["pairs"].values())


def _control_lines(summary: dict[str, Any]) -> list[str]:
    """The background control's table (model and raw pixels, as they are, swapped and, for
    registered depth, in another fabric's room)."""
    status = summary.get("background_control") or {}
    if status.get("skipped"):
        return ["", f"Background control: skipped ({status['skipped']})."]
    room = _has(summary, "model_room_top1")
    intro = (
        "Background control: the same queries with every depth image's background replaced "
        "by another fabric's (the cloth kept). A model that reads the cloth, not the room, "
        "scores the same."
    )
    if room:
        intro += (
            " Room control (registered depth): each depth image registered, as it was taken, "
            "against the room fitted on that other fabric's own image, nothing refitted: "
            "another session's registration of the same cloth (where the rooms differ by "
            "more than the margin, room becomes cloth or cloth is lost)."
        )
    columns = (
        ("model top-1", "model_top1"),
        ("model top-1, background swapped", "model_swapped_top1"),
        ("model top-1, in another fabric's room", "model_room_top1"),
        ("raw pixels top-1", "raw_pixels_top1"),
        ("raw pixels top-1, background swapped", "raw_pixels_swapped_top1"),
        ("raw pixels top-1, in another fabric's room", "raw_pixels_room_top1"),
    )
    return _pair_table(summary, intro, columns, chance=False, name="Background control")


def _label_space_lines(summary: dict[str, Any]) -> list[str]:
    """The table of matching in label space beside matching in the embedding."""
    columns = (
        ("model top-1", "model_top1"),
        ("label space top-1", "model_labels_top1"),
        ("label space top-1, background swapped", "model_labels_swapped_top1"),
        ("label space top-1, in another fabric's room", "model_labels_room_top1"),
        ("model top-3", "model_top3"),
        ("label space top-3", "model_labels_top3"),
    )
    intro = (
        "Matching in label space (`lookfeel.metrics.label_space`): the same queries, each "
        "modality's embeddings mapped onto the labels' normal scores by a ridge fitted on the "
        f"run's training {_plural(summary.get('noun', 'fabric'))} only, and a query matched to "
        "the gallery item whose predicted labels are nearest"
    )
    if _has(summary, "model_labels_swapped_top1"):  # the background control ran
        room = _has(summary, "model_labels_room_top1")
        also = " (and registered in another fabric's room)" if room else ""
        intro += (
            f"; for pairs with depth also with every depth image's background swapped{also}, "
            "as in the background control below"
        )
    return _pair_table(summary, intro + ".", columns, name="Matching in label space")


def _mapped_lines(summary: dict[str, Any]) -> list[str]:
    """The table of matching through the cross-modal maps beside the other readings."""
    columns = (
        ("model top-1", "model_top1"),
        ("cross-modal map top-1", "model_mapped_top1"),
        ("cross-modal map top-1, background swapped", "model_mapped_swapped_top1"),
        ("cross-modal map top-1, in another fabric's room", "model_mapped_room_top1"),
        ("label space top-1", "model_labels_top1"),
        ("cross-modal map top-3", "model_mapped_top3"),
    )
    nouns = _plural(summary.get("noun", "fabric"))
    return _pair_table(
        summary,
        "Matching through a cross-modal map (`lookfeel.metrics.cross_map`; no labels used): "
        "the same queries, the query modality's embeddings carried into the gallery "
        f"modality's and back by linear maps fitted on the run's training {nouns} only, a "
        "query matched to the gallery item nearest by both routes, each gallery item's "
        f"distance lowered by its crowding among the training {nouns} (the hub correction).",
        columns,
        name="Matching through a cross-modal map",
    )


def _untouched_lines(summary: dict[str, Any]) -> list[str]:
    """The untouched control's table (model and raw pixels, pressed and with no contact)."""
    return _pair_table(
        summary,
        "Untouched control: the same queries with every press replaced by a moment of its video "
        "with no contact, preprocessed alike (`lookfeel.data.touch_control`). A model that reads "
        "the contact, not the sensor's own light or the session, falls to chance.",
        (
            ("model top-1", "model_top1"),
            ("model top-1, untouched", "model_untouched_top1"),
            ("raw pixels top-1", "raw_pixels_top1"),
            ("raw pixels top-1, untouched", "raw_pixels_untouched_top1"),
        ),
        name="Untouched control",
    )


WORST_ITEMS = 8
"""Held-out items per pair that the report lists, worst first (`cv.json` keeps every one)."""


def _per_item_lines(summary: dict[str, Any]) -> list[str]:
    """The held-out items each pair matches worst, beside raw pixels (`_per_item`)."""
    rows = [(p, e["per_item"]) for p, e in summary["pairs"].items() if e.get("per_item")]
    if not rows:
        return []
    swapped = any("model_swapped_top1" in r for _, items in rows for r in items)
    lines = [
        "",
        f"Held-out items matched worst: each item's top-1 over every query it made, in every "
        f"run (the {WORST_ITEMS} worst per pair; `cv.json` lists all under `per_item`), beside raw "
        "pixels: where they score higher, the pixels hold something of the item that the model "
        "does not use.",
        "",
        "| pair | item | queries | model top-1 | raw pixels top-1 |"
        + (" background swapped |" if swapped else ""),
        "|---|---|---|---|---|" + ("---|" if swapped else ""),
    ]

    def cell(r: dict[str, Any], key: str) -> str:
        v = r.get(key)
        return "-" if v is None or math.isnan(v) else f"{v:.3f}"

    for pair, items in rows:
        perfect = sum(r["model_top1"] >= 1.0 for r in items)
        for r in items[:WORST_ITEMS]:
            cells = [str(r["queries"]), cell(r, "model_top1"), cell(r, "raw_pixels_top1")]
            if swapped:
                cells.append(cell(r, "model_swapped_top1"))
            lines.append(f"| {pair} | {r['item']} | {' | '.join(cells)} |")
        lines.append(
            f"| {pair} | ({perfect} of {len(items)} items always right) | | | |"
            + (" |" if swapped else "")
        )
    return lines


def _coverage_text(summary: dict[str, Any]) -> str:
    """What cv.md's first line says the folds held out: every fabric (object) once, or how
    many of how many, which folds were not run, and which were never used and why
    (``coverage``, `_fold_plan`); without it (a summary made elsewhere), the fold size."""
    noun = summary.get("noun", "fabric")
    cov = summary.get("coverage")
    if cov is None:
        size = summary["fold_size"]
        return f"every {noun} held out once" if size is None else f"{size} {noun}s per fold"
    sizes = cov["fold_sizes"]
    lo, hi = min(sizes), max(sizes)
    per = f"{lo} per fold" if lo == hi else f"{lo} to {hi} per fold"
    held, total = len(cov["held_out"]), cov["items"]
    if held == total:
        text = f"every {noun} held out once, {per}"
    else:
        text = f"{held} of the {_count(total, noun)} held out, each once, {per}"
    not_run = cov["not_run"]
    if not_run["folds"]:
        folds = ", ".join(map(str, not_run["folds"]))
        text += (
            f"; fold{'s' if len(not_run['folds']) > 1 else ''} {folds} of "
            f"{cov['folds_total']} not run (--only-folds): "
            f"{_count(len(not_run['items']), noun)} not held out"
        )
    if cov["train_only"]:
        text += (
            f"; {_count(len(cov['train_only']), noun)} in no fold, only trained on "
            f"({cov['folds_total']} folds of train.fold_size={summary['fold_size']})"
        )
    never = cov["never_used"]
    if never["items"]:
        shown = ", ".join(never["items"][:10]) + (", ..." if len(never["items"]) > 10 else "")
        text += (
            f"; {_count(len(never['items']), noun)} never used, neither trained on nor held "
            f"out ({shown}): {never['why']}"
        )
    return text


def format_cv_summary(summary: dict[str, Any]) -> str:
    """The cross-validation summary as Markdown: pick 1 of 10 per pair, then properties."""
    noun = summary.get("noun", "fabric")
    nouns = _plural(noun)
    fewer = any(e.get("chance_top1", 0.0) > 0.1 + 1e-9 for e in summary["pairs"].values())
    runs = summary["runs"]
    touch_pair = summary["pairs"].get("touch_to_touch", {})
    same_touch = ""
    if "touch_to_touch" in summary["pairs"]:
        same_touch = "; touch to touch picks among the single presses outside the query" + (
            " (none is left here: see below)" if "not_scored" in touch_pair else ""
        )
    lines = [
        f"{noun.capitalize()}-disjoint cross-validation: {runs} run{'' if runs == 1 else 's'} "
        f"(folds {summary['folds']}, seeds {summary['seeds']}; {_coverage_text(summary)}). "
        f"Pick 1 of 10 among each fold's held-out {nouns}"
        + (" (1 of all of them where a fold holds fewer than 10: see chance)" if fewer else "")
        + f"; mean over runs [95% interval, resampling held-out {nouns}]."
        + (
            f" Touch pools {summary['presses']} presses of one {noun}, as a query and as the "
            f"candidates of another sense's queries (the Multi-input Net's protocol){same_touch}."
            if summary.get("presses", 1) > 1
            else ""
        ),
        "",
        "| pair | model top-1 | model top-3 | raw pixels top-1 | raw pixels top-3 | chance |",
        "|---|---|---|---|---|---|",
    ]
    na3 = _na_top3(summary)
    for pair, e in summary["pairs"].items():
        if "not_scored" in e:
            lines.append(f"| {pair} | not scored | - | - | - | n/a |")
            continue
        top3 = {
            k: "n/a" if pair in na3 else _fmt(e[k])
            for k in e
            if k.endswith("_top3") and k != "chance_top3"
        }
        raw = (
            (_fmt(e["raw_pixels_top1"]), top3["raw_pixels_top3"])
            if "raw_pixels_top1" in e
            else ("-", "-")
        )
        lines.append(
            f"| {pair} | {_fmt(e['model_top1'])} | {top3['model_top3']} | {raw[0]} | {raw[1]} "
            f"| {e['chance_top1']:.3f} / {e['chance_top3']:.3f} |"
        )
    if na3:
        lines += [
            "",
            f"Top-3 is n/a for {', '.join(p.replace('_', ' ') for p in na3)}: no fold held out "
            f"more than 3 {nouns} to pick among, so every query's top-3 is right (chance "
            "1.000); read top-1.",
        ]
    unscored = [(p, e["not_scored"]) for p, e in summary["pairs"].items() if "not_scored" in e]
    if unscored:
        lines += [""] + [f"Not scored: {pair.replace('_', ' ')}: {why}." for pair, why in unscored]
    lines += _label_space_lines(summary)
    lines += _mapped_lines(summary)
    lines += _control_lines(summary)
    lines += _untouched_lines(summary)
    lines += _per_item_lines(summary)
    for m, per in summary["properties"].items():
        if not per.get("model"):
            continue
        lines += _probe_lines(m, per, runs, nouns)
    for m, per in summary.get("classes", {}).items():
        unit = "press" if m == Modality.TOUCH.value else "image"
        lines += [
            "",
            f"Classes from {m}: accuracy [95% interval, resampling held-out {nouns}] / macro-F1, "
            f"each the mean over runs of the run's accuracy over its held-out {_plural(unit)} "
            f"(n/a where no held-out {noun} is labelled). model: the class head on one {unit}; "
            f"pooled: every {unit} of one {noun} at once; probe: 5-NN on the training embeddings; "
            "raw pixels: 5-NN on training pixels; majority: the training majority class.",
            "",
            "| label | model | pooled | probe | raw pixels | majority | chance |",
            "|---|---|---|---|---|---|---|",
        ]
        for col, e in per.items():
            cells = [
                "n/a"
                if e[k]["accuracy"] is None or math.isnan(e[k]["accuracy"])
                else f"{_fmt({'mean': e[k]['accuracy'], 'ci95': e[k]['ci95']})} / "
                f"{e[k]['macro_f1']:.2f}{_of_runs(e[k].get('per_run'))}"
                for k in CLASS_METHODS
            ]
            lines.append(f"| {col} | {' | '.join(cells)} | {e['chance']:.2f} |")
        lines += _calibration_lines(m, per)
    return "\n".join(lines) + "\n"


def _probe_lines(modality: str, per: dict[str, Any], runs: int, nouns: str) -> list[str]:
    """The property probes' table of one modality (`_summarise_probes`): ``n/a: why`` where no
    run could score a label, and on how many runs and held-out items each row rests."""
    counted = any("runs" in row for row in per["model"].values())
    lines = [
        "",
        f"Physical properties from {modality} (ridge probe on {nouns[:-1]}-mean embeddings, "
        f"fitted on each fold's training {nouns}"
        + (
            f"; mean ± std over the runs that could score each label, "
            f"with a fold's Spearman over fewer than {MIN_SPEARMAN} {nouns} left out):"
            if runs > 1
            else "):"
        ),
        "",
        "| label | model R² | model Spearman | raw pixels R² | raw pixels Spearman |"
        + (" room alone R² | room alone Spearman |" if "room" in per else "")
        + (f" runs (held-out {nouns}) |" if counted else ""),
        "|---|---|---|---|---|"
        + ("---|---|" if "room" in per else "")
        + ("---|" if counted else ""),
    ]
    methods = [k for k in ("model", "raw_pixels", "room") if k in per]
    for label, row in per["model"].items():
        cells = [_pm(per[k][label], score) for k in methods for score in ("r2", "spearman")]
        why = row.get("not_scored")
        if why:
            cells[0] = f"n/a: {why}"
        elif row.get("spearman_not_scored"):
            cells[1] = f"n/a: {row['spearman_not_scored']}"
        if counted:
            cells.append(f"{row['runs']} of {row['runs_total']} ({row['held_out']})")
        lines.append(f"| {label} | {' | '.join(cells)} |")
    if "room" in per:
        lines += [
            "",
            "Room alone: the same probe on each raw depth image's background pixels (no "
            "cloth; `lookfeel data leakage`'s rule). Where it scores, the background "
            "follows the labels (as it does when each fabric was captured in its own "
            "session and the sessions follow the labels): read the model's probe against "
            "it, not against zero.",
        ]
    return lines


def _calibration_lines(modality: str, per: dict[str, Any]) -> list[str]:
    """The class heads' calibration table (`_calibration`), when the runs kept their logits;
    a temperature at the search's edge is marked not fitted and left out of the line that
    says what to put in ``model.class_temperature``."""
    cols = [(col, e["calibration"]) for col, e in per.items() if "calibration" in e]
    if not cols:
        return []
    unit = "press" if modality == Modality.TOUCH.value else "image"
    units = _plural(unit)
    lines = [
        "",
        f"How far the class heads' probabilities from {modality} can be trusted (one {unit}, "
        f"every run's held-out {units} at once: right is over them all, where the classes "
        "table averages each run's accuracy): the mean probability of the predicted class "
        f"beside how often it is right, and their expected calibration error ({CALIBRATION_BINS} "
        f"bins); then a temperature fitted on the other folds' held-out {units} applied to "
        "each run's (- where there are none), and the temperature fitted on them all "
        "(`model.class_temperature` applies one in `predict`).",
        "",
        "| label | probability | right | error | probability, other folds' temperature "
        "| error, other folds' temperature | temperature |",
        "|---|---|---|---|---|---|---|",
    ]
    fitted, edge = [], []
    for col, c in cols:
        cells = [
            c["confidence"], c["accuracy"], c["ece"], c["confidence_cross_fitted"],
            c["ece_cross_fitted"],
        ]  # fmt: skip
        text = ["-" if v is None or math.isnan(v) else f"{v:.3f}" for v in cells]
        at_edge, crossed = c.get("cross_fitted_at_edge") or 0, c.get("cross_fitted_runs")
        if at_edge and text[3] != "-":
            text[3] += f" (at the search edge in {int(at_edge)} of {int(crossed or 0)} runs)"
        t, t_edge = c["temperature"], c.get("temperature_search_edge")
        if t is not None and not math.isnan(t):
            temp = f"{t:.2f}"
            fitted.append(f"{col}: {t:.2f}")
        elif t_edge is not None and not math.isnan(t_edge):
            temp = f"n/a: at the search edge ({t_edge:.3g}): not fitted"
            edge.append(col)
        else:
            temp = "-"
        lines.append(f"| {col} | {' | '.join(text)} | {temp} |")
    if edge:
        lines += [
            "",
            f"Not fitted: {', '.join(edge)}: the likelihood is best at the edge of the "
            f"temperature search (too few or too certain classes: a head no better than a "
            f"guess on these {units} wants an infinite temperature, one never wrong a zero one); "
            "such a value calibrates nothing: leave it out of `model.class_temperature`.",
        ]
    if fitted:
        lines += [
            "",
            f"`model.class_temperature: {{{', '.join(fitted)}}}` applies the fitted "
            "temperatures in `predict`.",
        ]
    return lines


def cross_validate(
    config: RunConfig,
    data: str | Path,
    out: str | Path,
    *,
    seeds: Sequence[int] = (0,),
    folds: Sequence[int] | None = None,
    tta: bool = False,
    n_boot: int = 1000,
    background_control: bool = True,
    presses: int | None = None,
    log: Callable[[str], None] = print,
) -> dict[str, Any]:
    """Train and score ``config`` on every requested fold and seed; write ``cv.json`` and ``cv.md``.

    Args:
        config: the run config; its ``train.split``, ``train.fold`` and ``train.seed`` are set
            per run, ``train.folds``, ``train.fold_size`` and ``train.split_seed`` define the
            folds.
        data: the dataset folder.
        out: the cross-validation folder (created; reruns skip finished runs, and refuse a
            folder whose runs were made on another dataset: `Catalog.fingerprint`).
        seeds: training seeds.
        folds: which folds to run (default: all ``train.folds``).
        tta: embed each image and its left-right mirror and average the two (test-time pooling).
        n_boot: bootstrap resamples for the intervals.
        background_control: for a config with depth pairs, also score every run with the
            depth images' backgrounds swapped (module doc); about 0.2 s per held-out depth
            image once per fold (registration), shared by the seeds.
        presses: presses of one fabric pooled into a touch query (the Multi-input Net's
            protocol); default the config's ``data.presses``.
        log: where progress lines go.

    Returns:
        The summary that ``cv.json`` holds.

    Raises:
        SplitError: folds that hold out fewer than 2 fabrics (objects), or more than there are
            (`_fold_plan`), before anything is written or trained.
        ConfigError: a fold out of range, no seed, or more presses than a fabric has.
    """
    out = Path(out)
    t = config.train
    fold_list = list(range(t.folds)) if folds is None else list(folds)
    for f in fold_list:
        if not 0 <= f < t.folds:
            raise ConfigError(f"fold {f}: the config has train.folds={t.folds} (0..{t.folds - 1})")
    if not seeds:
        raise ConfigError("seeds: at least one training seed is needed")
    presses = config.data.presses if presses is None else presses
    if presses < 1:
        raise ConfigError(f"presses: a touch query pools at least 1 press, got {presses}")
    pairs = _pairs(config)
    loader = ImageLoader(config.data)  # runs differ only in train keys: one decode for all
    catalog = drop_unpressed(scan(data, require=config.train.modalities, strict=True), loader)
    # The folds and the touch queries checked before anything is printed, written or trained.
    coverage = _fold_plan(catalog, config, fold_list)
    noun = coverage["noun"]
    select_split(catalog, _run_config(config, fold_list[0], seeds[0]))
    kinds = [k.value for k in config.data.touch_kinds]
    if presses > 1 and Modality.TOUCH in _modalities(pairs):
        most = catalog.most_presses(config.data.touch_kinds)
        if most < presses:
            raise ConfigError(
                f"presses: no held-out fabric has {presses} touch presses ({', '.join(kinds)}) "
                f"to pool into a query (no fabric of {catalog.root} has more than {most}); use "
                f"--presses {max(most, 1)} or fewer"
            )
    out.mkdir(parents=True, exist_ok=True)
    uses_depth = any(Modality.DEPTH in (p.query, p.gallery) for p in pairs)
    control = (
        BackgroundControl(config.data, CONTROL_SEED) if background_control and uses_depth else None
    )
    untouched = UntouchedControl(config.data)  # shared by the seeds of a fold
    room = RoomProbe(catalog, config.data.workers) if control is not None else None
    fingerprint = catalog.fingerprint()
    data_id = {"root": str(catalog.root), "fingerprint": fingerprint}
    results = []
    for seed in seeds:
        for fold in fold_list:
            run_dir = out / f"seed{seed}-fold{fold}"
            cfg = _run_config(config, fold, seed)
            result_path = run_dir / RESULT
            key = {"config": _result_config(cfg), "tta": tta, "pairs": pairs}
            # How the maps score (session 22 added the hub correction): a result scored
            # otherwise is scored again from its checkpoint, never silently kept.
            key["cross_map_hubs"] = HUB_NEIGHBOURS
            key = finite_or_null(key)  # as result.json holds it
            if presses > 1:
                key["presses"] = presses
                key["pooled_gallery"] = True  # session 23: touch candidates pooled too
            if cfg.model.class_heads:
                key["class_logits"] = True  # session 47: the heads' calibration needs them
            if control is not None:
                key["background_control"] = CONTROL_SEED
                if control.has_room_control:
                    key["room_control"] = True
            saved = json.loads(result_path.read_text()) if result_path.exists() else None
            if saved is not None and saved.get("data", data_id)["fingerprint"] != fingerprint:
                raise ConfigError(
                    f"{run_dir} holds a run on another dataset ({saved['data']['root']}), or on "
                    f"{catalog.root} before its files or labels changed; use another --out"
                )
            if saved is not None and saved.get("key") == key:
                log(f"seed {seed} fold {fold}: done before, kept ({result_path})")
                results.append(_with_room(saved, run_dir, room))
                continue
            last = run_dir / "checkpoints" / "last.pt"
            done = load_model(last) if last.exists() else None
            if done is not None and done.step >= cfg.train.steps:
                if not _same_run(done.config, cfg):
                    raise ConfigError(
                        f"{run_dir} holds a finished run of another config; use another --out"
                    )
                # Trained before, scored differently (e.g. --tta): score again, keep the time.
                log(f"seed {seed} fold {fold}: trained before, scoring again")
                kept = saved.get("train_seconds") if saved else None
                seconds = math.nan if kept is None else float(kept)
            else:
                started = time.perf_counter()
                started_before = run_started(run_dir)
                verb = "resuming" if started_before else "training in"
                log(f"seed {seed} fold {fold}: {verb} {run_dir}")
                train(cfg, data, run_dir, resume=started_before)
                seconds = time.perf_counter() - started
            res = _evaluate_run(run_dir, catalog, pairs, tta, loader, control, untouched, presses)
            res |= {"key": key, "seed": seed, "fold": fold, "train_seconds": seconds}
            res["data"] = data_id
            res = _with_room(res, run_dir, room)
            _write_json(result_path, res)
            first = res["pairs"][pairs[0]]
            top1 = _scored_mean(np.asarray(first["model"], np.float64)[:, 0])
            extra = "".join(
                f", {name} {_scored_mean(np.asarray(first[method], np.float64)[:, 0]):.3f}"
                for method, name in (
                    ("model_labels", "label space"),
                    ("model_mapped", "cross-modal map"),
                    ("model_swapped", "background swapped"),
                    ("model_room", "in another's room"),
                )
                if method in first
            )
            took = "" if math.isnan(seconds) else f" (trained in {seconds:.0f} s)"
            if math.isnan(top1):  # no query had its own fabric to find: the report says why
                log(f"seed {seed} fold {fold}: {pairs[0]} not scored{took}")
            else:
                log(f"seed {seed} fold {fold}: {pairs[0]} top-1 {top1:.3f}{extra}{took}")
            results.append(res)
    names = {f.id: f.display_name for f in catalog.fabrics}

    def why(pair: Pair) -> str:
        return no_query_scored(pair, presses, fabrics="held-out", kinds=kinds, option="--presses ")

    values = catalog.label_matrix(catalog.label_columns)
    used = [v for i, v in values.items() if i not in set(coverage["never_used"]["ids"])]
    label_values = {
        col: [v[j] for v in used if not math.isnan(v[j])]
        for j, col in enumerate(catalog.label_columns)
    }
    summary = _summarise(
        results, pairs, n_boot, control is not None, names, why, label_values, noun
    ) | {
        "folds": fold_list,
        "seeds": list(seeds),
        "fold_size": t.fold_size,
        "tta": tta,
        "presses": presses,
        "train_seconds": mean_and_spread([r["train_seconds"] for r in results]),
        "config": to_dict(config),
        "coverage": coverage,
    }
    _write_json(out / SUMMARY, summary, indent=1)
    atomic_write_text(out / REPORT, format_cv_summary(summary))
    return summary
