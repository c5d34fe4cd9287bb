"""Validation during training: pick 1 of 10 (exact expectation) on held-out items."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import torch

from lookfeel.data import ImageLoader, Item
from lookfeel.embedding import embed_items
from lookfeel.metrics import PickResult, pairwise_distances, pick_k_of_n_exact
from lookfeel.modality import Modality
from lookfeel.models import Embedder
from lookfeel.train.features import FeatureTable

__all__ = ["default_pairs", "pick_pair", "validate"]


def default_pairs(modalities: Sequence[Modality]) -> list[str]:
    """Every ordered (query, gallery) pair, ``touch_to_depth`` (the paper's main task) first."""
    pairs = [f"{q.value}_to_{g.value}" for q in modalities for g in modalities]
    if "touch_to_depth" in pairs:
        pairs.remove("touch_to_depth")
        pairs.insert(0, "touch_to_depth")
    return pairs


@torch.inference_mode()
def _embed_cached(
    model: Embedder, table: FeatureTable, m: Modality, items: list[Item], batch: int
) -> np.ndarray:
    out = []
    for start in range(0, len(items), batch):
        f = table.gather(m, items[start : start + batch])
        if m is Modality.TOUCH:
            f = f.unsqueeze(1)  # (B, *F) -> (B, P=1, *F)
        out.append(model({m.value: f}, from_trunk=True)[m.value].float().cpu())
    return torch.cat(out).numpy()


def pick_pair(
    emb: Mapping[Modality, np.ndarray], fab: Mapping[Modality, np.ndarray], pair: str
) -> PickResult:
    """Exact pick 1 of 10, top-1 and top-3, for one ``query_to_gallery`` pair of embeddings
    (a query never counts itself when both sides are one modality). With fewer than 10
    fabrics the candidates offered shrink, and ``chance`` says so."""
    q, _, g = pair.partition("_to_")
    mq, mg = Modality(q), Modality(g)
    dist = pairwise_distances(emb[mq], emb[mg])
    exclude = np.arange(len(emb[mq])) if mq is mg else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # fewer than 10 fabrics: n_effective is reported
        return pick_k_of_n_exact(dist, fab[mq], fab[mg], n=10, ks=(1, 3), exclude_self=exclude)


def validate(
    model: Embedder,
    items: Mapping[Modality, list[Item]],
    loader: ImageLoader,
    table: FeatureTable | None,
    batch_size: int,
    device: torch.device,
    pairs: Sequence[str] = (),
) -> dict[str, Any]:
    """Embed the validation items and score each pair by pick 1 of 10 (exact, top-1 and -3).

    Returns:
        ``{pair}_top1``, ``{pair}_top3`` and ``{pair}_chance`` per pair, and ``primary_pair``
        (the first pair: what ``best.pt`` is chosen by).
    """
    was_training = model.training
    model.eval()
    try:
        emb: dict[Modality, np.ndarray] = {}
        fab: dict[Modality, np.ndarray] = {}
        for m, its in items.items():
            if not its:
                continue
            if table is not None:
                emb[m] = _embed_cached(model, table, m, its, batch_size)
            else:
                emb[m] = embed_items(model, its, loader, batch_size, device)
            fab[m] = np.array([it.fabric_id for it in its])
    finally:
        model.train(was_training)
    wanted = list(pairs) or default_pairs([m for m in items if m in emb])
    out: dict[str, Any] = {"primary_pair": wanted[0]}
    for pair in wanted:
        q, _, g = pair.partition("_to_")
        if Modality(q) not in emb or Modality(g) not in emb:
            continue
        res = pick_pair(emb, fab, pair)
        out[f"{pair}_top1"] = float(res.mean[0])
        out[f"{pair}_top3"] = float(res.mean[1])
        out[f"{pair}_chance"] = float(res.chance[0])
    return out
