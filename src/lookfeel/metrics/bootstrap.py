"""Uncertainty: bootstrap intervals over test fabrics, and spread over training seeds.

Queries of one fabric are not independent (they share the fabric), so the bootstrap resamples
fabrics, not queries: each replicate draws F fabrics with replacement and recomputes the metric
from the per-query values of the drawn fabrics (a fabric drawn twice counts twice). All
replicates come from one (B, F) matrix of multinomial weights, so B = 1000 costs a few matrix
products. A statistic that is not a mean over queries (R^2, Spearman) is computed on each
resample from the same weights (`lookfeel.metrics.properties.resampled_r2`) and its interval
read off by `percentile_interval`.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "MIN_INTERVAL_FABRICS",
    "bootstrap_ci",
    "fabric_weights",
    "mean_and_spread",
    "percentile_interval",
]

MIN_INTERVAL_FABRICS = 10
"""Below this many fabrics (or objects) an interval resampling them says little, and the
reports say so (`reproduce`'s findings, `evaluate`'s intervals, `cv`'s pick tables and
property probes). Pick 1 of 10 offers 10 fabrics
a draw (the paper's split needs 10 of its test fabrics for it), and a bootstrap over fewer
fabrics can only resample those few, so an interval can come out far narrower than the
uncertainty: over 4 fabrics one cell read 0.019 [0.00, 0.04] with chance at 0.250."""


def fabric_weights(n_fabrics: int, n_boot: int = 1000, seed: int = 0) -> NDArray[np.float64]:
    """(B, F) times each fabric is drawn in each of B resamples of F fabrics with replacement."""
    rng = np.random.default_rng(seed)
    if n_fabrics < 1:
        return np.zeros((n_boot, 0))
    return rng.multinomial(n_fabrics, np.full(n_fabrics, 1.0 / n_fabrics), size=n_boot).astype(
        np.float64
    )


def bootstrap_ci(
    values: ArrayLike,
    groups: ArrayLike,
    *,
    n_boot: int = 1000,
    alpha: float = 0.05,
    seed: int = 0,
    statistic: Literal["mean", "median"] = "mean",
    weights: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Percentile bootstrap interval of a per-query metric, resampling groups (fabrics).

    Args:
        values: (Q,) or (Q, M) per-query values of M metrics; NaN entries are left out (of
            that metric only).
        groups: (Q,) group (fabric) id of each query.
        n_boot: resamples B.
        alpha: the interval covers 1 - alpha (0.05: the 2.5th and 97.5th percentiles).
        seed: seeds the resampling; the same seed and groups give the same resamples, so
            intervals of different metrics are computed on the same draws.
        statistic: ``"mean"`` (the query-weighted mean over the drawn fabrics' queries) or
            ``"median"`` (the weighted median, for the median rank).
        weights: (B, F) resample weights from `fabric_weights` over the sorted unique groups,
            to share one draw between calls; overrides n_boot and seed.

    Returns:
        (low, high), each (M,) (or 0-d for 1-D values); NaN where no resample was drawn
        (``n_boot`` 0) or the metric is undefined in every one.
    """
    v = np.asarray(values, dtype=np.float64)
    one = v.ndim == 1
    v2 = v[:, None] if one else v
    g = np.asarray(groups).reshape(-1)
    if len(g) != len(v2):
        raise ValueError(f"groups has {len(g)} entries for {len(v2)} values")
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha must be in (0, 1); got {alpha}")
    uniq, gi = np.unique(g, return_inverse=True)
    w = fabric_weights(len(uniq), n_boot, seed) if weights is None else weights
    if w.shape[1] != len(uniq):
        raise ValueError(f"weights cover {w.shape[1]} groups; the values have {len(uniq)}")
    n_m = v2.shape[1]
    reps = np.full((len(w), n_m), np.nan)
    for j in range(n_m):
        ok = ~np.isnan(v2[:, j])
        if not ok.any():
            continue
        if statistic == "mean":
            sums = np.bincount(gi[ok], weights=v2[ok, j], minlength=len(uniq))
            counts = np.bincount(gi[ok], minlength=len(uniq)).astype(np.float64)
            den = w @ counts
            with np.errstate(invalid="ignore", divide="ignore"):
                reps[:, j] = (w @ sums) / den
        elif statistic == "median":
            reps[:, j] = _weighted_median(v2[ok, j], gi[ok], w)
        else:
            raise ValueError(f"statistic must be 'mean' or 'median'; got {statistic!r}")
    q = 100.0 * np.array([alpha / 2.0, 1.0 - alpha / 2.0])
    if not len(w):  # no resample drawn (n_boot 0): no interval, NaN, as for an undefined one
        low, high = np.full(n_m, np.nan), np.full(n_m, np.nan)
    else:
        low, high = np.nanpercentile(reps, q, axis=0) if n_m else (np.zeros(0), np.zeros(0))
    low, high = np.asarray(low, dtype=np.float64), np.asarray(high, dtype=np.float64)
    return (low[0], high[0]) if one else (low, high)


def percentile_interval(replicates: ArrayLike, alpha: float = 0.05) -> tuple[float, float]:
    """The percentile interval of a statistic from its bootstrap replicates (B,): their
    ``alpha / 2`` and ``1 - alpha / 2`` quantiles (the 2.5th and 97.5th percentiles for 0.05),
    over the replicates where the statistic is defined (not NaN); ``(nan, nan)`` where none
    is."""
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha must be in (0, 1); got {alpha}")
    r = np.asarray(replicates, dtype=np.float64).reshape(-1)
    r = r[~np.isnan(r)]
    if not len(r):
        return float("nan"), float("nan")
    low, high = np.percentile(r, [100.0 * alpha / 2.0, 100.0 * (1.0 - alpha / 2.0)])
    return float(low), float(high)


def _weighted_median(
    x: NDArray[np.float64], gi: NDArray[np.int64], w: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Lower weighted median of x for each resample: query weight = its group's weight.

    Works on the distinct values: (B, F) @ (F, U) counts per value, then a running sum.
    """
    vals, vi = np.unique(x, return_inverse=True)
    per_value = np.zeros((w.shape[1], len(vals)))
    np.add.at(per_value, (gi, vi), 1.0)
    cw = np.cumsum(w @ per_value, axis=1)  # (B, U)
    total = cw[:, -1:]
    pos = np.argmax(cw >= 0.5 * total, axis=1)
    return np.where(total[:, 0] > 0, vals[pos], np.nan)


def mean_and_spread(values_over_seeds: ArrayLike) -> dict[str, float]:
    """Summarise one metric over repeated runs (training seeds): mean, std, sem, min, max, n.

    ``std`` uses ddof 1 (the sample standard deviation; NaN for a single run), ``sem`` is
    std / sqrt(n). NaN runs are left out.
    """
    v = np.asarray(values_over_seeds, dtype=np.float64).reshape(-1)
    v = v[~np.isnan(v)]
    n = len(v)
    if n == 0:
        nan = float("nan")
        return {"mean": nan, "std": nan, "sem": nan, "min": nan, "max": nan, "n": 0.0}
    std = float(v.std(ddof=1)) if n > 1 else float("nan")
    return {
        "mean": float(v.mean()),
        "std": std,
        "sem": std / float(np.sqrt(n)) if n > 1 else float("nan"),
        "min": float(v.min()),
        "max": float(v.max()),
        "n": float(n),
    }
