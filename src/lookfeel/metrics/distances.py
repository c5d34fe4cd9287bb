"""Euclidean distances between query and gallery embeddings (section 4: ``D = ||E1 - E2||``)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["pairwise_distances"]


def pairwise_distances(query_emb: ArrayLike, gallery_emb: ArrayLike) -> NDArray[np.float64]:
    """Euclidean distance from every query embedding to every gallery embedding.

    Uses the matrix-product form ``|q|^2 + |g|^2 - 2 q.g`` in float64 (one BLAS call), clipped
    at 0 before the square root so rounding never yields NaN.

    Args:
        query_emb: (Q, D) query embeddings.
        gallery_emb: (G, D) gallery embeddings.

    Returns:
        (Q, G) float64 distances.

    Raises:
        ValueError: if the inputs are not 2-D, disagree in D, or hold NaN or infinity.
    """
    q = np.asarray(query_emb, dtype=np.float64)
    g = np.asarray(gallery_emb, dtype=np.float64)
    if q.ndim != 2 or g.ndim != 2:
        raise ValueError(f"embeddings must be 2-D (N, D); got {q.shape} and {g.shape}")
    if q.shape[1] != g.shape[1]:
        raise ValueError(f"embedding sizes differ: query D={q.shape[1]}, gallery D={g.shape[1]}")
    if not (np.isfinite(q).all() and np.isfinite(g).all()):
        raise ValueError("embeddings hold NaN or infinity")
    sq = q @ g.T  # (Q, D) @ (D, G) -> (Q, G)
    sq *= -2.0
    sq += np.einsum("ij,ij->i", q, q)[:, None]
    sq += np.einsum("ij,ij->i", g, g)[None, :]
    np.maximum(sq, 0.0, out=sq)
    return np.sqrt(sq, out=sq)
