"""Nearest-neighbour search over one modality's library embeddings: exact (numpy) or faiss.

Both backends answer the same question, the k gallery rows nearest to each query in Euclidean
distance (the paper's D), sorted nearest first. `ExactSearch` computes every distance (one
matrix-vector product; a 10,000 x 128 gallery takes well under a millisecond), so match
probabilities are normalised over the whole gallery exactly. `FaissSearch` is an HNSW graph
(faiss ``IndexHNSWFlat``): sub-linear search for libraries of hundreds of thousands of items,
approximate, and probabilities are then normalised over the k rows it returns (the rest hold a
negligible ``exp(-c D^2)`` share when k is large; `lookfeel.index.match` asks for 2,048).
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "AUTO_FAISS_MIN_ROWS",
    "BACKENDS",
    "ExactSearch",
    "FaissSearch",
    "Search",
    "choose_backend",
]

BACKENDS = ("auto", "numpy", "faiss")
"""Search backends a library can be built with; ``auto`` chooses by size."""

AUTO_FAISS_MIN_ROWS = 100_000
"""``auto`` uses faiss when a modality has at least this many items, else exact numpy search.
Below it exact search is fast enough (~1 ms per 10,000 items at D = 128 on 2 cores) and never
misses a neighbour."""


def choose_backend(backend: str, rows: int) -> str:
    """Resolve ``auto`` to ``numpy`` or ``faiss`` by the largest modality's row count.

    Raises:
        ValueError: naming the backend when it is not one of `BACKENDS`.
    """
    if backend not in BACKENDS:
        raise ValueError(f"search backend {backend!r} is not one of {', '.join(BACKENDS)}")
    if backend != "auto":
        return backend
    return "faiss" if rows >= AUTO_FAISS_MIN_ROWS else "numpy"


class Search(Protocol):
    """What `lookfeel.index.match` needs of a backend."""

    name: str
    exact: bool

    def __len__(self) -> int: ...

    def search(
        self, query: NDArray[np.floating], k: int
    ) -> tuple[NDArray[np.float64], NDArray[np.int64]]: ...


class ExactSearch:
    """Exact Euclidean search by brute force, in float64.

    Args:
        gallery: (G, D) embeddings.
    """

    name = "numpy"
    exact = True

    def __init__(self, gallery: NDArray[np.floating]) -> None:
        self._g = np.ascontiguousarray(gallery, dtype=np.float64)
        self._sq = np.einsum("ij,ij->i", self._g, self._g)  # (G,)

    def __len__(self) -> int:
        return len(self._g)

    def distances(self, query: NDArray[np.floating]) -> NDArray[np.float64]:
        """(Q, D) -> (Q, G) distances to every gallery row (``|q|^2 + |g|^2 - 2 q.g``)."""
        q = np.atleast_2d(np.asarray(query, dtype=np.float64))
        # (Q, D) @ (D, G) -> (Q, G). One query (a server's case) is a matrix-vector product in
        # numpy's own single-threaded loop: OpenBLAS would spread a one-row product over threads
        # that, on a busy machine, cost 10-100x more than they save (0.4 ms at G = 10,000).
        d2 = np.einsum("gd,d->g", self._g, q[0])[None, :] if len(q) == 1 else q @ self._g.T
        d2 *= -2.0
        d2 += self._sq[None, :]
        d2 += np.einsum("ij,ij->i", q, q)[:, None]
        np.maximum(d2, 0.0, out=d2)
        return np.sqrt(d2, out=d2)

    def search(
        self, query: NDArray[np.floating], k: int
    ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """The k nearest rows of each query.

        Returns:
            (distances (Q, k), row indices (Q, k)), nearest first; k is capped at G.
        """
        d = self.distances(query)
        k = min(k, d.shape[1])
        if k < d.shape[1]:
            idx = np.argpartition(d, k - 1, axis=1)[:, :k]
        else:
            idx = np.broadcast_to(np.arange(d.shape[1]), d.shape)
        part = np.take_along_axis(d, idx, axis=1)
        order = np.argsort(part, axis=1, kind="stable")
        return np.take_along_axis(part, order, axis=1), np.take_along_axis(idx, order, axis=1)


class FaissSearch:
    """Approximate search with a faiss HNSW graph (``IndexHNSWFlat``, L2).

    Args:
        index: a built faiss index; use `FaissSearch.build` or `FaissSearch.from_bytes`.
        ef_search: candidates the graph search keeps (recall against speed).
    """

    name = "faiss"
    exact = False

    def __init__(self, index: Any, ef_search: int = 256) -> None:
        self._index = index
        self._index.hnsw.efSearch = ef_search

    def __len__(self) -> int:
        return int(self._index.ntotal)

    @classmethod
    def build(
        cls, gallery: NDArray[np.floating], m: int = 32, ef_construction: int = 80
    ) -> FaissSearch:
        """Build an HNSW index over (G, D) embeddings (M links per node)."""
        import faiss

        g = np.ascontiguousarray(gallery, dtype=np.float32)
        index = faiss.IndexHNSWFlat(g.shape[1], m)
        index.hnsw.efConstruction = ef_construction
        index.add(g)
        return cls(index)

    def to_bytes(self) -> bytes:
        """The index serialised (faiss's own format)."""
        import faiss

        return bytes(faiss.serialize_index(self._index))

    @classmethod
    def from_bytes(cls, data: bytes) -> FaissSearch:
        """Read an index written by `to_bytes`."""
        import faiss

        return cls(faiss.deserialize_index(np.frombuffer(data, dtype=np.uint8)))

    def search(
        self, query: NDArray[np.floating], k: int
    ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """The (approximately) k nearest rows of each query; see `ExactSearch.search`."""
        q = np.ascontiguousarray(np.atleast_2d(query), dtype=np.float32)
        k = min(k, len(self))
        d2, idx = self._index.search(q, k)
        # HNSW may return fewer than k rows (trailing -1); keep the columns every query filled.
        n = int((idx >= 0).all(axis=0).sum())
        d = np.sqrt(np.maximum(d2[:, :n], 0.0)).astype(np.float64)
        return d, idx[:, :n].astype(np.int64)
