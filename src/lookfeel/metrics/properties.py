"""Physical-property probes: how well does the embedding predict thickness, stiffness, ...?

The paper labels every fabric with thickness, stiffness, stretchiness and density (section 3)
and hopes the embedding represents them. A probe fits a simple regressor from embeddings of
the training fabrics to each label and scores it on the test fabrics, which it never saw.

Per-item or per-fabric: labels belong to fabrics, so items of one fabric are not independent
samples. When fabric ids are given, each fabric's embeddings are averaged first and the probe
fits and scores one row per fabric; without them it uses one row per item.

`probe_columns` keeps each held-out row's prediction and the training rows' mean label (what
a probe that knows nothing predicts); `resampled_r2` and `resampled_spearman` score such
predictions in bootstrap resamples of the rows (`lookfeel.metrics.bootstrap.fabric_weights`),
as `lookfeel cv` does over every held-out fabric of a seed's folds.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

# scikit-learn and scipy.stats are imported where a probe is fitted or scored, not here:
# `lookfeel match` imports this module (through `lookfeel.metrics` and the cross-modal map)
# but fits nothing, and the two took 0.5 s of its start (tests/test_imports.py).

__all__ = [
    "MIN_SPEARMAN",
    "ProbeColumn",
    "fit_ridge",
    "fit_ridge_multi",
    "knn_neighbours",
    "per_fabric_means",
    "probe_columns",
    "property_probe",
    "resampled_r2",
    "resampled_spearman",
]

MIN_SPEARMAN = 3
"""Held-out items below which a probe's Spearman says nothing and is not shown (`lookfeel cv`
leaves a run's out, `lookfeel evaluate` its report's): over two it is +1 or -1 whatever the
probe predicts."""


def knn_neighbours(k: int, n_reference: int) -> int:
    """The neighbours a k-NN over ``n_reference`` reference rows averages: ``k``, but at most
    half of them (and at least one).

    The nearest k of k or fewer rows are all of them: the k-NN then answers their mean, the same
    for every query (and a probe scores exactly the MAE of always answering the training mean).
    Half keeps the nearest a minority; on 10 or more rows ``k`` = 5 stays 5.
    """
    return max(1, min(k, n_reference // 2))


def per_fabric_means(
    emb: NDArray[np.float64], labels: NDArray[np.float64], fabric: NDArray[np.generic]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.generic]]:
    """Each fabric's mean embedding (N_f, D) and labels (N_f, L; NaN kept), and the fabrics."""
    uniq, inv = np.unique(fabric, return_inverse=True)
    counts = np.bincount(inv, minlength=len(uniq)).astype(np.float64)
    e = np.zeros((len(uniq), emb.shape[1]))
    np.add.at(e, inv, emb)
    e /= counts[:, None]
    lab = np.full((len(uniq), labels.shape[1]), np.nan)
    for j in range(labels.shape[1]):
        ok = ~np.isnan(labels[:, j])
        s = np.bincount(inv[ok], weights=labels[ok, j], minlength=len(uniq))
        n = np.bincount(inv[ok], minlength=len(uniq))
        with np.errstate(invalid="ignore", divide="ignore"):
            lab[:, j] = s / n  # labels are per fabric; the mean just collapses repeats
    return e, lab, uniq


def fit_ridge_multi(
    xtr: NDArray[np.float64], ytr: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Ridge regression of ``ytr`` (N, K) on ``xtr`` (N, D), one penalty for all K outputs
    chosen by leave-one-out (efficient, RidgeCV); returns ``(coef (D, K), intercept (K,))`` on
    the raw features.

    Features are centred and divided by one common scale (the root mean column variance), not
    per column: a column nearly constant in training (a saturated pixel, a dead unit) would
    otherwise be blown up and dominate any test row where it moves. The penalty grid grows with
    the dimension, since the Gram matrix of D unit-variance columns does.
    """
    from sklearn.linear_model import RidgeCV

    y = np.asarray(ytr, dtype=np.float64).reshape(len(ytr), -1)
    mu = xtr.mean(axis=0)
    scale = float(np.sqrt(((xtr - mu) ** 2).mean()))
    scale = scale if scale > 0 else 1.0
    d = xtr.shape[1]
    ridge = RidgeCV(alphas=np.logspace(-3, 3, 25) * max(1, d))
    ridge.fit((xtr - mu) / scale, y)
    coef = np.asarray(ridge.coef_, dtype=np.float64).reshape(y.shape[1], d).T / scale
    intercept = np.asarray(ridge.intercept_, dtype=np.float64).reshape(-1) - mu @ coef
    return coef, intercept


def fit_ridge(
    xtr: NDArray[np.float64], ytr: NDArray[np.float64]
) -> tuple[NDArray[np.float64], float]:
    """`fit_ridge_multi` of one output ``ytr`` (N,); returns ``(coef (D,), intercept)``."""
    coef, intercept = fit_ridge_multi(xtr, ytr.reshape(-1, 1))
    return coef[:, 0], float(intercept[0])


def _ridge(
    xtr: NDArray[np.float64], ytr: NDArray[np.float64], xte: NDArray[np.float64]
) -> NDArray[np.float64]:
    """`fit_ridge` on the training rows, applied to ``xte``."""
    coef, intercept = fit_ridge(xtr, ytr)
    return np.asarray(xte @ coef + intercept, dtype=np.float64)


@dataclass(frozen=True)
class ProbeColumn:
    """What a probe made of one label column on the held-out rows (`probe_columns`).

    Attributes:
        rows: (M,) the held-out rows that have this label: their fabric ids when the probe
            was given fabrics (one row per fabric), else their row numbers.
        truth: (M,) their labels.
        pred: (M,) the probe's prediction for each; empty when the column was not fitted
            (fewer than 2 labelled training rows, or no labelled held-out row).
        n_train: the labelled training rows the probe was fitted on.
        train_mean: their mean label: what a probe that knows nothing predicts for every
            held-out row (NaN without training rows).
        k: the neighbours a k-NN probe averaged (NaN where it was not fitted); None for ridge.
    """

    rows: NDArray[np.generic]
    truth: NDArray[np.float64]
    pred: NDArray[np.float64]
    n_train: int
    train_mean: float
    k: float | None = None

    @property
    def fitted(self) -> bool:
        """Whether the probe predicted the held-out rows."""
        return len(self.pred) > 0

    def scores(self) -> dict[str, float]:
        """R^2, Spearman and MAE of the predictions, as `property_probe` returns them:
        ``{"r2", "spearman", "mae", "n_train", "n_test"}`` and, for k-NN, ``"k"``. Each is
        NaN where the column was not fitted; R^2 and Spearman also where fewer than 2 rows
        or their labels are all one value, and Spearman where the predictions are."""
        nan = float("nan")
        out = {
            "r2": nan,
            "spearman": nan,
            "mae": nan,
            "n_train": float(self.n_train),
            "n_test": float(len(self.truth)),
        }
        if self.k is not None:
            out["k"] = self.k
        if not self.fitted:
            return out
        pred, truth = self.pred, self.truth
        out["mae"] = float(np.abs(pred - truth).mean())
        if len(truth) >= 2 and np.ptp(truth) > 0:
            out["r2"] = float(
                1.0 - ((pred - truth) ** 2).sum() / ((truth - truth.mean()) ** 2).sum()
            )
            if np.ptp(pred) > 0:
                from scipy.stats import spearmanr

                out["spearman"] = float(spearmanr(pred, truth).statistic)
        return out


def probe_columns(
    train_emb: ArrayLike,
    train_labels: ArrayLike,
    test_emb: ArrayLike,
    test_labels: ArrayLike,
    method: Literal["knn", "ridge"] = "knn",
    *,
    names: Sequence[str] | None = None,
    train_fabric: ArrayLike | None = None,
    test_fabric: ArrayLike | None = None,
    k: int = 5,
) -> dict[str, ProbeColumn]:
    """`property_probe`'s fits, with each held-out row's prediction kept: per label column,
    a `ProbeColumn` (the held-out rows, their labels and predictions, and the training
    mean). Arguments and errors as `property_probe`'s."""
    xtr = np.asarray(train_emb, dtype=np.float64)
    xte = np.asarray(test_emb, dtype=np.float64)
    ytr = np.asarray(train_labels, dtype=np.float64)
    yte = np.asarray(test_labels, dtype=np.float64)
    ytr = ytr[:, None] if ytr.ndim == 1 else ytr
    yte = yte[:, None] if yte.ndim == 1 else yte
    if xtr.ndim != 2 or xte.ndim != 2 or xtr.shape[1] != xte.shape[1]:
        raise ValueError(f"embeddings must be (N, D) with one D; got {xtr.shape}, {xte.shape}")
    if len(ytr) != len(xtr) or len(yte) != len(xte) or ytr.shape[1] != yte.shape[1]:
        raise ValueError(
            f"labels {ytr.shape}, {yte.shape} do not match embeddings {xtr.shape}, {xte.shape}"
        )
    if method not in ("knn", "ridge"):
        raise ValueError(f"method must be 'knn' or 'ridge'; got {method!r}")
    n_cols = ytr.shape[1]
    col_names = list(names) if names is not None else [str(j) for j in range(n_cols)]
    if len(col_names) != n_cols:
        raise ValueError(f"{len(col_names)} names for {n_cols} label columns")
    if (train_fabric is None) != (test_fabric is None):
        raise ValueError("give both train_fabric and test_fabric, or neither")
    rows: NDArray[np.generic] = np.arange(len(xte))
    if train_fabric is not None and test_fabric is not None:
        ftr = np.asarray(train_fabric).reshape(-1)
        fte = np.asarray(test_fabric).reshape(-1)
        shared = np.intersect1d(ftr, fte)
        if len(shared):
            raise ValueError(f"fabric(s) {shared[:5].tolist()} are in both train and test")
        xtr, ytr, _ = per_fabric_means(xtr, ytr, ftr)
        xte, yte, rows = per_fabric_means(xte, yte, fte)
    out: dict[str, ProbeColumn] = {}
    for j, name in enumerate(col_names):
        tr = ~np.isnan(ytr[:, j])
        te = ~np.isnan(yte[:, j])
        n_tr, n_te = int(tr.sum()), int(te.sum())
        used: float | None = None if method == "ridge" else float("nan")
        pred = np.zeros(0)
        if n_tr >= 2 and n_te >= 1:
            if method == "knn":
                from sklearn.neighbors import KNeighborsRegressor

                used = float(knn_neighbours(k, n_tr))
                knn = KNeighborsRegressor(n_neighbors=int(used))
                knn.fit(xtr[tr], ytr[tr, j])
                pred = np.asarray(knn.predict(xte[te]), dtype=np.float64)
            else:
                pred = _ridge(xtr[tr], ytr[tr, j], xte[te])
        mean = float(ytr[tr, j].mean()) if n_tr else float("nan")
        out[name] = ProbeColumn(rows[te], yte[te, j], pred, n_tr, mean, used)
    return out


def property_probe(
    train_emb: ArrayLike,
    train_labels: ArrayLike,
    test_emb: ArrayLike,
    test_labels: ArrayLike,
    method: Literal["knn", "ridge"] = "knn",
    *,
    names: Sequence[str] | None = None,
    train_fabric: ArrayLike | None = None,
    test_fabric: ArrayLike | None = None,
    k: int = 5,
) -> dict[str, dict[str, float]]:
    """Fit a probe per label column on training embeddings; score R^2, Spearman, MAE on test.

    Args:
        train_emb: (N, D) training embeddings.
        train_labels: (N,) or (N, L) labels; NaN means unknown and the row is skipped for that
            column only.
        test_emb: (M, D) test embeddings (other fabrics than training).
        test_labels: (M,) or (M, L).
        method: ``"knn"``: mean label of the k nearest training rows (Euclidean, the
            embedding's own metric); ``"ridge"``: ridge regression on centred embeddings under
            one common scale, its penalty chosen by leave-one-out over a log grid (`_ridge`).
        names: a name per label column (default ``"0"``, ``"1"``, ...).
        train_fabric, test_fabric: (N,), (M,) fabric ids; when given, embeddings are averaged
            per fabric first, and a fabric in both sets raises.
        k: neighbours for ``"knn"``; at most half the training rows of a column
            (`knn_neighbours`: the nearest k of k or fewer are all of them, their mean).

    Returns:
        ``{name: {"r2", "spearman", "mae", "n_train", "n_test"}}``, and for ``"knn"`` ``"k"``,
        the neighbours it averaged (NaN where the column was not fitted); scores are NaN when
        a column has fewer than 2 training rows, fewer than 2 test rows or a constant
        target. `probe_columns` keeps each held-out row's prediction too.
    """
    columns = probe_columns(
        train_emb,
        train_labels,
        test_emb,
        test_labels,
        method,
        names=names,
        train_fabric=train_fabric,
        test_fabric=test_fabric,
        k=k,
    )
    return {name: c.scores() for name, c in columns.items()}


def _drawn_values(x: NDArray[np.float64], w: NDArray[np.float64]) -> NDArray[np.int64]:
    """(B,) how many distinct values of ``x`` (M,) each resample of ``w`` (B, M) draws."""
    _, inv = np.unique(x, return_inverse=True)
    onehot = np.zeros((len(x), int(inv.max(initial=-1)) + 1))
    onehot[np.arange(len(x)), inv] = 1.0
    return np.asarray(((w @ onehot) > 0).sum(axis=1), dtype=np.int64)


def _rows_and_weights(
    truth: ArrayLike, pred: ArrayLike, weights: ArrayLike | None
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    t = np.asarray(truth, dtype=np.float64).reshape(-1)
    p = np.asarray(pred, dtype=np.float64).reshape(-1)
    w = np.ones((1, len(t))) if weights is None else np.asarray(weights, dtype=np.float64)
    if len(p) != len(t) or w.ndim != 2 or w.shape[1] != len(t):
        raise ValueError(
            f"truth {t.shape}, predictions {p.shape} and weights {w.shape} must be (M,), (M,) "
            "and (B, M)"
        )
    return t, p, w


def resampled_r2(
    truth: ArrayLike, pred: ArrayLike, weights: ArrayLike | None = None
) -> NDArray[np.float64]:
    """R^2 of predictions ``pred`` (M,) of ``truth`` (M,) in each of B resamples of the rows.

    ``weights`` (B, M): how many times each resample draws each row (`fabric_weights`: a row
    drawn twice counts twice); None: the rows once, as they are (B = 1). R^2 is 1 - the
    squared error over the squared deviation from the drawn rows' own mean truth, so a
    predictor of any other constant scores below 0. NaN where a resample's truths are all
    one value (nothing to explain).

    Returns:
        (B,) R^2 of each resample.
    """
    t, p, w = _rows_and_weights(truth, pred, weights)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = (w @ t) / w.sum(axis=1)
        ss_tot = (w * (t[None, :] - mean[:, None]) ** 2).sum(axis=1)
        r2 = 1.0 - (w @ (p - t) ** 2) / ss_tot
    return np.where(_drawn_values(t, w) >= 2, r2, np.nan)


def _midranks(x: NDArray[np.float64], w: NDArray[np.float64]) -> NDArray[np.float64]:
    """(B, M) the rank of each row of ``x`` (M,) among the rows each resample of ``w`` (B, M)
    draws, ties given their mean rank (as Spearman's): the draws strictly below it, plus the
    mean position among the draws equal to it."""
    below = (x[:, None] < x[None, :]).astype(np.float64)  # [j, i]: row j below row i
    equal = (x[:, None] == x[None, :]).astype(np.float64)
    return np.asarray(w @ below + (w @ equal + 1.0) / 2.0, dtype=np.float64)


def resampled_spearman(
    truth: ArrayLike, pred: ArrayLike, weights: ArrayLike | None = None
) -> NDArray[np.float64]:
    """Spearman's rank correlation of ``pred`` (M,) with ``truth`` (M,) in each of B resamples
    of the rows (``weights`` (B, M) as `resampled_r2`'s; None: the rows as they are).

    Each resample's rows are ranked among its draws (a row drawn twice is two tied values,
    both given their mean rank), and the ranks correlated, weighted by the draws: exactly
    ``scipy.stats.spearmanr`` of the drawn rows written out. NaN where a resample draws one
    value of either.

    Returns:
        (B,) Spearman of each resample.
    """
    t, p, w = _rows_and_weights(truth, pred, weights)
    rt, rp = _midranks(t, w), _midranks(p, w)
    total = w.sum(axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        dt = rt - (w * rt).sum(axis=1, keepdims=True) / total
        dp = rp - (w * rp).sum(axis=1, keepdims=True) / total
        rho = (w * dt * dp).sum(axis=1) / np.sqrt((w * dt**2).sum(axis=1) * (w * dp**2).sum(axis=1))
    ok = (_drawn_values(t, w) >= 2) & (_drawn_values(p, w) >= 2)
    return np.where(ok, np.clip(rho, -1.0, 1.0), np.nan)
