"""Scoring one run: pick 1 of 10 of the model, of raw pixels and of each control on the held-out
items (single or pooled touch queries, in label space, through cross-modal maps), the property
probes (`RoomProbe`: the room alone) and the class heads; `score_checkpoint` scores a checkpoint
on another dataset the same way. What each score means: the package docstring
(`lookfeel.crossval`).
"""

from __future__ import annotations

import json
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from lookfeel.checkpoint import LoadedModel, load_model
from lookfeel.config import RunConfig
from lookfeel.config._core import ConfigError
from lookfeel.crossval.summary import CONTROL_SEED, _check_n_boot, _summarise
from lookfeel.data import Catalog, ImageLoader, Item, scan
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
    score_distances,
    score_pairs,
)
from lookfeel.metrics.classes import knn_classes, majority_class
from lookfeel.metrics.cross_map import CrossMap, fit_cross_maps
from lookfeel.metrics.label_space import LabelSpace, fit_label_spaces
from lookfeel.metrics.properties import probe_columns
from lookfeel.modality import Modality, Pair
from lookfeel.train.validate import default_pairs

__all__ = ["RoomProbe", "score_checkpoint"]


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
) -> dict[str, dict[str, Any]]:
    """The ridge probe of every label column on fabric-mean rows (`probe_columns`): per label
    its scores on the held-out fabrics (`property_probe`'s) and ``held_out``, what the summary
    pools over a run's folds: each held-out fabric's id (``fabric``), label (``truth``) and
    prediction (``pred``), and the training fabrics' mean label (``train_mean``, what a probe
    that knows nothing predicts). The lists are empty where the probe was not fitted."""
    if not catalog.label_columns:
        return {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        columns = probe_columns(
            train_x,
            _labels(catalog, train_f),
            test_x,
            _labels(catalog, test_f),
            "ridge",
            names=list(catalog.label_columns),
            train_fabric=train_f,
            test_fabric=test_f,
        )
    out: dict[str, dict[str, Any]] = {}
    for name, c in columns.items():
        rows = range(len(c.rows) if c.fitted else 0)  # a probe not fitted predicted none
        held_out = {
            "fabric": [int(c.rows[i]) for i in rows],
            "truth": [float(c.truth[i]) for i in rows],
            "pred": [float(c.pred[i]) for i in rows],
            "train_mean": c.train_mean,
        }
        out[name] = c.scores() | {"held_out": held_out}
    return out


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
    ) -> dict[str, dict[str, Any]] | None:
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
    queries pooling ``presses`` presses when above 1: the package doc), and
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
        if m.pooled and pool is not None:
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
            if m.pooled and pool is not None:
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
                x = x.unsqueeze(0) if m.pooled else x  # a pooled modality's presses: one input
                z = lm.model({m.value: x}, heads=True)[f"{m.value}/{CLASSES}"]
                pooled.append(z[0] if m.pooled else z.amax(0))
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
        n_boot: bootstrap resamples for the intervals (0: none, every ``ci95`` NaN).
        background_control: for depth pairs, also score with backgrounds swapped.
        presses: presses pooled into a touch query; default the run's ``data.presses``.

    Returns:
        ``{"pairs": {pair: {"model_top1": {"mean", "ci95", ...}, "raw_pixels_top1": ...,
        "model_swapped_top1": ..., "chance_top1": ...}}, "checkpoint", "data_root", "step",
        "background_control"}``.
    """
    _check_n_boot(n_boot)
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
        "data_root": str(data),
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
    split = json.loads((run_dir / "split.json").read_text(encoding="utf-8"))
    probe = room(split["train"], split["val"])
    if probe is not None:
        depth["room"] = probe
    return result
