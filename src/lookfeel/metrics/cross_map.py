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

A map carries *hubs*: some gallery items land near every query (a "hub", as nearest
neighbours in high dimensions are known to form) and would be picked for queries of any
fabric. Each gallery item's distance is lowered by its own crowding,

    d'(q, g) = d(q, g) - r(g),   r(g) = mean of d(h, g) over the k training fabrics h
                                        (query modality, fabric means) nearest to g,

the gallery side of CSLS (cross-domain similarity local scaling; Conneau, Lample, Ranzato,
Denoyer & Jegou, "Word translation without parallel data", ICLR 2018), made inductive: the
neighbourhood is the training fabrics, never the other queries, so a query's distance to an
item depends on those two alone, whatever else the gallery holds. A constant of the map (the
largest r among the training fabrics) is added back, and the rare result below 0 clipped, so
that distances stay non-negative; the order of a query's gallery items is what it changes.
``hub_neighbours=0`` turns it off (the map as fitted before session 22).

Used by `lookfeel cv` (the ``model_mapped`` rows) beside matching in the embedding itself and
in label space, by `lookfeel evaluate` (the ``*_mapped`` keys) and by a fabric library
(`lookfeel.index`), which matches a pair through its map when that does better in calibration.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lookfeel.metrics.distances import pairwise_distances
from lookfeel.metrics.properties import fit_ridge_multi
from lookfeel.modality import Modality, Pair

__all__ = [
    "HUB_NEIGHBOURS",
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

HUB_NEIGHBOURS = 10
"""Training fabrics a gallery item's crowding is measured over (`CrossMap.hubs`). Chosen on
folds 0-1 of the seed-5 synthetic world (5, 10 and 20 tried), confirmed on folds 2-4."""


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
        hubs: (K, D_q) the training fabrics' mean query embeddings against which a gallery
            item's crowding is measured (module doc), or ``None``: no hub correction.
        hub_neighbours: how many of ``hubs`` nearest a gallery item its crowding averages.
        hub_offset: added to every hub-corrected distance (the training fabrics' largest
            crowding), so that distances stay non-negative.
    """

    forward: LinearMap
    backward: LinearMap
    scale_forward: float
    scale_backward: float
    hubs: F64 | None = None
    hub_neighbours: int = HUB_NEIGHBOURS
    hub_offset: float = 0.0

    def to_arrays(self) -> dict[str, F64]:
        """Plain arrays (for an ``.npz``); `from_arrays` reads them back exactly."""
        out = {
            "forward_coef": self.forward.coef,
            "forward_intercept": self.forward.intercept,
            "backward_coef": self.backward.coef,
            "backward_intercept": self.backward.intercept,
            "scales": np.array([self.scale_forward, self.scale_backward]),
        }
        if self.hubs is not None:
            out["hubs"] = self.hubs
            out["hub_settings"] = np.array([self.hub_neighbours, self.hub_offset])
        return out

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, ArrayLike]) -> CrossMap:
        """The map `to_arrays` wrote (without ``hubs``, as written before session 22: no hub
        correction).

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
        hubs, k, offset = None, HUB_NEIGHBOURS, 0.0
        if "hubs" in arrays:
            hubs = np.asarray(arrays["hubs"], dtype=np.float64)
            settings = np.asarray(arrays["hub_settings"], dtype=np.float64).reshape(-1)
            if (
                hubs.ndim != 2
                or hubs.shape[1] != fc.shape[0]
                or len(hubs) == 0
                or not np.isfinite(hubs).all()
                or settings.shape != (2,)
                or not np.isfinite(settings).all()
                or not settings[0] >= 1
                or settings[0] != int(settings[0])
            ):
                raise ValueError(
                    f"cross-modal map hubs {hubs.shape} / hub_settings {settings.tolist()} do "
                    f"not fit a map from {fc.shape[0]} dimensions"
                )
            k, offset = int(settings[0]), float(settings[1])
        return cls(
            LinearMap(fc, a["forward_intercept"]),
            LinearMap(bc, a["backward_intercept"]),
            float(a["scales"][0]),
            float(a["scales"][1]),
            hubs,
            k,
            offset,
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
        shift = None
        if self.hubs is not None:
            shift = self.hub_offset - self._crowding(self._routes(self.hubs, g, g_back))

        def distances(query: ArrayLike) -> F64:
            d = self._routes(np.asarray(query, dtype=np.float64), g, g_back)
            return d if shift is None else np.maximum(d + shift, 0.0)

        return distances

    def crowding(self, gallery: ArrayLike) -> F64:
        """(G,) each gallery item's crowding r(g): the mean two-route distance of its
        ``hub_neighbours`` nearest ``hubs`` (module doc). Requires hubs."""
        if self.hubs is None:
            raise ValueError("this cross-modal map has no hubs")
        g = np.asarray(gallery, dtype=np.float64)
        return self._crowding(self._routes(self.hubs, g, self.backward(g)))

    def _routes(self, q: F64, g: F64, g_back: F64) -> F64:
        """(Q, G) two-route distances, each route in its unit; ``g_back`` is ``backward(g)``."""
        there = pairwise_distances(self.forward(q), g) / self.scale_forward
        back = pairwise_distances(q, g_back) / self.scale_backward
        return np.asarray(there + back, dtype=np.float64)

    def _crowding(self, to_hubs: F64) -> F64:
        """(G,) the mean of each column's ``hub_neighbours`` smallest (K, G) distances."""
        if to_hubs.shape[1] == 0:
            return np.zeros(0)
        k = min(self.hub_neighbours, len(to_hubs))
        return np.asarray(np.partition(to_hubs, k - 1, axis=0)[:k].mean(axis=0), np.float64)


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
    *,
    hub_neighbours: int = HUB_NEIGHBOURS,
) -> CrossMap:
    """Fit the maps between two modalities on their training items (module doc).

    Args:
        query_embeddings, query_fabrics: (N_q, D_q) training items of the query modality and
            their fabrics.
        gallery_embeddings, gallery_fabrics: the same for the gallery modality.
        hub_neighbours: training fabrics a gallery item's crowding is measured over (module
            doc); 0: no hub correction.

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
    if hub_neighbours < 0:
        raise ValueError(f"hub_neighbours must be >= 0; got {hub_neighbours}")
    mq, mg = _fabric_means(xq, fq, ids), _fabric_means(xg, fg, ids)
    forward, backward = fit_linear_map(mq, mg), fit_linear_map(mg, mq)
    plain = CrossMap(
        forward, backward, _mean_distance(forward(mq), mg), _mean_distance(mq, backward(mg))
    )
    if not hub_neighbours:
        return plain
    hubbed = replace(plain, hubs=mq, hub_neighbours=hub_neighbours)
    return replace(hubbed, hub_offset=float(hubbed.crowding(mg).max()))


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
