"""Multi-press touch queries: pool several presses of one fabric into one query (section 4.1).

The Multi-input Net embeds 3 GelSight presses with one branch and takes their element-wise
maximum as the touch embedding; evaluating it needs query groups of P presses of one fabric.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["PressGroups", "group_members", "group_queries", "max_pool_groups"]


class PressGroups(NamedTuple):
    """Pooled multi-press queries."""

    emb: NDArray[np.float64]
    """(M, D) element-wise max over each group's presses."""
    fabric: NDArray[np.generic]
    """(M,) fabric id of each group."""
    members: NDArray[np.int64]
    """(M, P) row indices (into the input) of each group's presses."""


def group_members(fabric: ArrayLike, presses: int = 3, seed: int = 0) -> NDArray[np.int64]:
    """Split each fabric's presses into disjoint random groups of P, without pooling them.

    A fabric's presses are shuffled (seeded) and cut into ``count // P`` groups; the
    ``count % P`` left over are dropped, and a fabric with fewer than P presses gives none.

    Args:
        fabric: (N,) fabric id of each press.
        presses: P, presses per query (the paper's Multi-input Net uses 3).
        seed: seeds the shuffle.

    Returns:
        (M, P) row indices (into ``fabric``) of each group's presses, fabric by fabric in
        increasing id.
    """
    if presses < 1:
        raise ValueError(f"presses must be >= 1; got {presses}")
    f = np.asarray(fabric).reshape(-1)
    rng = np.random.default_rng(seed)
    groups: list[NDArray[np.int64]] = []
    for fab in np.unique(f):
        rows = rng.permutation(np.flatnonzero(f == fab))
        usable = len(rows) - len(rows) % presses
        if usable:
            groups.append(rows[:usable].reshape(-1, presses))
    return np.concatenate(groups) if groups else np.zeros((0, presses), dtype=np.int64)


def max_pool_groups(emb: ArrayLike, members: NDArray[np.int64]) -> NDArray[np.float64]:
    """Element-wise max of each group's embeddings: the Multi-input Net's pooling (section
    4.1), the one place it is computed at evaluation (`group_queries`,
    `lookfeel.evaluate.max_pool_presses`).

    Args:
        emb: (N, D) per-press embeddings.
        members: (M, P) rows of each group (`group_members`).

    Returns:
        (M, D) float64: ``emb[members].max(axis=1)  # (M, P, D) -> (M, D)``.
    """
    e = np.asarray(emb, dtype=np.float64)
    if len(members) == 0:
        return np.zeros((0, e.shape[1]))
    return np.asarray(e[members].max(axis=1), dtype=np.float64)


def group_queries(
    emb: ArrayLike, fabric: ArrayLike, presses: int = 3, seed: int = 0
) -> PressGroups:
    """Split each fabric's presses into disjoint random groups of P (`group_members`) and
    max-pool each group (`max_pool_groups`).

    Args:
        emb: (N, D) per-press embeddings.
        fabric: (N,) fabric id of each press.
        presses: P, presses per query (the paper's Multi-input Net uses 3).
        seed: seeds the shuffle.

    Returns:
        `PressGroups`: ``e = emb[members].max(axis=1)  # (M, P, D) -> (M, D)``.
    """
    e = np.asarray(emb, dtype=np.float64)
    f = np.asarray(fabric).reshape(-1)
    if e.ndim != 2 or len(e) != len(f):
        raise ValueError(f"emb must be (N, D) with N = len(fabric); got {e.shape}, {len(f)}")
    members = group_members(f, presses, seed)
    return PressGroups(
        max_pool_groups(e, members), f[members[:, 0]] if len(members) else f[:0], members
    )
