"""Match probabilities ``P ∝ exp(-c D^2)`` (paper section 5.2, eq. 3-4) and their calibration.

For a query and a set of candidate items, ``P(q, i) = exp(-c D_qi^2) / sum_j exp(-c D_qj^2)``
(the paper fixes c = 0.085 and normalises over all depth images of the candidate fabrics). The
probability of a fabric is the sum over its items. `fit_temperature` chooses c by maximum
likelihood of each query's true fabric instead of fixing it; the reliability curve and the
expected calibration error say whether the resulting fabric probabilities can be trusted.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lookfeel.metrics._ranking import prepare

__all__ = [
    "PAPER_C",
    "ReliabilityCurve",
    "expected_calibration_error",
    "fabric_predictions",
    "fabric_probabilities",
    "fit_temperature",
    "match_probabilities",
    "reliability_curve",
]

PAPER_C = 0.085
"""The paper's coefficient c in ``P ∝ exp(-c D^2)`` (section 5.2)."""


def match_probabilities(
    dist: ArrayLike, c: float = PAPER_C, exclude_self: ArrayLike | None = None
) -> NDArray[np.float64]:
    """Row-normalised ``exp(-c D^2)`` over the gallery items (paper eq. 3-4).

    Computed as a softmax of ``-c D^2`` with the row maximum subtracted (log-sum-exp), so large
    c or D never under- or overflow.

    Args:
        dist: (Q, G) distances.
        c: positive coefficient.
        exclude_self: (Q,) gallery index of each query's own item (-1 for none), or a (Q, G)
            mask; those items get probability 0.

    Returns:
        (Q, G) probabilities, each row summing to 1.
    """
    if not c > 0:
        raise ValueError(f"c must be positive; got {c}")
    d = np.asarray(dist, dtype=np.float64)
    if d.ndim != 2:
        raise ValueError(f"dist must be 2-D (Q, G); got shape {d.shape}")
    logits = -c * np.square(d)
    mask = _mask(exclude_self, d.shape)
    if mask is not None:
        logits[mask] = -np.inf
    logits -= logits.max(axis=1, keepdims=True)
    p = np.exp(logits)
    p /= p.sum(axis=1, keepdims=True)
    return p


def _mask(exclude_self: ArrayLike | None, shape: tuple[int, ...]) -> NDArray[np.bool_] | None:
    if exclude_self is None:
        return None
    e = np.asarray(exclude_self)
    if e.dtype == np.bool_:
        if e.shape != shape:
            raise ValueError(f"exclude_self mask must have shape {shape}; got {e.shape}")
        return e
    m = np.zeros(shape, dtype=bool)
    keep = e >= 0
    m[np.flatnonzero(keep), e[keep]] = True
    return m


def fabric_probabilities(
    dist: ArrayLike,
    gallery_fabric: ArrayLike,
    c: float = PAPER_C,
    exclude_self: ArrayLike | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.generic]]:
    """P(query shows gallery fabric f): `match_probabilities` summed over f's items.

    Args:
        dist: (Q, G) distances.
        gallery_fabric: (G,) fabric id of each gallery item.

    Returns:
        (probabilities (Q, F), fabric ids (F,) sorted); rows sum to 1.
    """
    gf = np.asarray(gallery_fabric).reshape(-1)
    p = match_probabilities(dist, c, exclude_self)
    if p.shape[1] != len(gf):
        raise ValueError(f"gallery_fabric has {len(gf)} entries for {p.shape[1]} dist columns")
    fabrics, gi = np.unique(gf, return_inverse=True)
    onehot = np.zeros((len(gf), len(fabrics)))
    onehot[np.arange(len(gf)), gi] = 1.0
    return p @ onehot, fabrics  # (Q, G) @ (G, F) -> (Q, F)


def fabric_predictions(
    dist: ArrayLike,
    query_fabric: ArrayLike,
    gallery_fabric: ArrayLike,
    c: float = PAPER_C,
    exclude_self: ArrayLike | None = None,
) -> tuple[NDArray[np.generic], NDArray[np.float64], NDArray[np.bool_]]:
    """Most probable fabric of each query, its probability (confidence) and whether it is right.

    Returns:
        (predicted fabric (Q,), confidence (Q,), correct (Q,)).
    """
    probs, fabrics = fabric_probabilities(dist, gallery_fabric, c, exclude_self)
    best = np.argmax(probs, axis=1)
    predicted = fabrics[best]
    correct = predicted == np.asarray(query_fabric).reshape(-1)
    return predicted, probs[np.arange(len(best)), best], correct


def fit_temperature(
    dist: ArrayLike,
    query_fabric: ArrayLike,
    gallery_fabric: ArrayLike,
    exclude_self: ArrayLike | None = None,
) -> float:
    """Maximum-likelihood c: maximise the mean ``log P(true fabric)`` over the queries.

    ``P(true fabric) = sum over the true fabric's items of P(q, i)`` (`fabric_probabilities`),
    so the fit is at the fabric level, as the paper reads the probabilities. Fit on validation
    data, not on the test fabrics. c is searched on a log grid (relative to the median squared
    distance) and refined with Brent's method; if the likelihood still rises at the grid's
    edge (e.g. perfectly separated fabrics want c -> infinity) the edge is returned with a
    warning.

    Args:
        dist: (Q, G) distances.
        query_fabric: (Q,) fabric id of each query; queries without a true item are skipped.
        gallery_fabric: (G,) fabric id of each gallery item.
        exclude_self: as in `match_probabilities`.

    Returns:
        The fitted c.
    """
    prep = prepare(dist, query_fabric, gallery_fabric, exclude_self)
    d2 = np.square(prep.dist)
    true = prep.gidx[None, :] == prep.qidx[:, None]
    if prep.excluded is not None:
        d2[prep.excluded] = np.inf
        true &= ~prep.excluded
    keep = true.any(axis=1)
    if not keep.any():
        raise ValueError("no query has an item of its fabric in the gallery")
    d2, true = d2[keep], true[keep]
    # Shift by the row minima so exp never underflows to 0 for the nearest items.
    min_all = d2.min(axis=1, keepdims=True)
    min_true = np.where(true, d2, np.inf).min(axis=1, keepdims=True)
    rel_all = d2 - min_all
    # Only the true items' exp is computed (a query's fabric has a few of the G items); the
    # others are exp(-inf) = 0, so they are left 0 in a (Q, G) buffer summed as the whole
    # row was: the same sums, bit for bit, so the same c.
    rows, cols = np.nonzero(true)
    rel_true = (d2 - min_true)[rows, cols]
    buf = np.empty_like(rel_all)  # (Q, G) buffers for every call, not new ones each
    buf_true = np.zeros_like(rel_all)

    def nll(log_c: float) -> float:
        c = np.exp(log_c)
        np.multiply(rel_all, -c, out=buf)
        np.exp(buf, out=buf)
        lse_all = -c * min_all[:, 0] + np.log(buf.sum(axis=1))
        buf_true[rows, cols] = np.exp(-c * rel_true)
        lse_true = -c * min_true[:, 0] + np.log(buf_true.sum(axis=1))
        return float(-(lse_true - lse_all).mean())

    finite = d2[np.isfinite(d2)]
    scale = float(np.median(finite[finite > 0])) if (finite > 0).any() else 1.0
    grid = np.log(1.0 / scale) + np.linspace(np.log(1e-4), np.log(1e4), 33)
    vals = np.array([nll(x) for x in grid])
    i = int(np.argmin(vals))
    if i in (0, len(grid) - 1):
        warnings.warn(
            f"fit_temperature: the likelihood is best at the search edge c={np.exp(grid[i]):.3g}",
            UserWarning,
            stacklevel=2,
        )
        return float(np.exp(grid[i]))
    from scipy.optimize import minimize_scalar  # here: `lookfeel match` never fits c

    res = minimize_scalar(
        nll, bounds=(grid[i - 1], grid[i + 1]), method="bounded", options={"xatol": 1e-6}
    )
    return float(np.exp(res.x))


@dataclass(frozen=True)
class ReliabilityCurve:
    """Confidence against accuracy in equal-width bins of confidence."""

    edges: NDArray[np.float64]
    """(B + 1,) bin edges over [0, 1]."""
    confidence: NDArray[np.float64]
    """(B,) mean confidence in each bin (NaN when empty)."""
    accuracy: NDArray[np.float64]
    """(B,) fraction correct in each bin (NaN when empty)."""
    count: NDArray[np.int64]
    """(B,) predictions in each bin."""
    ece: float
    """Expected calibration error: ``sum_b count_b / N |accuracy_b - confidence_b|``."""


def reliability_curve(
    confidence: ArrayLike, correct: ArrayLike, n_bins: int = 10
) -> ReliabilityCurve:
    """Bin predictions by confidence and compare each bin's accuracy with its confidence.

    Args:
        confidence: (N,) predicted probability of the predicted class, in [0, 1].
        correct: (N,) whether each prediction was right.
        n_bins: equal-width bins over [0, 1]; 1.0 falls in the last bin.
    """
    conf = np.asarray(confidence, dtype=np.float64).reshape(-1)
    ok = np.asarray(correct, dtype=np.float64).reshape(-1)
    if len(conf) != len(ok):
        raise ValueError(f"confidence has {len(conf)} entries, correct has {len(ok)}")
    if n_bins < 1:
        raise ValueError(f"n_bins must be >= 1; got {n_bins}")
    if ((conf < 0) | (conf > 1)).any():
        raise ValueError("confidence must lie in [0, 1]")
    edges = np.linspace(0.0, 1.0, n_bins + 1)
    b = np.minimum((conf * n_bins).astype(np.int64), n_bins - 1)
    count = np.bincount(b, minlength=n_bins)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_conf = np.bincount(b, weights=conf, minlength=n_bins) / count
        acc = np.bincount(b, weights=ok, minlength=n_bins) / count
    filled = count > 0
    ece = float((count[filled] * np.abs(acc[filled] - mean_conf[filled])).sum() / max(len(conf), 1))
    return ReliabilityCurve(edges, mean_conf, acc, count.astype(np.int64), ece)


def expected_calibration_error(
    confidence: ArrayLike, correct: ArrayLike, n_bins: int = 10
) -> float:
    """ECE of `reliability_curve` (0 for perfectly calibrated confidences)."""
    return reliability_curve(confidence, correct, n_bins).ece
