"""Metrics speed: all 9 modality pairs with bootstrap intervals from 10,000 embeddings.

Synthetic embeddings (D = 128; 3,334 depth, 3,333 colour, 3,333 touch) with fabric structure,
scored by `lookfeel.metrics.score_pairs` with everything on (`PAPER_PROTOCOL`): exact
pick-1-of-10 (top 1 and 3), the sampled protocol (15 queries x 10 draws per fabric), mAP,
recall@1/5/10, median rank and 1,000 fabric-bootstrap resamples. Two fabric counts: 118 (all
GelFabric fabrics, ~28 items per fabric and modality) and 18 (the paper's test split, ~185 items
each: more true candidates per query). Target: <= 10 s for each, median of 3 runs.
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path

import numpy as np

from lookfeel.metrics import PAPER_PROTOCOL, flat_metrics, score_pairs
from lookfeel.modality import Modality

TARGET_S = 10.0
RUNS = 3
SIZES = {Modality.DEPTH: 3334, Modality.COLOR: 3333, Modality.TOUCH: 3333}
DIM = 128


def _embeddings(n_fabrics: int, seed: int = 0) -> tuple[dict[Modality, np.ndarray], dict]:
    rng = np.random.default_rng(seed)
    centres = rng.standard_normal((n_fabrics, DIM))
    emb, fab = {}, {}
    for m, n in SIZES.items():
        fabric = np.arange(n) % n_fabrics
        emb[m] = 0.3 * centres[fabric] + rng.standard_normal((n, DIM))
        fab[m] = fabric
    return emb, fab


def _measure(n_fabrics: int) -> dict[str, object]:
    emb, fab = _embeddings(n_fabrics)
    times = []
    out: dict[str, float] = {}
    for _ in range(RUNS):
        start = time.perf_counter()
        out = flat_metrics(score_pairs(emb, fab, PAPER_PROTOCOL))
        times.append(time.perf_counter() - start)
    median = statistics.median(times)
    return {
        "fabrics": n_fabrics,
        "embeddings": sum(SIZES.values()),
        "dim": DIM,
        "pairs": len({k.rsplit("_top1", 1)[0] for k in out if k.endswith("_top1")}),
        "keys": len(out),
        "median_s": round(median, 3),
        "runs_s": [round(t, 3) for t in times],
        "met": median <= TARGET_S,
        "touch_to_depth_top1": round(out["touch_to_depth_top1"], 4),
        "touch_to_depth_top1_sampled": round(out["touch_to_depth_top1_sampled"], 4),
    }


def run(data: Path | None) -> dict[str, object]:
    """Median seconds for all 9 pairs with bootstrap intervals; ``data`` is not used."""
    del data  # synthetic embeddings: the metrics never see images
    configs = [_measure(118), _measure(18)]
    return {
        "what": "lookfeel.metrics.score_pairs on 10,000 embeddings, 9 pairs, 1000 bootstraps",
        "target_s": TARGET_S,
        "runs": RUNS,
        "configs": configs,
        "median_s": max(float(c["median_s"]) for c in configs),  # type: ignore[arg-type]
        "met": all(bool(c["met"]) for c in configs),
    }
