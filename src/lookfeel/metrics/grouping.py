"""Multi-press touch queries: pool several presses of one fabric into one query (section 4.1).

The Multi-input Net embeds 3 GelSight presses with one branch and takes their element-wise
maximum as the touch embedding; evaluating it needs query groups of P presses of one fabric.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["PressGroups", "group_queries"]


class PressGroups(NamedTuple):
    """Pooled multi-press queries."""

    emb: NDArray[np.float64]
    """(M, D) element-wise max over each group's presses."""
    fabric: NDArray[np.generic]
    """(M,) fabric id of each group."""
    members: NDArray[np.int64]
    """(M, P) row indices (into the input) of each group's presses."""


def group_queries(
    emb: ArrayLike, fabric: ArrayLike, presses: int = 3, seed: int = 0
) -> PressGroups:
    """Split each fabric's presses into disjoint random groups of P and max-pool each group.

    A fabric's presses are shuffled (seeded) and cut into ``count // P`` groups; the
    ``count % P`` left over are dropped, and a fabric with fewer than P presses gives none.

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
    if presses < 1:
        raise ValueError(f"presses must be >= 1; got {presses}")
    rng = np.random.default_rng(seed)
    groups: list[NDArray[np.int64]] = []
    for fab in np.unique(f):
        rows = rng.permutation(np.flatnonzero(f == fab))
        usable = len(rows) - len(rows) % presses
        if usable:
            groups.append(rows[:usable].reshape(-1, presses))
    members = np.concatenate(groups) if groups else np.zeros((0, presses), dtype=np.int64)
    pooled = e[members].max(axis=1) if len(members) else np.zeros((0, e.shape[1]))
    return PressGroups(pooled, f[members[:, 0]] if len(members) else f[:0], members)
