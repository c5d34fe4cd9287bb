"""Matching through a cross-modal map: one modality's embeddings carried into the other's.

Two branches trained together seldom put a fabric's press and its drape at the same point, yet
each embedding knows much of the fabric's physics (`lookfeel.metrics.label_space` reads it
back through the labels). A linear map from one modality's embedding space onto the other's,
fitted on the training fabrics, uses that knowledge without any label: the fabrics themselves
pair the two spaces. `fit_cross_map` fits it both ways on the training fabrics' mean
embeddings (a multi-output ridge per direction, its penalty chosen by leave-one-out over
fabrics), and `CrossMap.distances` scores a query against a gallery by both routes:

    d(q, g) = |F(q) - g| / s_F + |q - B(g)| / s_B

with ``F`` the query-to-gallery map, ``B`` the reverse, and each route's distance in units of
its mean over pairs of training fabrics (``s_F``, ``s_B``), so that neither route outweighs
the other by scale alone. Nothing is fitted on the fabrics being scored.

Used by `lookfeel cv` (the ``model_mapped`` rows) beside matching in the embedding itself and
in label space.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lookfeel.metrics.distances import pairwise_distances
from lookfeel.metrics.properties import fit_ridge_multi

__all__ = ["MIN_FABRICS", "CrossMap", "LinearMap", "fit_cross_map", "fit_linear_map"]

F64 = NDArray[np.float64]

MIN_FABRICS = 3
"""A map is fitted only when both modalities have at least this many training fabrics."""


@dataclass(frozen=True)
class LinearMap:
    """``x @ coef + intercept``: (N, D_in) -> (N, D_out)."""

    coef: F64
    intercept: F64

    def __call__(self, x: ArrayLike) -> F64:
        return np.asarray(np.asarray(x, dtype=np.float64) @ self.coef + self.intercept)


def fit_linear_map(x: ArrayLike, y: ArrayLike) -> LinearMap:
    """Multi-output ridge regression of ``y`` (N, D_out) on ``x`` (N, D_in), one penalty for
    all outputs chosen by efficient leave-one-out
    (`lookfeel.metrics.properties.fit_ridge_multi`)."""
    coef, intercept = fit_ridge_multi(
        np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    )
    return LinearMap(coef, intercept)


@dataclass(frozen=True)
class CrossMap:
    """The two maps between a query modality's embeddings and a gallery modality's.

    Attributes:
        forward: query space -> gallery space.
        backward: gallery space -> query space.
        scale_forward, scale_backward: each route's mean distance over pairs of training
            fabrics (the unit of `distances`).
    """

    forward: LinearMap
    backward: LinearMap
    scale_forward: float
    scale_backward: float

    def distances(self, query: ArrayLike, gallery: ArrayLike) -> F64:
        """(Q, G) distances between query and gallery embeddings by both routes (module
        doc); non-negative, as the pick metrics need."""
        q = np.asarray(query, dtype=np.float64)
        g = np.asarray(gallery, dtype=np.float64)
        there = pairwise_distances(self.forward(q), g) / self.scale_forward
        back = pairwise_distances(q, self.backward(g)) / self.scale_backward
        return np.asarray(there + back, dtype=np.float64)


def _fabric_means(x: F64, fabric: NDArray[np.int64], ids: NDArray[np.int64]) -> F64:
    return np.stack([x[fabric == i].mean(axis=0) for i in ids])


def _mean_distance(a: F64, b: F64) -> float:
    d = float(pairwise_distances(a, b).mean())
    return d if d > 0 else 1.0


def fit_cross_map(
    query_embeddings: ArrayLike,
    query_fabrics: ArrayLike,
    gallery_embeddings: ArrayLike,
    gallery_fabrics: ArrayLike,
) -> CrossMap:
    """Fit the maps between two modalities on their training items (module doc).

    Args:
        query_embeddings, query_fabrics: (N_q, D_q) training items of the query modality and
            their fabrics.
        gallery_embeddings, gallery_fabrics: the same for the gallery modality.

    Returns:
        A `CrossMap`, fitted on the mean embedding of every fabric both modalities have.

    Raises:
        ValueError: embeddings and fabric ids of different lengths, or fewer than
            `MIN_FABRICS` fabrics in common.
    """
    xq = np.asarray(query_embeddings, dtype=np.float64)
    xg = np.asarray(gallery_embeddings, dtype=np.float64)
    fq = np.asarray(query_fabrics).reshape(-1)
    fg = np.asarray(gallery_fabrics).reshape(-1)
    for name, x, f in (("query", xq, fq), ("gallery", xg, fg)):
        if x.ndim != 2 or len(x) != len(f):
            raise ValueError(f"{name} embeddings {x.shape} do not match {len(f)} fabric ids")
    ids = np.intersect1d(fq, fg)
    if len(ids) < MIN_FABRICS:
        raise ValueError(
            f"a cross-modal map needs {MIN_FABRICS} or more training fabrics both modalities "
            f"have; got {len(ids)}"
        )
    mq, mg = _fabric_means(xq, fq, ids), _fabric_means(xg, fg, ids)
    forward, backward = fit_linear_map(mq, mg), fit_linear_map(mg, mq)
    return CrossMap(
        forward,
        backward,
        _mean_distance(forward(mq), mg),
        _mean_distance(mq, backward(mg)),
    )
