"""What stands beside the model's scores: raw pixels, and the controls that expose a shortcut.

`lookfeel evaluate` scores the same queries, by the same exact pick k of n with intervals over
the test fabrics (`exact_protocol`), three more ways, as `lookfeel cv` does (`lookfeel.crossval`):

- **raw pixels** (`raw_pixel_baseline`): every same-modality pair matched on the preprocessed
  images themselves (the network's input, flattened), a pooled touch query the mean of its
  presses' pixels (as ``cv``'s ``raw_pixels``). Keys ``{pair}_raw_pixels_top{k}`` (+
  ``_ci_low``/``_ci_high``). Across modalities there is none: no pixel of a drape corresponds
  to one of a press.
- the **background control** (`background_control`, a model with a depth branch): each test
  depth image's background replaced by another fabric's, the cloth kept
  (`lookfeel.data.background_swap.BackgroundControl`); every pair with depth scored again
  (``{pair}_top{k}_swapped``), raw pixels of depth too
  (``depth_to_depth_raw_pixels_top{k}_swapped``), and for registered depth the room control
  (``..._room``). Touch queries pool the same presses as the main scores: the depth images
  change, nothing else.
- the **untouched control** (`untouched_control`, touch recorded as press videos): every press
  replaced by a moment of its own video without contact (`lookfeel.data.touch_control`); every
  pair with touch scored again (``{pair}_top{k}_untouched``), raw pixels of touch too
  (``touch_to_touch_raw_pixels_top{k}_untouched``). The sensor's light and drift identify a
  recording session; a model that reads the contact falls to chance there.

Pairs scored through a cross-modal map are scored through the same map under each control
(``{pair}_top{k}_mapped_swapped``, ``..._mapped_untouched``); in label space (``eval.space:
labels``) the controls' embeddings are mapped onto the labels as the main ones were.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from lookfeel.config import DataConfig
from lookfeel.config.model import EMBED_BATCH
from lookfeel.data import ImageLoader
from lookfeel.data.background_swap import BackgroundControl
from lookfeel.data.touch_control import UntouchedControl
from lookfeel.embedding import EmbeddedItems, embed_items, press_pooler, raw_pixels
from lookfeel.errors import LookfeelError
from lookfeel.metrics import QuerySet, score_distances, score_pairs
from lookfeel.metrics.label_space import LabelSpace
from lookfeel.modality import Modality, Pair
from lookfeel.models import Embedder

from .core import exact_protocol, keep_pick, max_pool_presses
from .result import EvalResult

__all__ = ["background_control", "raw_pixel_baseline", "untouched_control"]

_TOUCH = Modality.TOUCH


def _mean_pooled(q: QuerySet, pixels: NDArray[np.generic]) -> QuerySet:
    """The same groups as ``q`` over raw pixels: each group's mean (``cv``'s pooling of them)."""
    return QuerySet(np.asarray(pixels, np.float64)[q.members].mean(axis=1), q.fabric, q.members)


def _pixel_scores(
    result: EvalResult,
    pixels: Mapping[Modality, NDArray[np.generic]],
    pairs: Sequence[Pair],
    name: str,
) -> dict[str, float]:
    """Exact pick of each same-modality pair in ``pairs`` on ``pixels``, keys
    ``{pair}_raw_pixels_top{k}{name}``; touch queries pooled as the main scores pooled them."""
    cfg = result.config
    fab = {m: np.asarray(result.embedded[m].fabric_ids, dtype=np.int64) for m in pixels}
    queries = {
        m: _mean_pooled(q, pixels[m]) for m, q in result.pooled_queries.items() if m in pixels
    }
    wanted = [p for p in pairs if p.same and p.query in pixels]
    out: dict[str, float] = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # few fabrics: the main scores' notes say so already
        scores = score_pairs(pixels, fab, exact_protocol(cfg), wanted, queries=queries)
    for pair, score in scores.items():
        keep_pick(out, score.metrics, cfg.ks, f"{pair}_raw_pixels_top{{k}}{name}{{suffix}}")
    return out


def _scorable(result: EvalResult, pairs: Sequence[Pair]) -> list[Pair]:
    """``pairs`` less those none of whose queries could be scored (`EvalResult.not_scored`)."""
    return [p for p in pairs if p not in result.not_scored]


def raw_pixel_baseline(result: EvalResult, loader: ImageLoader) -> dict[str, float]:
    """Raw pixels of every same-modality pair the result scored (module doc).

    Args:
        result: the model's scores (its pairs, config and pooled touch queries).
        loader: reads the test items as the model's preprocessing does.

    Returns:
        ``{pair}_raw_pixels_top{k}`` with ``_ci_low``/``_ci_high``.
    """
    pairs = _scorable(result, [p for p in result.pairs if p.same])
    pixels = {p.query: raw_pixels(result.embedded[p.query].items, loader) for p in pairs}
    return _pixel_scores(result, pixels, pairs, "")


def _model_scores(
    result: EvalResult,
    vecs: Mapping[Modality, NDArray[np.float64]],
    queries: Mapping[Modality, QuerySet],
    pairs: Sequence[Pair],
    name: str,
) -> dict[str, float]:
    """Exact pick of ``pairs`` on the embeddings ``vecs`` (pooled touch as ``queries``, as
    queries and as another modality's candidates), and through each pair's cross-modal map;
    keys ``{pair}_top{k}{name}`` and ``{pair}_top{k}_mapped{name}``."""
    cfg = result.config
    protocol = exact_protocol(cfg)
    fab = {m: np.asarray(result.embedded[m].fabric_ids, dtype=np.int64) for m in vecs}
    out: dict[str, float] = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # few fabrics: the main scores' notes say so already
        scores = score_pairs(vecs, fab, protocol, pairs, queries=queries, galleries=queries)
        for pair, score in scores.items():
            keep_pick(out, score.metrics, cfg.ks, f"{pair}_top{{k}}{name}{{suffix}}")
        sets = {m: QuerySet.single(v, fab[m]) for m, v in vecs.items()} | dict(queries)
        for pair, cmap in result.cross_maps.items():
            if pair in pairs:
                q, g = sets[pair.query], sets[pair.gallery]
                dist = cmap.distances(q.emb, g.emb)
                scored = score_distances(dist, q.fabric, g.fabric, protocol)
                keep_pick(out, scored.metrics, cfg.ks, f"{pair}_top{{k}}_mapped{name}{{suffix}}")
    return out


def _in_space(
    vecs: Mapping[Modality, NDArray[np.generic]], spaces: Mapping[Modality, LabelSpace] | None
) -> dict[Modality, NDArray[np.float64]]:
    """The embeddings as the pairs were scored: mapped onto the labels in label space."""
    if spaces is None:
        return {m: np.asarray(v, dtype=np.float64) for m, v in vecs.items()}
    return {m: spaces[m].project(v) for m, v in vecs.items()}


def background_control(
    model: Embedder,
    data_config: DataConfig,
    embedded: Mapping[Modality, EmbeddedItems],
    result: EvalResult,
    batch_size: int = EMBED_BATCH,
    device: str = "cpu",
    spaces: Mapping[Modality, LabelSpace] | None = None,
) -> tuple[dict[str, float], list[str]]:
    """The background control (module doc): every pair with depth scored again with each test
    depth image's background swapped (and, for registered depth, in another fabric's room).

    Args:
        model: the model that embedded ``embedded``.
        data_config: its preprocessing.
        embedded: the test items' embeddings in the model's own space (not mapped onto labels).
        result: the model's scores; its pooled touch queries are the queries and candidates
            touch takes here too.
        spaces: in label space, the maps the pairs were scored through.

    Returns:
        (metrics, notes saying what was skipped and why).
    """
    cfg = result.config
    pairs = _scorable(result, [p for p in result.pairs if Modality.DEPTH in (p.query, p.gallery)])
    if not pairs:
        return {}, []
    items = list(embedded[Modality.DEPTH].items)
    control = BackgroundControl(data_config, cfg.seed)
    variants: dict[str, ImageLoader] = {}
    try:
        variants["_swapped"] = control.loader(items)
        if control.has_room_control:
            variants["_room"] = control.room_loader(items)
    except LookfeelError as e:
        return {}, [f"background control skipped: {e}"]
    vecs = {m: np.asarray(e.embeddings) for m, e in embedded.items()}
    out: dict[str, float] = {}
    for name, ld in variants.items():
        depth = embed_items(model, items, ld, batch_size, device)
        vecs_v = _in_space(vecs | {Modality.DEPTH: depth}, spaces)
        out |= _model_scores(result, vecs_v, result.pooled_queries, pairs, name)
        out |= _pixel_scores(result, {Modality.DEPTH: raw_pixels(items, ld)}, pairs, name)
    return out, []


def untouched_control(
    model: Embedder,
    data_config: DataConfig,
    embedded: Mapping[Modality, EmbeddedItems],
    result: EvalResult,
    pool_exact: bool,
    batch_size: int = EMBED_BATCH,
    device: str = "cpu",
    spaces: Mapping[Modality, LabelSpace] | None = None,
) -> tuple[dict[str, float], list[str]]:
    """The untouched control (module doc): every pair with touch scored again with each press
    replaced by a moment of its video without contact; nothing when touch is not press videos.

    Args:
        model, data_config, embedded, spaces: as `background_control`.
        result: the model's scores; a pooled touch query pools the same presses' untouched
            moments here.
        pool_exact: the model's multi-press embedding is the max of its per-press embeddings
            (`lookfeel.evaluate.pools_final_embedding`); else the model pools them itself.

    Returns:
        (metrics, notes saying what was skipped and why).
    """
    if _TOUCH not in embedded:
        return {}, []
    items = list(embedded[_TOUCH].items)
    pairs = _scorable(result, [p for p in result.pairs if _TOUCH in (p.query, p.gallery)])
    if not pairs or not UntouchedControl.applies(items):
        return {}, []
    try:
        still = UntouchedControl(data_config).loader(items)
    except LookfeelError as e:
        return {}, [f"untouched control skipped: {e}"]
    touch = embed_items(model, items, still, batch_size, device)
    vecs = {m: np.asarray(e.embeddings) for m, e in embedded.items()} | {_TOUCH: touch}
    pixels = {_TOUCH: raw_pixels(items, still)}
    queries: dict[Modality, QuerySet] = {}
    if _TOUCH in result.pooled_queries:  # the same groups of presses, each its still moments
        q = result.pooled_queries[_TOUCH]
        still_touch = EmbeddedItems(_TOUCH, touch, embedded[_TOUCH].fabric_ids, tuple(items))
        pool = max_pool_presses if pool_exact else press_pooler(model, still, batch_size, device)
        pooled = pool(still_touch, q.members)
        if spaces is not None:
            pooled = spaces[_TOUCH].project(pooled)
        queries[_TOUCH] = QuerySet(np.asarray(pooled, dtype=np.float64), q.fabric, q.members)
    out = _model_scores(result, _in_space(vecs, spaces), queries, pairs, "_untouched")
    out |= _pixel_scores(result, pixels, pairs, "_untouched")
    return out, []
