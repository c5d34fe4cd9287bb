"""Distances between embeddings, safe to differentiate where two embeddings coincide.

The Euclidean norm has no derivative at 0, and ``sqrt`` of an exact 0 back-propagates NaN; the
paper's positive pairs aim for exactly that point. `euclidean_distance` returns 0 with a zero
gradient there instead (the "double where" trick: the square root only ever sees positives).
"""

from __future__ import annotations

import torch
from torch import Tensor

__all__ = [
    "euclidean_distance",
    "mean_squared_distance",
    "pairwise_euclidean",
    "pairwise_mean_squared",
]


def _safe_sqrt(sq: Tensor) -> Tensor:
    """``sqrt(sq)`` for ``sq >= 0`` with a zero (not NaN) gradient at 0."""
    pos = sq > 0
    return torch.where(pos, torch.where(pos, sq, torch.ones_like(sq)).sqrt(), torch.zeros_like(sq))


def euclidean_distance(a: Tensor, b: Tensor) -> Tensor:
    """``||a - b||`` row by row (the paper's D, section 4).

    Args:
        a: (..., D).
        b: (..., D), broadcastable with ``a``.

    Returns:
        (...) distances; gradient 0 where ``a == b``.
    """
    return _safe_sqrt((a - b).pow(2).sum(dim=-1))


def mean_squared_distance(a: Tensor, b: Tensor) -> Tensor:
    """The mean over dimensions of ``(a - b) ** 2`` (the authors' released code).

    Args:
        a: (..., D).
        b: (..., D), broadcastable with ``a``.

    Returns:
        (...) distances.
    """
    return (a - b).pow(2).mean(dim=-1)


def _pairwise_sq(a: Tensor, b: Tensor) -> Tensor:
    """Squared Euclidean distances of every row of ``a`` to every row of ``b``: (N, M)."""
    # The expansion |a|^2 + |b|^2 - 2ab needs no (N, M, D) intermediate; rounding can make it
    # slightly negative, hence the clamp.
    sq = a.pow(2).sum(-1)[:, None] + b.pow(2).sum(-1)[None, :] - 2.0 * a @ b.T
    return sq.clamp_min(0.0)


def pairwise_euclidean(a: Tensor, b: Tensor) -> Tensor:
    """Euclidean distance of every row of ``a`` to every row of ``b``.

    Args:
        a: (N, D).
        b: (M, D).

    Returns:
        (N, M) distances; gradient 0 where two rows coincide.
    """
    return _safe_sqrt(_pairwise_sq(a, b))


def pairwise_mean_squared(a: Tensor, b: Tensor) -> Tensor:
    """`mean_squared_distance` of every row of ``a`` to every row of ``b``.

    Args:
        a: (N, D).
        b: (M, D).

    Returns:
        (N, M) distances.
    """
    return _pairwise_sq(a, b) / a.shape[-1]
