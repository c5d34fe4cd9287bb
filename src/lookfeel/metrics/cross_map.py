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
in label space, by `lookfeel evaluate` (the ``*_mapped`` keys) and by a fabric library
(`lookfeel.index`), which matches a pair through its map when that does better in calibration.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lookfeel.metrics.distances import pairwise_distances
from lookfeel.metrics.properties import fit_ridge_multi
from lookfeel.modality import Modality, Pair

__all__ = [
    "MIN_FABRICS",
    "CrossMap",
    "LinearMap",
    "fit_cross_map",
    "fit_cross_maps",
    "fit_linear_map",
]

F64 = NDArray[np.float64]

_ARRAYS = ("forward_coef", "forward_intercept", "backward_coef", "backward_intercept", "scales")
"""What `CrossMap.to_arrays` writes."""

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

    def to_arrays(self) -> dict[str, F64]:
        """Plain arrays (for an ``.npz``); `from_arrays` reads them back exactly."""
        return {
            "forward_coef": self.forward.coef,
            "forward_intercept": self.forward.intercept,
            "backward_coef": self.backward.coef,
            "backward_intercept": self.backward.intercept,
            "scales": np.array([self.scale_forward, self.scale_backward]),
        }

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, ArrayLike]) -> CrossMap:
        """The map `to_arrays` wrote.

        Raises:
            KeyError: an array is missing; ValueError: their shapes do not fit together.
        """
        a = {k: np.asarray(arrays[k], dtype=np.float64) for k in _ARRAYS}
        fc, bc = a["forward_coef"], a["backward_coef"]
        if (
            fc.ndim != 2
            or bc.shape != fc.shape[::-1]
            or a["forward_intercept"].shape != (fc.shape[1],)
            or a["backward_intercept"].shape != (fc.shape[0],)
            or a["scales"].shape != (2,)
            or not all(np.isfinite(v).all() for v in a.values())
            or not (a["scales"] > 0).all()
        ):
            raise ValueError(
                "cross-modal map arrays do not fit together: "
                + ", ".join(f"{k} {v.shape}" for k, v in a.items())
            )
        return cls(
            LinearMap(fc, a["forward_intercept"]),
            LinearMap(bc, a["backward_intercept"]),
            float(a["scales"][0]),
            float(a["scales"][1]),
        )

    def distances(self, query: ArrayLike, gallery: ArrayLike) -> F64:
        """(Q, G) distances between query and gallery embeddings by both routes (module
        doc); non-negative, as the pick metrics need."""
        return self.against(gallery)(query)

    def against(self, gallery: ArrayLike) -> Callable[[ArrayLike], F64]:
        """``distances`` to a fixed gallery, its reverse map computed once (a library answers
        many queries against the same items)."""
        g = np.asarray(gallery, dtype=np.float64)
        g_back = self.backward(g)

        def distances(query: ArrayLike) -> F64:
            q = np.asarray(query, dtype=np.float64)
            there = pairwise_distances(self.forward(q), g) / self.scale_forward
            back = pairwise_distances(q, g_back) / self.scale_backward
            return np.asarray(there + back, dtype=np.float64)

        return distances


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


def fit_cross_maps(
    items: Mapping[Modality, tuple[ArrayLike, ArrayLike]], pairs: Iterable[Pair]
) -> dict[Pair, CrossMap]:
    """The cross-modal map of every pair of two modalities in ``pairs`` that ``items`` holds
    with `MIN_FABRICS` or more fabrics in common (the others are left out).

    Args:
        items: modality -> ((N, D) embeddings, (N,) fabric ids) of the fabrics to fit on.
        pairs: the pairs wanted; same-modality pairs are skipped.
    """
    maps = {}
    for p in pairs:
        if p.same or p.query not in items or p.gallery not in items:
            continue
        (eq, fq), (eg, fg) = items[p.query], items[p.gallery]
        try:
            maps[p] = fit_cross_map(eq, fq, eg, fg)
        except ValueError:  # too few fabrics in common
            continue
    return maps
