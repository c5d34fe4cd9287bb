"""Matching in label space: each modality's embeddings mapped onto the fabrics' labels.

Two modalities' embeddings meet only where training pulled them together. When the labels of
the training fabrics are known (thickness, density, stiffness, stretchiness ...), each
modality can also be mapped onto them, and a query matched to a gallery by how alike their
*predicted labels* are: a touch press that predicts "thick, dense, stiff" is matched to the
drape that predicts the same. The map is a ridge regression per label column, fitted on the
training fabrics only (their mean embeddings, the penalty chosen by leave-one-out over
fabrics), onto the column's normal scores among those fabrics (rank-based, so a skewed column
or one in odd units weighs like the others). Nothing is fitted on the fabrics being scored.

Used by `lookfeel cv` (the ``model_labels`` rows) beside matching in the embedding itself.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import ndtri
from scipy.stats import rankdata

from lookfeel.metrics.properties import fit_ridge, per_fabric_means

__all__ = ["MIN_FABRICS", "LabelSpace", "fit_label_space", "fit_label_spaces", "normal_scores"]

MIN_FABRICS = 3
"""A label column is mapped only when at least this many training fabrics have it."""


def normal_scores(values: ArrayLike) -> NDArray[np.float64]:
    """Rank-based normal scores ``Φ⁻¹((rank - 0.5) / n)``, ties sharing their mean rank; NaN
    stays NaN."""
    v = np.asarray(values, dtype=np.float64).reshape(-1)
    out = np.full(v.shape, np.nan)
    ok = ~np.isnan(v)
    n = int(ok.sum())
    if n:
        out[ok] = ndtri((rankdata(v[ok]) - 0.5) / n)
    return out


@dataclass(frozen=True)
class LabelSpace:
    """A linear map from one modality's embeddings to predicted label normal scores.

    Attributes:
        columns: the label columns mapped (those enough training fabrics have).
        coef: (D, L) weights on the raw embedding.
        intercept: (L,).
    """

    columns: tuple[str, ...]
    coef: NDArray[np.float64]
    intercept: NDArray[np.float64]

    def project(self, embeddings: ArrayLike) -> NDArray[np.float64]:
        """(N, D) embeddings -> (N, L) predicted normal scores of the labels."""
        x = np.asarray(embeddings, dtype=np.float64)
        return np.asarray(x @ self.coef + self.intercept, dtype=np.float64)

    def restrict(self, columns: Sequence[str]) -> LabelSpace:
        """The map onto ``columns`` only (each must be one of this map's), in that order."""
        idx = [self.columns.index(c) for c in columns]
        return LabelSpace(tuple(columns), self.coef[:, idx], self.intercept[idx])


def fit_label_space(
    embeddings: ArrayLike,
    fabric_ids: ArrayLike,
    labels: Mapping[int, Sequence[float]],
    columns: Sequence[str],
) -> LabelSpace:
    """Fit the map of one modality on its training items.

    Args:
        embeddings: (N, D) embeddings of the training items.
        fabric_ids: (N,) their fabrics.
        labels: fabric id -> label values in ``columns`` order (NaN: unknown).
        columns: the label columns' names.

    Returns:
        The `LabelSpace` of the columns at least `MIN_FABRICS` training fabrics have (and that
        vary among them).

    Raises:
        ValueError: embeddings and fabric ids of different lengths, or no column to map.
    """
    x = np.asarray(embeddings, dtype=np.float64)
    f = np.asarray(fabric_ids).reshape(-1)
    if x.ndim != 2 or len(x) != len(f):
        raise ValueError(f"embeddings {x.shape} do not match {len(f)} fabric ids")
    y = np.array(
        [labels.get(int(i), [np.nan] * len(columns)) for i in f], dtype=np.float64
    ).reshape(len(f), len(columns))
    xf, yf, _ = per_fabric_means(x, y, f)
    kept, coefs, intercepts = [], [], []
    for j, name in enumerate(columns):
        known = ~np.isnan(yf[:, j])
        if known.sum() < MIN_FABRICS or np.ptp(yf[known, j]) == 0:
            continue
        coef, intercept = fit_ridge(xf[known], normal_scores(yf[known, j]))
        kept.append(name)
        coefs.append(coef)
        intercepts.append(intercept)
    if not kept:
        raise ValueError(
            f"no label column has {MIN_FABRICS} or more training fabrics with varying values"
        )
    return LabelSpace(tuple(kept), np.stack(coefs, axis=1), np.asarray(intercepts))


def fit_label_spaces(
    training: Mapping[Any, tuple[ArrayLike, ArrayLike]],
    labels: Mapping[int, Sequence[float]],
    columns: Sequence[str],
) -> dict[Any, LabelSpace]:
    """`fit_label_space` for several modalities, kept to the columns all of them map, so that
    any two can be compared.

    Args:
        training: per modality, its training items' ``(embeddings, fabric_ids)``.
        labels, columns: as `fit_label_space`.

    Returns:
        Per modality its map, every one onto the same columns (a modality with no column to
        map is left out); empty when they share none.
    """
    spaces = {}
    for key, (emb, fab) in training.items():
        try:
            spaces[key] = fit_label_space(emb, fab, labels, columns)
        except ValueError:  # no column enough of its training fabrics have: left out
            continue
    common = [c for c in columns if all(c in s.columns for s in spaces.values())]
    if not common:
        return {}
    return {key: s.restrict(common) for key, s in spaces.items()}
