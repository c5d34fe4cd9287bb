"""One sort per distance-matrix row, shared by the pick-k-of-n and the whole-gallery metrics.

Ties. Distances are compared after dropping their lowest ``b = bit_length(G - 1)`` mantissa bits
(a relative resolution of about ``2**-(52 - b)``, 1e-12 for G = 3,333: below the rounding error
of the matrix-product distance itself). Distances equal at that resolution are ties, and ties are
broken uniformly at random; every metric here is the exact expectation over that tie-break, so a
collapsed embedding (all distances equal) scores exactly chance.

Dropping those bits lets the column index ride in them: one integer sort per row gives the
order, the quantised value and the index together (about twice as fast as ``argsort``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import gammaln

_CHUNK = 1 << 19
"""Elements of a (rows, G) block processed at once: keeps each temporary at about 4 MB."""

_MAX_ALTERNATING_M = 12
"""Largest distractor count for the fast alternating-sum formula; its cancellation error is at
most about ``3**m`` ulps (5e-11 at m = 12). Beyond it a positive-term recursion is used."""

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]


def tie_bits(n_gallery: int) -> int:
    """Low mantissa bits dropped (and reused for the column index) for a gallery of this size."""
    return max(1, (max(n_gallery, 2) - 1).bit_length())


def quantize(dist: FloatArray, bits: int) -> IntArray:
    """Order-preserving integers for non-negative distances, equal exactly for ties."""
    d = np.ascontiguousarray(dist, dtype=np.float64) + 0.0  # + 0.0 turns -0.0 into 0.0
    return d.view(np.int64) >> bits


@dataclass(frozen=True)
class Prepared:
    """Validated inputs: the distance matrix and fabrics as dense indices."""

    dist: FloatArray
    """(Q, G) distances."""
    qidx: IntArray
    """(Q,) index of each query's fabric among the gallery fabrics, -1 when absent."""
    gidx: IntArray
    """(G,) index of each gallery item's fabric."""
    fabrics: NDArray[np.generic]
    """(F,) the gallery's fabric ids, sorted."""
    counts: IntArray
    """(F,) gallery items per fabric."""
    excluded: NDArray[np.bool_] | None
    """(Q, G) items dropped from the query's ranking (the query itself), or None."""


def prepare(
    dist: ArrayLike,
    query_fabric: ArrayLike,
    gallery_fabric: ArrayLike,
    exclude_self: ArrayLike | None = None,
) -> Prepared:
    """Validate a distance matrix, its fabric ids and the items each query must not see.

    Args:
        dist: (Q, G) non-negative finite distances.
        query_fabric: (Q,) fabric id of each query.
        gallery_fabric: (G,) fabric id of each gallery item.
        exclude_self: None; a (Q,) integer array of gallery indices (``-1`` for none), the
            query's own item when query and gallery are the same set; or a (Q, G) boolean mask.
            Excluded items must belong to the query's fabric: they are dropped from its true
            candidates and from its gallery ranking.

    Raises:
        ValueError: naming the argument that is malformed.
    """
    d = np.asarray(dist, dtype=np.float64)
    if d.ndim != 2:
        raise ValueError(f"dist must be 2-D (Q, G); got shape {d.shape}")
    if not np.isfinite(d).all():
        raise ValueError("dist holds NaN or infinity")
    if (d < 0).any():
        raise ValueError("dist holds negative values")
    qf = np.asarray(query_fabric).reshape(-1)
    gf = np.asarray(gallery_fabric).reshape(-1)
    n_q, n_g = d.shape
    if len(qf) != n_q:
        raise ValueError(f"query_fabric has {len(qf)} entries for {n_q} dist rows")
    if len(gf) != n_g:
        raise ValueError(f"gallery_fabric has {len(gf)} entries for {n_g} dist columns")
    if n_g == 0:
        raise ValueError("the gallery is empty")
    fabrics, gidx, counts = np.unique(gf, return_inverse=True, return_counts=True)
    pos = np.searchsorted(fabrics, qf) if n_q else np.zeros(0, dtype=np.int64)
    pos = np.minimum(pos, len(fabrics) - 1)
    qidx = np.where(fabrics[pos] == qf, pos, -1).astype(np.int64) if n_q else pos
    excluded = _exclusion_mask(exclude_self, n_q, n_g)
    if excluded is not None:
        rows, cols = np.nonzero(excluded)
        bad = gidx[cols] != qidx[rows]
        if bad.any():
            r, c = int(rows[bad][0]), int(cols[bad][0])
            raise ValueError(
                f"exclude_self drops gallery item {c} (fabric {gf[c]!r}) for query {r} "
                f"(fabric {qf[r]!r}); only items of the query's own fabric may be excluded"
            )
    return Prepared(d, qidx, gidx.astype(np.int64), fabrics, counts.astype(np.int64), excluded)


def _exclusion_mask(exclude_self: ArrayLike | None, n_q: int, n_g: int) -> NDArray[np.bool_] | None:
    if exclude_self is None:
        return None
    e = np.asarray(exclude_self)
    if e.dtype == np.bool_:
        if e.shape != (n_q, n_g):
            raise ValueError(f"exclude_self mask must have shape {(n_q, n_g)}; got {e.shape}")
        return e if e.any() else None
    if e.shape != (n_q,) or not np.issubdtype(e.dtype, np.integer):
        raise ValueError(
            f"exclude_self must be a ({n_q},) integer array of gallery indices or a "
            f"({n_q}, {n_g}) boolean mask; got dtype {e.dtype}, shape {e.shape}"
        )
    if ((e < -1) | (e >= n_g)).any():
        raise ValueError(f"exclude_self holds indices outside [-1, {n_g})")
    mask = np.zeros((n_q, n_g), dtype=bool)
    keep = e >= 0
    mask[np.flatnonzero(keep), e[keep]] = True
    return mask if keep.any() else None


@dataclass(frozen=True)
class ScanResult:
    """Per-query values of both protocols; NaN where a query has no true item in the gallery."""

    pick: FloatArray
    """(Q, K) P(true candidate ranks within k) in pick-k-of-n, one column per k."""
    ap: FloatArray
    """(Q,) average precision over the whole gallery (items of the query's fabric relevant)."""
    first_rank: FloatArray
    """(Q,) expected 1-based rank of the first relevant item."""
    recall: FloatArray
    """(Q, Kr) P(first relevant item ranks within k)."""
    n_relevant: IntArray
    """(Q,) relevant gallery items (the query's fabric, minus excluded items)."""
    n_gallery: IntArray
    """(Q,) gallery items the query is ranked against (minus excluded items)."""


def scan(
    prep: Prepared,
    *,
    m: int,
    ks: tuple[int, ...],
    recall_ks: tuple[int, ...],
    pick: bool = True,
    gallery: bool = True,
) -> ScanResult:
    """Sort every row once and derive pick-k-of-n (``m`` distractors) and gallery metrics."""
    d_all, qidx, gidx = prep.dist, prep.qidx, prep.gidx
    n_q, n_g = d_all.shape
    n_f = len(prep.fabrics)
    bits = tie_bits(n_g)
    low = (1 << bits) - 1
    cols = np.arange(n_g, dtype=np.int64)
    pick_out = np.full((n_q, len(ks)), np.nan)
    ap = np.full(n_q, np.nan)
    first = np.full(n_q, np.nan)
    recall = np.full((n_q, len(recall_ks)), np.nan)
    n_excl = prep.excluded.sum(1) if prep.excluded is not None else np.zeros(n_q, np.int64)
    own = np.where(qidx >= 0, prep.counts[np.maximum(qidx, 0)], 0)
    n_rel = (own - n_excl).astype(np.int64)
    n_gal = (n_g - n_excl).astype(np.int64)
    rows_all = np.flatnonzero(n_rel > 0)
    rows_all = rows_all[np.argsort(qidx[rows_all], kind="stable")]  # like fabrics together
    t_max = int(n_rel.max()) if n_q else 0
    row_cost = n_g + ((t_max + 1) * n_f if pick else 0)
    per_chunk = max(1, _CHUNK // row_cost)
    inv_counts = 1.0 / prep.counts
    coef = _fewer_than_coefficients(m, n_f - 1, ks) if pick else None
    for start in range(0, len(rows_all), per_chunk):
        rows = rows_all[start : start + per_chunk]
        n_r = len(rows)
        d = d_all[rows]  # (R, G) copy
        d += 0.0  # -0.0 would sort below every positive distance as an integer
        if prep.excluded is not None:
            d[prep.excluded[rows]] = np.inf  # excluded items sort last, after every real one
        key = d.view(np.int64)
        key &= ~low
        key |= cols
        key.sort(axis=1)
        idx = key & low  # gallery column of each sorted position
        qv = key >> bits  # quantised distance: equal means tied
        lab = gidx[idx]  # (R, G) fabric index in sorted order
        rel = lab == qidx[rows][:, None]
        if prep.excluded is not None:
            rel &= ~prep.excluded[rows[:, None], idx]
        new = np.empty((n_r, n_g), dtype=bool)
        new[:, 0] = True
        np.not_equal(qv[:, 1:], qv[:, :-1], out=new[:, 1:])
        ties = not new.all()
        gstart = np.maximum.accumulate(np.where(new, cols, 0), axis=1) if ties else None
        gend = None
        if ties:
            last = np.empty_like(new)
            last[:, -1] = True
            last[:, :-1] = new[:, 1:]
            gend = np.minimum.accumulate(np.where(last, cols, n_g)[:, ::-1], axis=1)[:, ::-1]
        crel = np.cumsum(rel, axis=1)
        if pick:
            assert coef is not None
            r_i, p_i = np.nonzero(rel)  # true candidates, row-major = sorted within each row
            t_rank = crel[r_i, p_i] - 1  # 0-based order of the true item within its row
            # Item j is strictly closer than true item i (1-based along the row) when fewer
            # than i true items are tied with or closer than j: ``seen[j] < i``.
            seen = crel if gend is None else np.take_along_axis(crel, gend, axis=1)
            below = _counts_before(r_i, t_rank, seen, lab, n_f)  # (N, F) strictly closer
            a_i = qidx[rows][r_i]
            below[np.arange(len(r_i)), a_i] = 0  # the true fabric is never a distractor
            p_lt = below * inv_counts
            p_eq = None
            if gstart is not None:
                # ... and closer or tied when fewer than i true items are strictly closer.
                prev = np.take_along_axis(crel, np.maximum(gstart - 1, 0), axis=1)
                seen = np.where(gstart > 0, prev, 0)
                upto = _counts_before(r_i, t_rank, seen, lab, n_f)
                upto[np.arange(len(r_i)), a_i] = 0
                p_eq = (upto - below) * inv_counts
            vals = _pick_probability(p_lt, p_eq, m, n_f - 1, ks, coef)  # (N, K)
            for c in range(len(ks)):  # mean over each query's true items
                sums = np.bincount(r_i, weights=vals[:, c], minlength=n_r)
                pick_out[rows, c] = sums / n_rel[rows]
        if gallery:
            ap[rows], first[rows], recall[rows] = _gallery_rows(
                rel, crel, new, gstart, gend, n_rel[rows], recall_ks
            )
    return ScanResult(pick_out, ap, first, recall, n_rel, n_gal)


def _counts_before(
    r_i: IntArray, t_rank: IntArray, seen: IntArray, lab: IntArray, n_f: int
) -> FloatArray:
    """Items of every fabric counted for each true item: those j of its row with seen[j] < i.

    A histogram over (row, seen, fabric) accumulated along the seen axis holds every answer,
    O(R G) in all instead of O(R G T) comparisons.

    Args:
        r_i: (N,) row of each true item.
        t_rank: (N,) 0-based order i - 1 of each true item along its row.
        seen: (R, G) per sorted position, the count compared with i.
        lab: (R, G) fabric index per sorted position.

    Returns:
        (N, F) counts, one row per true item (in ``r_i`` order).
    """
    n_r = len(seen)
    t_max = int(t_rank.max()) + 1 if len(t_rank) else 0  # true items in the fullest row
    key = (np.arange(n_r)[:, None] * (t_max + 1) + seen) * n_f + lab
    hist = np.bincount(key.ravel(), minlength=n_r * (t_max + 1) * n_f)
    acc = np.cumsum(hist.reshape(n_r, t_max + 1, n_f), axis=1)
    return acc[r_i, t_rank].astype(np.float64)


def _fewer_than_coefficients(m: int, n_other: int, ks: tuple[int, ...]) -> FloatArray:
    """W with ``P(fewer than k of m chosen fabrics beat t) = sum_i e_i(p) W[i, k]``.

    Averaged over uniform m-subsets S of the n_other distractor fabrics,
    ``P(N_S = j) = sum_{i>=j} (-1)^(i-j) C(i, j) C(n_other - i, m - i) e_i(p) / C(n_other, m)``.
    """
    total = math.comb(n_other, m)
    w = np.zeros((m + 1, len(ks)))
    for i in range(m + 1):
        base = math.comb(n_other - i, m - i)
        for c, k in enumerate(ks):
            acc = 0
            for j in range(min(k, i + 1)):
                acc += (-1) ** (i - j) * math.comb(i, j) * base
            w[i, c] = acc / total
    return w


def _pick_probability(
    p_lt: FloatArray,
    p_eq: FloatArray | None,
    m: int,
    n_other: int,
    ks: tuple[int, ...],
    coef: FloatArray,
) -> FloatArray:
    """P(rank of t <= k) for each (query, true item) given per-fabric beat probabilities.

    With ties, t and each tied distractor get independent uniform keys; given t's key u, fabric
    f beats t with probability ``p_lt + u p_eq`` independently of the others. The answer is a
    polynomial of degree <= m in u, so Gauss-Legendre with ceil((m + 1) / 2) nodes integrates
    it exactly over u in [0, 1].

    Args:
        p_lt: (N, F) P(a random item of fabric f is strictly closer than t); 0 for t's fabric.
        p_eq: (N, F) P(it ties with t), or None when nothing ties.
    """
    out = _fewer_than(p_lt, m, n_other, ks, coef)
    if p_eq is None:
        return out
    tied = np.flatnonzero(p_eq.any(axis=1))
    if len(tied) == 0:
        return out
    nodes, weights = np.polynomial.legendre.leggauss(max(1, (m + 2) // 2))
    acc = np.zeros((len(tied), len(ks)))
    lt, eq = p_lt[tied], p_eq[tied]
    for x, w in zip(nodes, weights, strict=True):
        u = (x + 1.0) / 2.0
        acc += (w / 2.0) * _fewer_than(lt + u * eq, m, n_other, ks, coef)
    out[tied] = acc
    return out


def _fewer_than(
    p: FloatArray, m: int, n_other: int, ks: tuple[int, ...], coef: FloatArray
) -> FloatArray:
    """P(fewer than k of a uniform m-subset of fabrics beat t), each fabric f independently.

    Args:
        p: (N, F) beat probabilities, 0 in the true fabric's column (a factor of 1 below).

    Returns:
        (N, K) probabilities, one column per k.
    """
    n, n_f = p.shape
    if m == 0:
        return np.ones((n, len(ks)))
    pt = np.ascontiguousarray(p.T)  # (F, N): one contiguous row per fabric
    if m <= _MAX_ALTERNATING_M:
        # Elementary symmetric polynomials e_0..e_m of the p's: prod_f (1 + p_f z).
        e = np.zeros((m + 1, n))
        e[0] = 1.0
        for f in range(n_f):
            top = min(f + 1, m)
            e[1 : top + 1] += pt[f] * e[:top]  # the product is formed from the old e first
        out: FloatArray = e.T @ coef
        return np.clip(out, 0.0, 1.0)
    # Positive terms: K = fabrics (of all n_other) that beat t is Poisson-binomial; the chosen
    # m-subset is independent of the draws, so given K the beaten count is hypergeometric.
    pk = np.zeros((n_f + 1, n))
    pk[0] = 1.0
    for f in range(n_f):
        carry = pk[: f + 1] * pt[f]
        pk[: f + 1] *= 1.0 - pt[f]
        pk[1 : f + 2] += carry
    big_k = np.arange(n_other + 1)
    hyp = np.stack([_hypergeom_cdf(k - 1, n_other, big_k, m) for k in ks], axis=1)
    return np.clip(pk[: n_other + 1].T @ hyp, 0.0, 1.0)


def _hypergeom_cdf(x: int, population: int, successes: IntArray, draws: int) -> FloatArray:
    """P(X <= x) for X ~ Hypergeometric(population, successes, draws), vectorised over successes."""
    out = np.zeros(len(successes))
    for j in range(0, min(x, draws) + 1):
        ok = (successes >= j) & (population - successes >= draws - j)
        s = successes[ok]
        out[ok] += np.exp(
            _log_comb(s, j) + _log_comb(population - s, draws - j) - _log_comb(population, draws)
        )
    return np.minimum(out, 1.0)


def _log_comb(n: ArrayLike, k: ArrayLike) -> FloatArray:
    n_ = np.asarray(n, dtype=np.float64)
    k_ = np.asarray(k, dtype=np.float64)
    return np.asarray(gammaln(n_ + 1) - gammaln(k_ + 1) - gammaln(n_ - k_ + 1), dtype=np.float64)


def none_first_probability(s: ArrayLike, r: ArrayLike, x: ArrayLike) -> FloatArray:
    """P(the first x of s irrelevant and r relevant items, in random order, are all irrelevant).

    Equals ``C(s, x) / C(r + s, x)``: 1 for x <= 0, 0 for x > s.
    """
    s_ = np.asarray(s, dtype=np.float64)
    r_ = np.asarray(r, dtype=np.float64)
    x_ = np.broadcast_to(np.asarray(x, dtype=np.float64), np.broadcast(s_, r_, x).shape)
    xs = np.clip(x_, 0.0, None)
    ok = xs <= s_
    xs = np.where(ok, xs, 0.0)
    val = np.exp(
        gammaln(s_ + 1) - gammaln(s_ - xs + 1) + gammaln(r_ + s_ - xs + 1) - gammaln(r_ + s_ + 1)
    )
    return np.asarray(np.where(ok, val, 0.0), dtype=np.float64)


def _gallery_rows(
    rel: NDArray[np.bool_],
    crel: IntArray,
    new: NDArray[np.bool_],
    gstart: IntArray | None,
    gend: IntArray | None,
    n_rel: IntArray,
    recall_ks: tuple[int, ...],
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Expected AP, first relevant rank and recall@k of sorted rows under random tie-breaks."""
    n_r, n_g = rel.shape
    rank = np.arange(1, n_g + 1, dtype=np.float64)
    first_pos = np.argmax(rel, axis=1)
    rr = np.arange(n_r)
    if gstart is None or gend is None:  # no ties: the textbook definitions
        ap = (rel * crel / rank).sum(axis=1) / n_rel
        before = first_pos.astype(np.float64)  # irrelevant items ranked above the first hit
        tied_irrel = np.zeros(n_r)
        tied_rel = np.ones(n_r)
    else:
        # Tie group of n items (r relevant) starting after position s, c relevant before it:
        # item l of the group adds E[rel_l (c + rel_1 + ... + rel_l)] / (s + l)
        #   = ((c + 1) r / n + (l - 1) r (r - 1) / (n (n - 1))) / (s + l).
        flat_new = new.ravel()
        gid = np.cumsum(flat_new) - 1
        size = np.bincount(gid).astype(np.float64)
        nrel = np.bincount(gid, weights=rel.ravel())
        before_group = (crel - rel).ravel()[np.flatnonzero(flat_new)].astype(np.float64)
        n_ = size[gid]
        r_ = nrel[gid]
        c_ = before_group[gid]
        offset = (np.arange(n_g)[None, :] - gstart).ravel()
        pair = np.where(n_ > 1, r_ * (r_ - 1) / np.maximum(n_ * (n_ - 1), 1.0), 0.0)
        contrib = ((c_ + 1.0) * r_ / n_ + offset * pair) / np.tile(rank, n_r)
        ap = contrib.reshape(n_r, n_g).sum(axis=1) / n_rel
        gs = gstart[rr, first_pos]
        ge = gend[rr, first_pos]
        before = gs.astype(np.float64)
        tied_rel = crel[rr, ge].astype(np.float64)  # nothing relevant precedes this group
        tied_irrel = (ge - gs + 1) - tied_rel
    first = before + 1.0 + tied_irrel / (tied_rel + 1.0)
    rec = np.stack(
        [1.0 - none_first_probability(tied_irrel, tied_rel, k - before) for k in recall_ks],
        axis=1,
    )
    rec = np.where(np.asarray(recall_ks)[None, :] > before[:, None], rec, 0.0)
    return ap, first, rec
