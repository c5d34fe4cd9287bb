"""Pick k of n (paper section 5.1): does the query's true fabric rank first among n candidates?

The candidates are one gallery item of the query's fabric (the true candidate t) and one item
each of ``n - 1`` other fabrics drawn at random. The paper samples this (15 queries per fabric,
10 draws each); `pick_k_of_n_exact` computes the expectation over the draw exactly from the
full distance matrix, and `pick_k_of_n_sampled` reproduces the sampled protocol.

Exact expectation. Draw one item from every other fabric (the chosen m = n - 1 fabrics are a
uniform subset, independent of the items), so fabric f beats t independently with probability
``p_f`` = (its items closer than t) / (its items). The number of chosen fabrics beating t
averaged over uniform m-subsets of the F' other fabrics is
``P(N = j) = [s^j] e_m(1 - p + s p) / C(F', m)
           = sum_{i>=j} (-1)^(i-j) C(i, j) C(F' - i, m - i) e_i(p) / C(F', m)``,
with ``e_i`` the elementary symmetric polynomials of the p's (a dynamic program over fabrics);
``P(rank <= k) = P(N < k)``. This is averaged over t (uniform over the query's fabric) and
reported per query. Ties are broken uniformly at random (see ``_ranking``), exactly.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lookfeel.metrics._ranking import Prepared, prepare, quantize, scan, tie_bits

__all__ = [
    "PickResult",
    "SampledPickResult",
    "n_effective",
    "pick_k_of_n_exact",
    "pick_k_of_n_sampled",
    "pick_result_from",
    "sampled_from",
    "warn_if_short",
]


@dataclass(frozen=True)
class PickResult:
    """Exact pick-k-of-n: per-query expectations and their mean."""

    ks: tuple[int, ...]
    per_query: NDArray[np.float64]
    """(Q, K) P(true candidate ranks within k); NaN for queries with no true item."""
    mean: NDArray[np.float64]
    """(K,) mean over the queries that have a true item (with equal queries per fabric, the
    expectation of the paper's 15-queries-per-fabric average)."""
    chance: NDArray[np.float64]
    """(K,) the same for random embeddings: ``min(k, n_effective) / n_effective``."""
    n_effective: int
    """Candidates actually offered: ``min(n, gallery fabrics)``."""
    n_queries: int
    """Queries that have a true item (the rest are NaN and left out of the mean)."""


@dataclass(frozen=True)
class SampledPickResult:
    """Sampled pick-k-of-n (the paper's protocol): means over trials and standard errors."""

    ks: tuple[int, ...]
    mean: NDArray[np.float64]
    """(K,) fraction of trials where the true candidate ranked within k."""
    se: NDArray[np.float64]
    """(K,) standard error: std of the per-query means over sqrt(queries) (ddof 1)."""
    chance: NDArray[np.float64]
    """(K,) ``min(k, n_effective) / n_effective`` (approximate with allow_true_distractor)."""
    n_effective: int
    n_queries: int
    n_trials: int


def n_effective(n: int, n_gallery_fabrics: int, *, allow_true_distractor: bool = False) -> int:
    """Candidates in a draw: ``n``, or fewer when the gallery has too few fabrics to fill it."""
    if n < 1:
        raise ValueError(f"n must be >= 1; got {n}")
    others = n_gallery_fabrics if allow_true_distractor else n_gallery_fabrics - 1
    return 1 + min(n - 1, max(others, 0))


def _check_ks(ks: tuple[int, ...] | list[int]) -> tuple[int, ...]:
    out = tuple(int(k) for k in ks)
    if not out or min(out) < 1:
        raise ValueError(f"ks must be positive integers; got {ks!r}")
    return out


def warn_if_short(n: int, n_eff: int, n_fabrics: int) -> None:
    if n_eff < n:
        warnings.warn(
            f"pick {n}: the gallery has only {n_fabrics} fabrics, so each draw offers "
            f"{n_eff} candidates (n_effective={n_eff}, chance top-1 = 1/{n_eff})",
            UserWarning,
            stacklevel=3,
        )


def _chance(ks: tuple[int, ...], n_eff: int) -> NDArray[np.float64]:
    return np.array([min(k, n_eff) / n_eff for k in ks])


def pick_k_of_n_exact(
    dist: ArrayLike,
    query_fabric: ArrayLike,
    gallery_fabric: ArrayLike,
    n: int = 10,
    ks: tuple[int, ...] = (1, 3),
    exclude_self: ArrayLike | None = None,
) -> PickResult:
    """Exact expected top-k accuracy of the paper's pick-1-of-n experiment (section 5.1).

    No sampling: the expectation over the true item, the ``n - 1`` distractor fabrics and
    their items (and over random tie-breaks) is computed from the whole distance matrix (see
    the module docstring). O(Q G log G) for the sort plus O(Q G m) for the recursion.

    Args:
        dist: (Q, G) distances from each query to each gallery item.
        query_fabric: (Q,) fabric id of each query.
        gallery_fabric: (G,) fabric id of each gallery item.
        n: candidates per draw (the paper's 10); with fewer gallery fabrics, all of them are
            used and a warning says so (``n_effective``).
        ks: report P(true candidate ranks within k) for each k (the paper's top 1 and top 3).
        exclude_self: for same-modality pairs, the (Q,) gallery index of each query's own item
            (or a (Q, G) mask): never a true candidate.

    Returns:
        `PickResult` with (Q, K) per-query values and their mean.
    """
    ks = _check_ks(ks)
    prep = prepare(dist, query_fabric, gallery_fabric, exclude_self)
    return _pick_from(prep, n, ks)


def _pick_from(prep: Prepared, n: int, ks: tuple[int, ...]) -> PickResult:
    n_f = len(prep.fabrics)
    n_eff = n_effective(n, n_f)
    warn_if_short(n, n_eff, n_f)
    res = scan(prep, m=n_eff - 1, ks=ks, recall_ks=(), gallery=False)
    return pick_result_from(res.pick, ks, n_eff)


def pick_result_from(per_query: NDArray[np.float64], ks: tuple[int, ...], n_eff: int) -> PickResult:
    """Wrap per-query pick values (from a shared scan) as a `PickResult`."""
    ok = ~np.isnan(per_query[:, 0]) if per_query.size else np.zeros(0, dtype=bool)
    mean = per_query[ok].mean(axis=0) if ok.any() else np.full(len(ks), np.nan)
    return PickResult(ks, per_query, mean, _chance(ks, n_eff), n_eff, int(ok.sum()))


def pick_k_of_n_sampled(
    dist: ArrayLike,
    query_fabric: ArrayLike,
    gallery_fabric: ArrayLike,
    n: int = 10,
    ks: tuple[int, ...] = (1, 3),
    queries_per_fabric: int = 15,
    repeats: int = 10,
    seed: int = 0,
    exclude_self: ArrayLike | None = None,
    allow_true_distractor: bool = False,
) -> SampledPickResult:
    """The paper's sampled pick-1-of-n: 15 queries per fabric, each drawn 10 times.

    Each trial draws a true item uniformly from the query's fabric (never the query itself),
    ``n - 1`` distractor fabrics uniformly without replacement from the other gallery fabrics
    and one item of each uniformly; the true item's rank among the n candidates is 1 + the
    distractors closer than it + a uniform share of those tied with it (as in the exact form).

    Args:
        queries_per_fabric: queries drawn (without replacement) per query fabric; all of a
            fabric's queries when it has fewer.
        repeats: independent draws of candidates per query.
        seed: seeds everything drawn.
        allow_true_distractor: the released code's variant: distractor fabrics are drawn from
            all gallery fabrics, the query's own included; an own-fabric distractor is another
            item of that fabric (not t, not the query) and counts as a wrong candidate. The own
            fabric is eligible only when it has such an item.

    Returns:
        `SampledPickResult` (means, standard errors over queries, trial counts).
    """
    ks = _check_ks(ks)
    if queries_per_fabric < 1 or repeats < 1:
        raise ValueError("queries_per_fabric and repeats must be >= 1")
    prep = prepare(dist, query_fabric, gallery_fabric, exclude_self)
    return sampled_from(prep, n, ks, queries_per_fabric, repeats, seed, allow_true_distractor)


def sampled_from(
    prep: Prepared,
    n: int,
    ks: tuple[int, ...],
    queries_per_fabric: int,
    repeats: int,
    seed: int,
    allow_true_distractor: bool,
) -> SampledPickResult:
    rng = np.random.default_rng(seed)
    n_f = len(prep.fabrics)
    n_eff = n_effective(n, n_f, allow_true_distractor=allow_true_distractor)
    warn_if_short(n, n_eff, n_f)
    m = n_eff - 1
    order = np.argsort(prep.gidx, kind="stable")  # gallery items grouped by fabric
    starts = np.concatenate([[0], np.cumsum(prep.counts)[:-1]])
    n_excl = prep.excluded.sum(axis=1) if prep.excluded is not None else 0
    own_count = np.where(prep.qidx >= 0, prep.counts[np.maximum(prep.qidx, 0)], 0)
    n_true = own_count - n_excl  # true candidates per query
    chosen = []
    for a in np.unique(prep.qidx[(prep.qidx >= 0) & (n_true > 0)]):
        qs = np.flatnonzero((prep.qidx == a) & (n_true > 0))
        chosen.append(rng.permutation(qs)[: min(queries_per_fabric, len(qs))])
    if not chosen:
        nan = np.full(len(ks), np.nan)
        return SampledPickResult(ks, nan, nan, _chance(ks, n_eff), n_eff, 0, 0)
    sel = np.concatenate(chosen)
    q = np.repeat(sel, repeats)  # (N,) one entry per trial
    a = prep.qidx[q]

    def draw_own(avoid: NDArray[np.int64] | None) -> NDArray[np.int64]:
        """A uniform item of each trial's own fabric, not excluded and not ``avoid``."""
        out = np.zeros(len(q), dtype=np.int64)
        todo = np.arange(len(q))
        while len(todo):  # rejection sampling: uniform over the allowed items
            pos = np.floor(rng.random(len(todo)) * prep.counts[a[todo]]).astype(np.int64)
            item = order[starts[a[todo]] + pos]
            bad = np.zeros(len(todo), dtype=bool)
            if prep.excluded is not None:
                bad |= prep.excluded[q[todo], item]
            if avoid is not None:
                bad |= item == avoid[todo]
            out[todo[~bad]] = item[~bad]
            todo = todo[bad]
        return out

    t = draw_own(None)
    keys = rng.random((len(q), n_f))
    own_spare = n_true[q] - 1  # own items that are neither t nor excluded
    shut = (a >= 0) if not allow_true_distractor else own_spare == 0
    keys[np.flatnonzero(shut), a[shut]] = np.inf  # the own fabric is not eligible
    if m < n_f:
        fabs = np.argpartition(keys, m - 1, axis=1)[:, :m] if m > 0 else keys[:, :0].astype(int)
    else:
        fabs = np.broadcast_to(np.arange(n_f), (len(q), n_f)).copy()
    valid = np.isfinite(np.take_along_axis(keys, fabs, axis=1))  # (N, m) real candidates
    pos = np.floor(rng.random(fabs.shape) * prep.counts[fabs]).astype(np.int64)
    items = order[starts[fabs] + pos]
    is_own = (fabs == a[:, None]) & valid
    if is_own.any():
        spare = draw_own(t)  # another item of the own fabric: a wrong candidate
        items = np.where(is_own, spare[:, None], items)
    bits = tie_bits(prep.dist.shape[1])
    dt = quantize(prep.dist[q, t], bits)[:, None]
    dd = quantize(prep.dist[q[:, None], items], bits)
    closer = ((dd < dt) & valid).sum(axis=1)
    tied = ((dd == dt) & valid).sum(axis=1)
    rank = 1 + closer + rng.integers(0, tied + 1)  # uniform place among the tied
    hits = rank[:, None] <= np.asarray(ks)[None, :]  # (N, K)
    vals = hits.reshape(len(sel), repeats, len(ks)).mean(axis=1)  # (queries, K)
    n_q = len(vals)
    se = vals.std(axis=0, ddof=1) / np.sqrt(n_q) if n_q > 1 else np.full(len(ks), np.nan)
    return SampledPickResult(
        ks, vals.mean(axis=0), se, _chance(ks, n_eff), n_eff, n_q, n_q * repeats
    )
