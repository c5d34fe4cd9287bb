"""Validation during training: pick 1 of 10 (exact expectation) on held-out items, each touch
query one press (`lookfeel evaluate` pools ``data.presses`` of them and gives intervals)."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import torch

from lookfeel.data import ImageLoader, Item
from lookfeel.embedding import check_finite, embed_items
from lookfeel.metrics import EXACT_PICK, score_pairs
from lookfeel.modality import Modality, Pair
from lookfeel.models import Embedder, add_press_axis, eval_mode
from lookfeel.train.features import FeatureTable

__all__ = ["FEWER_THAN_TWO", "MAIN_PAIR", "default_pairs", "not_scored_reason", "validate"]

MAIN_PAIR = Pair(Modality.TOUCH, Modality.DEPTH)
"""The paper's main task: a GelSight press matched against depth images."""


def default_pairs(modalities: Sequence[Modality]) -> list[Pair]:
    """Every ordered (query, gallery) pair, ``touch_to_depth`` (the paper's main task) first."""
    pairs = Pair.every(modalities)
    if MAIN_PAIR in pairs:
        pairs.remove(MAIN_PAIR)
        pairs.insert(0, MAIN_PAIR)
    return pairs


@torch.inference_mode()
def _embed_cached(
    model: Embedder, table: FeatureTable, m: Modality, items: list[Item], batch: int
) -> np.ndarray:
    out = []
    for start in range(0, len(items), batch):
        f = add_press_axis(table.gather(m, items[start : start + batch]), m)
        out.append(model({m.value: f}, from_trunk=True)[m.value].float().cpu())
    return check_finite(torch.cat(out).numpy(), items)


FEWER_THAN_TWO = "fewer than two held-out items per fabric"
"""The short reason every unscored pair's reason ends with (`lookfeel reproduce`'s legend)."""


def not_scored_reason(pair: Pair, have: Sequence[Modality]) -> str:
    """Why no query of ``pair`` could be scored on the held-out items (``have``: the
    modalities that have any): the pair needs two items of a fabric (one the query, one its
    own fabric's candidate), within a modality or across two."""
    q, g = pair.query.value, pair.gallery.value
    missing = [m.value for m in dict.fromkeys((pair.query, pair.gallery)) if m not in have]
    if missing:
        return f"no held-out {' or '.join(missing)} item ({FEWER_THAN_TWO})"
    if pair.same:
        return f"no held-out fabric has a second {q} item for a query to find ({FEWER_THAN_TWO})"
    return f"no held-out fabric with a {q} item has a {g} item for it to find ({FEWER_THAN_TWO})"


def validate(
    model: Embedder,
    items: Mapping[Modality, list[Item]],
    loader: ImageLoader,
    table: FeatureTable | None,
    batch_size: int,
    device: torch.device,
    pairs: Sequence[Pair | str] = (),
) -> dict[str, Any]:
    """Embed the validation items and score each pair by pick 1 of 10 (exact, top-1 and -3).

    Same-modality pairs never offer a query its own item; with fewer than 10 fabrics the
    candidates offered shrink, and ``chance`` says so (`lookfeel.metrics.EXACT_PICK`). Every
    query is one item: a touch query is a single press, never pooled as `lookfeel evaluate`
    pools ``data.presses`` of them, so the two give different numbers for a run of more presses.

    A pair none of whose queries has an item of its own fabric to find (one depth image per
    held-out fabric for depth to depth; no held-out item of a modality at all, as
    ``train.split=seen`` leaves a fabric with one item) is not scored: it has no numbers, only
    ``{pair}_not_scored``, the reason.

    Args:
        pairs: the pairs to score (``query_to_gallery``); default `default_pairs` of the
            modalities of ``items``.

    Returns:
        ``{pair}_top1``, ``{pair}_top3`` and ``{pair}_chance`` per scored pair, with
        ``{pair}_queries`` (the queries scored, one item each) and ``{pair}_fabrics`` (the
        held-out fabrics they come from), ``{pair}_not_scored`` (why, in words) per pair not
        scored, and ``primary_pair`` (the first pair's name: what ``best.pt`` is chosen by).

    Raises:
        EmbeddingError: the model embeds some item as NaN or infinity (a diverged run).
    """
    emb: dict[Modality, np.ndarray] = {}
    fab: dict[Modality, np.ndarray] = {}
    with eval_mode(model):
        for m, its in items.items():
            if not its:
                continue
            if table is not None:
                emb[m] = _embed_cached(model, table, m, its, batch_size)
            else:
                emb[m] = embed_items(model, its, loader, batch_size, device)
            fab[m] = np.array([it.fabric_id for it in its])
    wanted = [Pair.parse(p) for p in pairs] or default_pairs(list(items))
    out: dict[str, Any] = {"primary_pair": str(wanted[0])} if wanted else {}
    present = [p for p in wanted if p.query in emb and p.gallery in emb]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # fewer than 10 fabrics: chance says so
        scores = score_pairs(emb, fab, EXACT_PICK, present) if present else {}
    for pair in wanted:
        s = scores.get(pair)
        if s is None or s.pick.n_queries == 0:
            out[f"{pair}_not_scored"] = not_scored_reason(pair, list(emb))
            continue
        out[f"{pair}_top1"] = s.metrics["top1"]
        out[f"{pair}_top3"] = s.metrics["top3"]
        out[f"{pair}_chance"] = s.metrics["top1_chance"]
        scored = ~np.isnan(s.pick.per_query[:, 0])  # queries with an item of their own fabric
        out[f"{pair}_queries"] = int(s.pick.n_queries)
        out[f"{pair}_fabrics"] = len(np.unique(fab[pair.query][scored]))
    return out
