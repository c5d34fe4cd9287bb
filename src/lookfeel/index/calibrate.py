"""Calibrating a library: c of ``P ∝ exp(-c D^2)``, an "unknown" class and its threshold.

For every pair (query modality, gallery modality) of the library, queries are drawn from the
library itself (up to ``max_queries`` items of the query modality, seeded), and each is matched
twice:

- **Known fabric.** Against the whole gallery with its own item left out. c is fitted by
  maximum likelihood of the true fabric (`lookfeel.metrics.fit_temperature`: the fabric-level
  reading of the paper's section 5.2, eq. 3-4).
- **Unknown fabric (leave fabrics out).** The gallery's fabrics are dealt into ``folds`` groups
  at random, and the query is matched against the gallery without its own fold's fabrics, so
  its true fabric is absent, as for a material the library has never seen.

A softmax over the library's fabrics always sums to 1, so on its own it cannot say "none of
these": an unseen material close to one fabric gets a probability near 1, more so the larger c.
So the fabrics are joined by an **unknown class**, a pseudo-item with a fixed logit ``a``::

    P(unknown)  = exp(a) / (exp(a) + sum_i exp(-c D_i^2))
    P(fabric f) = (1 - P(unknown)) * sum_{i in f} exp(-c D_i^2) / sum_i exp(-c D_i^2)

``a`` (``unknown_logit``) is fitted by maximum likelihood with c fixed: the known-fabric matches
should say "not unknown", the absent-fabric matches "unknown" (a one-parameter logistic
regression on ``logsumexp(-c D^2)``, so it is a far item, not a low softmax peak, that reads as
unknown; both kinds of match are equally many, a prior of one half).

**Threshold.** A query is reported as a known fabric when its best fabric probability is at least
``threshold``: a value at which at most ``target_false_accept`` (default 5%) of the
absent-fabric matches are accepted, halfway between the highest absent-fabric match it rejects
and the lowest known-fabric match it accepts (`threshold_for`). ``true_accept`` is the share of
known-fabric matches still accepted, ``accepted_top1`` their accuracy: what that false-accept
rate costs.

Touch queries are single presses here; a pooled multi-press query (the Multi-input Net) is
usually matched more confidently, so the threshold is conservative for it.

**In-sample.** Every number here is fitted and scored on the library's own items: the queries
are library items (their own item left out of a same-modality gallery, their fabric's other
items kept), c is fitted on the very known-fabric matches ``top1`` counts, and the threshold is
chosen on the very absent-fabric matches ``false_accept`` counts, so ``false_accept`` is the
target met by construction, not a rate measured on new data. ``top1``'s chance is ``chance``:
1 over the gallery's fabrics, as a query is ranked among all of them (not pick 1 of 10).
Held-out numbers, with intervals, are `lookfeel evaluate`'s and `lookfeel cv`'s.

**Through a cross-modal map.** A pair that can be matched through a cross-modal map
(`lookfeel.metrics.cross_map`, fitted on the library's own items, `lookfeel.index.build`) is
calibrated twice, with the embedding's own distances and with the map's, and keeps the one
whose top-1 is higher (``mapped``; the other's top-1 in ``top1_unmapped``). The map's
queries are held out as the fabrics are: each fold's queries are measured through a map
refitted without that fold's fabrics, so neither top-1 nor c nor the threshold rests on a map
that saw the query's fabric; the choice between the two is made on the same queries (in-sample).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from lookfeel.errors import LookfeelError
from lookfeel.metrics import (
    expected_calibration_error,
    fit_temperature,
    match_probabilities,
    pairwise_distances,
)
from lookfeel.metrics.cross_map import fit_cross_map
from lookfeel.modality import Modality, Pair

if TYPE_CHECKING:
    from scipy import sparse

__all__ = [
    "CALIBRATION_VERSION",
    "Calibration",
    "CalibrationError",
    "Distances",
    "PairCalibration",
    "calibrate",
    "calibrate_pair",
    "fit_unknown_logit",
    "item_logsumexp",
    "pair_key",
    "threshold_for",
    "unknown_probability",
]

CALIBRATION_VERSION = 1
"""Which way of calibrating made a library's calibration: part of the key under which
`lookfeel.index.build` reuses a finished library's calibration. Raise it with any change to
what `calibrate` computes, so that a rebuild calibrates afresh (lookfeel's own version does
not change between development sessions)."""


Distances = Callable[[NDArray[np.floating], NDArray[np.floating]], NDArray[np.float64]]
"""(Q, D) queries, (G, D) gallery -> (Q, G) distances."""


def pair_key(query: Modality, gallery: Modality) -> Pair:
    """``touch_to_depth``: the project's ``query_to_gallery`` naming (a `Pair`)."""
    return Pair(query, gallery)


class CalibrationError(LookfeelError):
    """A calibration read back from a library's manifest has a missing, unknown or wrongly typed
    value; the message names its key (``calibration.pairs.color_to_color.c``)."""


@dataclass(frozen=True)
class PairCalibration:
    """How matching one query modality against one gallery modality behaves on the library's own
    items as queries (in-sample: the module docstring).

    Attributes:
        query, gallery: the modalities.
        c: the fitted coefficient of ``exp(-c D^2)``.
        c_at_edge: the likelihood was still improving at the edge of c's search range (fabrics
            perfectly separated): probabilities are then close to 0 or 1.
        unknown_logit: the unknown class's logit ``a`` (module docstring); ``-inf``: no unknown
            class (too few fabrics to hold any out).
        threshold: best fabric probability at or above which a query is a known fabric.
        target_false_accept: the false-accept rate the threshold was chosen for.
        false_accept: absent-fabric queries accepted at the threshold: the queries the
            threshold was chosen on, so at most the target by construction (in-sample).
        true_accept: known-fabric queries accepted at the threshold.
        accepted_top1: top-1 accuracy among the accepted known-fabric queries (NaN if none).
        top1: top-1 accuracy of the best match over known-fabric queries, before thresholding,
            among all ``fabrics`` of the gallery (in-sample: c was fitted on these queries).
        log_likelihood: mean ``log P(true fabric)`` over known-fabric queries (closed set:
            without the unknown class, as the paper's P).
        ece: expected calibration error of the closed-set best-match probability (10 bins).
        n_present: known-fabric queries (those with another item of their fabric).
        n_absent: absent-fabric queries (0: too few fabrics; no threshold, never "unknown").
        fabrics: fabrics in the gallery.
        mapped: matched through the pair's cross-modal map (module docstring).
        top1_unmapped: when a map was tried, the top-1 of the embedding's own
            distances (NaN otherwise); ``top1`` is then the map's when ``mapped``.

    The ``chance`` of ``top1`` is derived from ``fabrics`` (a property).
    """

    query: Modality
    gallery: Modality
    c: float
    c_at_edge: bool
    unknown_logit: float
    threshold: float
    target_false_accept: float
    false_accept: float
    true_accept: float
    accepted_top1: float
    top1: float
    log_likelihood: float
    ece: float
    n_present: int
    n_absent: int
    fabrics: int
    mapped: bool = False
    top1_unmapped: float = math.nan

    @property
    def key(self) -> str:
        return pair_key(self.query, self.gallery)

    @property
    def chance(self) -> float:
        """``top1`` of a random ranking: a known query's best match is ranked among all the
        gallery's ``fabrics``, so 1 / ``fabrics`` (NaN without any)."""
        return 1.0 / self.fabrics if self.fabrics else math.nan

    def to_dict(self) -> dict[str, Any]:
        """Plain data for the manifest (NaN becomes None so the JSON is standard), with the
        `chance` beside ``top1`` for a reader of the JSON."""
        d = asdict(self) | {"chance": self.chance}
        d["query"], d["gallery"] = self.query.value, self.gallery.value
        return {
            k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in d.items()
        }

    @classmethod
    def from_dict(cls, d: object, where: str = "calibration.pair") -> PairCalibration:
        """Read back what `to_dict` wrote, checking every value's type (None: NaN, and for
        ``unknown_logit`` minus infinity; ``mapped`` and ``top1_unmapped`` may be absent, as
        in a library of version 1; ``chance``, which `to_dict` writes for readers of the JSON, is
        derived from ``fabrics`` and not read).

        Args:
            d: the pair's mapping, as read from a manifest.
            where: its key there, to name a bad value by (``calibration.pairs.touch_to_depth``).

        Raises:
            CalibrationError: naming the key and the value that is missing, unknown or wrong.
        """
        d = _mapping(d, where)
        names = [f.name for f in fields(cls)]
        unknown = [k for k in d if k not in names and k != "chance"]
        if unknown:
            raise CalibrationError(f"{where}: unknown key {unknown[0]!r}")
        optional = {"mapped", "top1_unmapped"}
        missing = [k for k in names if k not in d and k not in optional]
        if missing:
            raise CalibrationError(f"{where}.{missing[0]}: missing")
        values: dict[str, Any] = {}
        for name in names:
            if name not in d:
                continue
            key, v = f"{where}.{name}", d[name]
            if name in ("query", "gallery"):
                values[name] = _modality(v, key)
            elif name in ("c_at_edge", "mapped"):
                if not isinstance(v, bool):
                    raise CalibrationError(f"{key} is {v!r}, not true or false")
                values[name] = v
            elif name in ("n_present", "n_absent", "fabrics"):
                values[name] = _count(v, key)
            elif name in ("c", "threshold"):  # used to match: finite, >= 0
                values[name] = _number(v, key, low=0.0)
            elif name == "unknown_logit":
                values[name] = -math.inf if v is None else _number(v, key)
            else:
                values[name] = math.nan if v is None else _number(v, key)
        return cls(**values)


@dataclass(frozen=True)
class Calibration:
    """Every calibrated pair of a library and the gallery each query modality uses by default.

    Attributes:
        pairs: ``query_to_gallery`` -> its calibration.
        default_gallery: query modality -> the gallery modality with the best (in-sample) top-1
            accuracy (ties: the best log-likelihood).
        target_false_accept, folds, seed, max_queries: the settings used.
    """

    pairs: dict[str, PairCalibration]
    default_gallery: dict[Modality, Modality]
    target_false_accept: float
    folds: int
    seed: int
    max_queries: int
    notes: list[str] = field(default_factory=list)

    def pair(self, query: Modality, gallery: Modality) -> PairCalibration:
        """The calibration of one pair.

        Raises:
            KeyError: naming the pair and those calibrated.
        """
        key = pair_key(query, gallery)
        if key not in self.pairs:
            have = ", ".join(self.pairs) or "none"
            raise KeyError(f"no calibration for {key} (calibrated: {have})")
        return self.pairs[key]

    def to_dict(self) -> dict[str, Any]:
        return {
            "target_false_accept": self.target_false_accept,
            "folds": self.folds,
            "seed": self.seed,
            "max_queries": self.max_queries,
            "default_gallery": {q.value: g.value for q, g in self.default_gallery.items()},
            "pairs": {k: p.to_dict() for k, p in self.pairs.items()},
            "notes": list(self.notes),
        }

    @classmethod
    def from_dict(cls, d: object, where: str = "calibration") -> Calibration:
        """Read back what `to_dict` wrote (a library manifest's ``calibration``), checking every
        value's type, and that each query modality's default gallery is a calibrated pair.

        Raises:
            CalibrationError: naming the key (``calibration.pairs.color_to_color.c``) and what
                is wrong with its value.
        """
        d = _mapping(d, where)
        settings = ("target_false_accept", "folds", "seed", "max_queries")
        for name in ("pairs", "default_gallery", *settings):
            if name not in d:
                raise CalibrationError(f"{where}.{name}: missing")
        pairs = {}
        for k, p in _mapping(d["pairs"], f"{where}.pairs").items():
            pc = PairCalibration.from_dict(p, f"{where}.pairs.{k}")
            if pc.key != k:
                raise CalibrationError(
                    f"{where}.pairs.{k}: its query and gallery are those of {pc.key}"
                )
            pairs[k] = pc
        default = {}
        for q, g in _mapping(d["default_gallery"], f"{where}.default_gallery").items():
            key = f"{where}.default_gallery.{q}"
            query, gallery = _modality(q, key), _modality(g, key)
            if pair_key(query, gallery) not in pairs:
                raise CalibrationError(f"{key}: {pair_key(query, gallery)} is not calibrated")
            default[query] = gallery
        notes = d.get("notes", [])
        if not isinstance(notes, list) or not all(isinstance(n, str) for n in notes):
            raise CalibrationError(f"{where}.notes is {notes!r}, not a list of text")
        return cls(
            pairs=pairs,
            default_gallery=default,
            target_false_accept=_number(d["target_false_accept"], f"{where}.target_false_accept"),
            folds=_count(d["folds"], f"{where}.folds"),
            seed=_count(d["seed"], f"{where}.seed"),
            max_queries=_count(d["max_queries"], f"{where}.max_queries"),
            notes=list(notes),
        )


def _mapping(value: object, key: str) -> Mapping[str, Any]:
    """``value`` when it is a mapping with text keys (a JSON object)."""
    if not isinstance(value, Mapping) or not all(isinstance(k, str) for k in value):
        raise CalibrationError(f"{key} is {_short(value)}, not a mapping")
    return value


def _number(value: object, key: str, low: float | None = None) -> float:
    """``value`` as a float when it is a number (not true/false), at least ``low`` if given
    (and then finite)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise CalibrationError(f"{key} is {_short(value)}, not a number")
    x = float(value)
    if low is not None and not (math.isfinite(x) and x >= low):
        raise CalibrationError(f"{key} is {value!r}, not a number >= {low:g}")
    return x


def _count(value: object, key: str) -> int:
    """``value`` when it is a whole number >= 0 (not true/false)."""
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise CalibrationError(f"{key} is {_short(value)}, not a whole number >= 0")
    return value


def _modality(value: object, key: str) -> Modality:
    """``value`` as a `Modality` when it names one."""
    try:
        return Modality(value)
    except ValueError:
        names = ", ".join(m.value for m in Modality)
        raise CalibrationError(f"{key} is {_short(value)}, not a modality ({names})") from None


def _short(value: object) -> str:
    """A value as a person reads it in one line: its repr, cut at 40 characters."""
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _fabric_sum(p: NDArray[np.float64], onehot: sparse.csr_matrix) -> NDArray[np.float64]:
    """(Q, G) item probabilities -> (Q, F) fabric probabilities (sum over each fabric's items)."""
    return np.asarray((onehot.T @ p.T).T)


def item_logsumexp(
    dist: NDArray[np.float64], c: float, mask: NDArray[np.bool_] | None = None
) -> NDArray[np.float64]:
    """``logsumexp_i(-c D_i^2)`` of each row over the items not masked: (Q, G) -> (Q,)."""
    logits = -c * np.square(dist)
    if mask is not None:
        logits = np.where(mask, -np.inf, logits)
    top = logits.max(axis=1)
    return top + np.log(np.exp(logits - top[:, None]).sum(axis=1))


def unknown_probability(
    lse: NDArray[np.float64] | float, unknown_logit: float
) -> NDArray[np.float64]:
    """P(unknown) = ``exp(a) / (exp(a) + exp(lse))`` = ``sigmoid(a - lse)``, computed stably."""
    z = unknown_logit - np.asarray(lse, dtype=np.float64)
    return np.asarray(0.5 * (1.0 + np.tanh(0.5 * z)))


def fit_unknown_logit(lse_known: NDArray[np.float64], lse_absent: NDArray[np.float64]) -> float:
    """Maximum-likelihood ``a``: known matches say "not unknown", absent matches "unknown".

    The negative log-likelihood ``-sum log(1 - s(a - L_known)) - sum log s(a - L_absent)`` is
    convex in ``a``; it is minimised over a bracket wide enough for any data.
    """
    lk = np.asarray(lse_known, dtype=np.float64)
    la = np.asarray(lse_absent, dtype=np.float64)

    def nll(a: float) -> float:
        # -log s(x) = logaddexp(0, -x); -log(1 - s(x)) = logaddexp(0, x)
        return float(np.logaddexp(0.0, a - lk).sum() + np.logaddexp(0.0, la - a).sum())

    both = np.concatenate([lk, la])
    lo, hi = float(both.min()) - 50.0, float(both.max()) + 50.0
    from scipy.optimize import minimize_scalar  # here: matching never calibrates

    res = minimize_scalar(nll, bounds=(lo, hi), method="bounded", options={"xatol": 1e-6})
    return float(res.x)


def threshold_for(
    absent_best: NDArray[np.float64],
    target: float,
    known_best: NDArray[np.float64] | None = None,
) -> float:
    """A threshold accepting at most ``target`` of the absent-fabric scores.

    A query is accepted when its score is ``>= threshold``; with n scores at most
    ``floor(target * n)`` are accepted. Without ``known_best``: the smallest such threshold.
    With the known-fabric scores, it is moved up into the middle of the empty gap above the
    highest rejected absent score, halfway to the lowest known score that the smallest
    threshold accepts: the same known matches are accepted, and a query scored between the
    two (an image unlike any the library was calibrated on) is not taken for a known fabric
    by a hair's margin. Where the absent scores all underflow to 0 (a library whose fabrics
    lie far apart), the smallest threshold would accept any score above 0, even a best fabric
    at P = 1e-10 beside P(unknown) = 1.
    """
    n = len(absent_best)
    if n == 0:
        return 0.0
    allowed = math.floor(target * n + 1e-9)
    if allowed >= n:
        return 0.0
    s = np.sort(absent_best)[::-1]
    rejected = float(s[allowed])
    smallest = float(np.nextafter(rejected, np.inf))
    if known_best is None:
        return smallest
    above = known_best[known_best >= smallest]
    if not len(above):
        return smallest
    lowest_known = float(above.min())
    return max(smallest, min(0.5 * (rejected + lowest_known), lowest_known))


def calibrate_pair(
    query_emb: NDArray[np.floating],
    query_fabric: NDArray[np.integer],
    gallery_emb: NDArray[np.floating],
    gallery_fabric: NDArray[np.integer],
    query: Modality,
    gallery: Modality,
    *,
    target_false_accept: float = 0.05,
    folds: int = 5,
    seed: int = 0,
    max_queries: int = 1000,
    distances_without: Callable[[NDArray[np.integer]], Distances] | None = None,
) -> PairCalibration | None:
    """Calibrate one (query, gallery) modality pair of a library (see the module docstring).

    When query and gallery are the same modality, each query's own row is left out.

    Args:
        query_emb: (Q, D) embeddings of the query modality's items.
        query_fabric: (Q,) their fabric ids.
        gallery_emb: (G, D), gallery_fabric: (G,) the gallery modality's.
        target_false_accept: the false-accept rate to choose the threshold for.
        folds: groups the gallery's fabrics are dealt into for leave-fabrics-out.
        seed: draws the queries and the folds.
        max_queries: at most this many queries (a (Q, G) distance matrix is held in memory).
        distances_without: fabric ids -> a (queries, gallery) -> (Q, G) distance that never
            saw those fabrics: each fold's queries are measured by the one without the fold's
            fabrics (for a cross-modal map, one refitted without them). Default: Euclidean
            (the paper's D), which is fitted on nothing.

    Returns:
        The calibration, or None when no query has another item of its fabric in the gallery.
    """
    rng = np.random.default_rng(seed)
    same = query is gallery
    qf_all = np.asarray(query_fabric).reshape(-1)
    gf = np.asarray(gallery_fabric).reshape(-1)
    sel = np.sort(rng.choice(len(qf_all), size=min(len(qf_all), max_queries), replace=False))
    qf = qf_all[sel]
    fabrics, gidx = np.unique(gf, return_inverse=True)
    nf = len(fabrics)
    q_fold = np.full(len(qf), -1)  # each query's fold of fabrics (-1: its fabric has none)
    fold_of = np.zeros(nf, dtype=np.int64)
    if nf >= 2 and folds >= 2:
        fold_of[rng.permutation(nf)] = np.arange(nf) % min(folds, nf)
        q_col = np.minimum(np.searchsorted(fabrics, qf), nf - 1)
        q_fold = np.where(fabrics[q_col] == qf, fold_of[q_col], -1)
    qe = np.asarray(query_emb)[sel]
    if distances_without is None:
        dist = pairwise_distances(qe, gallery_emb)  # (Q, G)
    else:  # each fold's queries by a distance that never saw the fold's fabrics
        dist = np.empty((len(qf), len(gf)))
        for k in np.unique(q_fold):
            rows = q_fold == k
            left_out = fabrics[fold_of == k] if k >= 0 else fabrics[:0]
            dist[rows] = distances_without(left_out)(qe[rows], gallery_emb)
    from scipy import sparse

    onehot = sparse.csr_matrix((np.ones(len(gf)), (np.arange(len(gf)), gidx)), shape=(len(gf), nf))
    self_mask = np.zeros(dist.shape, dtype=bool)
    if same:
        self_mask[np.arange(len(sel)), sel] = True
    true_item = (gf[None, :] == qf[:, None]) & ~self_mask
    present = true_item.any(axis=1)
    if not present.any():
        return None

    # Known fabrics: fit c, then score the best match.
    dp, mp = dist[present], self_mask[present]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        c = fit_temperature(dp, qf[present], gf, mp)
    at_edge = any("search edge" in str(w.message) for w in caught)
    pf = _fabric_sum(match_probabilities(dp, c, mp), onehot)  # (Q, F), closed set
    lse_known = item_logsumexp(dp, c, mp)
    best = pf.max(axis=1)
    correct = fabrics[pf.argmax(axis=1)] == qf[present]
    true_col = np.searchsorted(fabrics, qf[present])
    p_true = pf[np.arange(len(pf)), true_col]
    log_lik = float(np.log(np.maximum(p_true, 1e-300)).mean())
    ece = expected_calibration_error(np.clip(best, 0.0, 1.0), correct)

    # Unknown fabrics: remove every fabric of the query's fold from the gallery.
    unknown_logit = -math.inf
    open_best = best
    absent_open = np.zeros(0)
    if nf >= 2 and folds >= 2:
        removed = fold_of[gidx][None, :] == q_fold[:, None]  # (Q, G)
        usable = ~removed.all(axis=1)
        da, ma = dist[usable], removed[usable]
        absent_closed = _fabric_sum(match_probabilities(da, c, ma), onehot).max(axis=1)
        lse_absent = item_logsumexp(da, c, ma)
        unknown_logit = fit_unknown_logit(lse_known, lse_absent)
        open_best = best * (1.0 - unknown_probability(lse_known, unknown_logit))
        absent_open = absent_closed * (1.0 - unknown_probability(lse_absent, unknown_logit))
    threshold = threshold_for(absent_open, target_false_accept, open_best)
    accepted = open_best >= threshold
    return PairCalibration(
        query=query,
        gallery=gallery,
        c=float(c),
        c_at_edge=at_edge,
        unknown_logit=unknown_logit,
        threshold=threshold,
        target_false_accept=target_false_accept,
        false_accept=float((absent_open >= threshold).mean()) if len(absent_open) else math.nan,
        true_accept=float(accepted.mean()),
        accepted_top1=float(correct[accepted].mean()) if accepted.any() else math.nan,
        top1=float(correct.mean()),
        log_likelihood=log_lik,
        ece=float(ece),
        n_present=int(present.sum()),
        n_absent=len(absent_open),
        fabrics=nf,
    )


def _refit(
    items: Mapping[Modality, tuple[NDArray[np.floating], NDArray[np.integer]]],
    query: Modality,
    gallery: Modality,
) -> Callable[[NDArray[np.integer]], Distances]:
    """Fabric ids -> the distances of the pair's cross-modal map fitted on ``items`` without
    those fabrics."""
    (eq, fq), (eg, fg) = items[query], items[gallery]

    def without(left_out: NDArray[np.integer]) -> Distances:
        kq, kg = ~np.isin(fq, left_out), ~np.isin(fg, left_out)
        return fit_cross_map(eq[kq], fq[kq], eg[kg], fg[kg]).distances

    return without


def calibrate(
    embeddings: Mapping[Modality, tuple[NDArray[np.floating], NDArray[np.integer]]],
    *,
    target_false_accept: float = 0.05,
    folds: int = 5,
    seed: int = 0,
    max_queries: int = 1000,
    map_pairs: Sequence[Pair] = (),
    map_items: Mapping[Modality, tuple[NDArray[np.floating], NDArray[np.integer]]] | None = None,
) -> Calibration:
    """Calibrate every (query, gallery) pair of a library's modalities.

    Args:
        embeddings: modality -> ((N, D) embeddings, (N,) fabric ids).
        target_false_accept, folds, seed, max_queries: see `calibrate_pair`.
        map_pairs: pairs to try matching through a cross-modal map (module docstring).
        map_items: modality -> the items the maps are fitted on (a library's own); each
            fold's queries are measured through a map refitted without the fold's fabrics (so
            with ``folds`` below 2, no fabric is held out and no map is tried).

    Raises:
        ValueError: ``target_false_accept`` outside [0, 1).
    """
    if not 0.0 <= target_false_accept < 1.0:
        raise ValueError(f"target false-accept rate must be in [0, 1); got {target_false_accept}")
    pairs: dict[str, PairCalibration] = {}
    notes: list[str] = []
    for q, (qe, qf) in embeddings.items():
        for g, (ge, gf) in embeddings.items():
            settings: dict[str, Any] = dict(
                target_false_accept=target_false_accept,
                folds=folds,
                seed=seed,
                max_queries=max_queries,
            )
            pc = calibrate_pair(qe, qf, ge, gf, q, g, **settings)
            if pc is not None and map_items and folds >= 2 and pair_key(q, g) in map_pairs:
                try:
                    pm = calibrate_pair(
                        qe, qf, ge, gf, q, g, distances_without=_refit(map_items, q, g), **settings
                    )
                except ValueError as e:  # a fold left too few fabrics to fit a map on
                    notes.append(f"{pair_key(q, g)}: not tried through a cross-modal map ({e})")
                else:
                    assert pm is not None  # the same queries and gallery as pc's
                    better = pm.top1 > pc.top1
                    pc = replace(pm if better else pc, mapped=better, top1_unmapped=pc.top1)
            if pc is None:
                notes.append(
                    f"{pair_key(q, g)}: not calibrated (no query has another item of its "
                    "fabric in the gallery)"
                )
                continue
            pairs[pc.key] = pc
            if pc.n_absent == 0:
                notes.append(
                    f"{pc.key}: fewer than 2 fabrics, no unknown threshold (never 'unknown')"
                )
    default: dict[Modality, Modality] = {}
    for q in embeddings:
        options = [p for p in pairs.values() if p.query is q]
        if options:
            best = max(options, key=lambda p: (p.top1, p.log_likelihood, p.gallery is q))
            default[q] = best.gallery
    return Calibration(pairs, default, target_false_accept, folds, seed, max_queries, notes)
