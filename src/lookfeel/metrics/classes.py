"""Class labels (ranks such as hardness 0/1/2, words such as material): accuracy, macro-F1,
the majority-class baseline, and a nearest-neighbour probe on any embedding.

Pure functions of integer class indices (``-1``: unknown, left out) and arrays; they know
nothing of models. A query's class is its object's, so intervals resample objects
(`lookfeel.metrics.bootstrap_ci` with the object ids as groups).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "UNKNOWN",
    "LogitTemperature",
    "accuracy",
    "fit_logit_temperature",
    "knn_classes",
    "logit_temperature",
    "macro_f1",
    "majority_class",
    "softmax",
]

UNKNOWN = -1
"""Class index of a query whose label is unknown: scored by nothing."""


def _known(truth: ArrayLike, predicted: ArrayLike) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    t = np.asarray(truth, dtype=np.int64)
    p = np.asarray(predicted, dtype=np.int64)
    if t.shape != p.shape:
        raise ValueError(f"truth {t.shape} and predictions {p.shape} differ in shape")
    keep = t != UNKNOWN
    return t[keep], p[keep]


def accuracy(truth: ArrayLike, predicted: ArrayLike) -> float:
    """Fraction of known queries whose predicted class is the true one (NaN when none known)."""
    t, p = _known(truth, predicted)
    return float(np.mean(t == p)) if t.size else float("nan")


def macro_f1(truth: ArrayLike, predicted: ArrayLike, n_classes: int | None = None) -> float:
    """The mean over classes of F1 = 2 TP / (2 TP + FP + FN), over the classes that occur in the
    truth or the predictions (a class never seen nor predicted has no F1). NaN when none known.
    """
    t, p = _known(truth, predicted)
    if not t.size:
        return float("nan")
    k = int(max(t.max(), p.max()) + 1) if n_classes is None else n_classes
    scores = []
    for c in range(k):
        tp = int(np.sum((t == c) & (p == c)))
        fp = int(np.sum((t != c) & (p == c)))
        fn = int(np.sum((t == c) & (p != c)))
        if tp + fp + fn:
            scores.append(2 * tp / (2 * tp + fp + fn))
    return float(np.mean(scores)) if scores else float("nan")


def softmax(logits: ArrayLike, temperature: float = 1.0) -> NDArray[np.float64]:
    """Row-wise softmax of (N, K) ``logits / temperature``."""
    from scipy.special import softmax as _softmax

    return np.asarray(_softmax(np.asarray(logits, np.float64) / temperature, axis=-1))


@dataclass(frozen=True)
class LogitTemperature:
    """A class head's temperature (`logit_temperature`) and whether it was fitted.

    Attributes:
        value: the temperature T of softmax(logits / T); the search's edge when ``at_edge``.
        at_edge: the likelihood was best at the edge of the search (about 1e-4 or 1e4 times
            the logits' scale): no temperature was fitted. A head no better than a guess on
            these rows wants T -> infinity (every class alike), one never wrong wants T -> 0;
            with few rows or classes either is common. Such a value is no calibration to use.
    """

    value: float
    at_edge: bool = False


_EDGE = "fit_temperature: the likelihood is best at the search"
"""The start of `lookfeel.metrics.calibration.fit_temperature`'s warning of an edge."""


def logit_temperature(logits: ArrayLike, truth: ArrayLike) -> LogitTemperature:
    """The temperature T under which softmax(logits / T) gives the known classes of ``truth``
    the highest likelihood (temperature scaling, Guo et al. 2017): T > 1 softens a head that is
    surer than it is right, T < 1 sharpens one that is less sure. The predicted class is the
    same at any T. Rows of unknown truth are left out; 1.0 when none is known.

    The fit is `lookfeel.metrics.calibration.fit_temperature`'s, with each class a gallery item
    at squared distance ``max(logits) - logits`` from its row: ``exp(-c D^2)`` is then
    ``softmax(c logits)``, so T = 1 / c. Where the likelihood is best at the search's edge (a
    head that knows nothing wants T -> infinity, one never wrong T -> 0) the edge is returned,
    without a warning, marked ``at_edge``: it was not fitted.

    Args:
        logits: (N, K) a class head's outputs.
        truth: (N,) class indices (`UNKNOWN`: left out).
    """
    from lookfeel.metrics.calibration import fit_temperature

    z = np.asarray(logits, dtype=np.float64)
    t = np.asarray(truth, dtype=np.int64)
    keep = t != UNKNOWN
    z, t = z[keep], t[keep]
    if not t.size:
        return LogitTemperature(1.0)
    dist = np.sqrt(z.max(axis=1, keepdims=True) - z)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        c = fit_temperature(dist, t, np.arange(z.shape[1]))
    edge = False
    for w in caught:
        if str(w.message).startswith(_EDGE):
            edge = True
        else:  # any other warning is the caller's to see
            warnings.warn(w.message, w.category, stacklevel=2)
    return LogitTemperature(1.0 / c, edge)


def fit_logit_temperature(logits: ArrayLike, truth: ArrayLike) -> float:
    """`logit_temperature`'s value: the fitted temperature, or, silently, the search's edge
    (`logit_temperature` says which)."""
    return logit_temperature(logits, truth).value


def majority_class(train_classes: ArrayLike, n_classes: int) -> int:
    """The most frequent known class (the lowest index on a tie); UNKNOWN when none is known."""
    c = np.asarray(train_classes, dtype=np.int64)
    c = c[c != UNKNOWN]
    if not c.size:
        return UNKNOWN
    return int(np.bincount(c, minlength=n_classes).argmax())


def knn_classes(
    train_x: ArrayLike,
    train_classes: ArrayLike,
    test_x: ArrayLike,
    n_classes: int,
    k: int = 5,
) -> NDArray[np.int64]:
    """Each test row's class by a vote of its ``k`` nearest known training rows (Euclidean,
    features z-scored on the training rows); ties go to the nearer neighbours' class.

    Returns:
        (N,) class indices; UNKNOWN for every row when no training row is known.
    """
    x = np.asarray(train_x, dtype=np.float64)
    c = np.asarray(train_classes, dtype=np.int64)
    q = np.asarray(test_x, dtype=np.float64)
    keep = c != UNKNOWN
    x, c = x[keep], c[keep]
    if not len(c):
        return np.full(len(q), UNKNOWN, np.int64)
    mean, std = x.mean(0), x.std(0) + 1e-8
    x, q = (x - mean) / std, (q - mean) / std
    d = (q**2).sum(1)[:, None] - 2 * q @ x.T + (x**2).sum(1)[None, :]
    k = min(k, len(c))
    nearest = np.argsort(d, axis=1, kind="stable")[:, :k]  # (N, k), nearest first
    votes = np.zeros((len(q), n_classes))
    for j in range(k):  # a nearer neighbour's vote weighs a little more: it breaks ties
        np.add.at(votes, (np.arange(len(q)), c[nearest[:, j]]), 1.0 + 1e-3 * (k - j))
    return votes.argmax(1).astype(np.int64)
