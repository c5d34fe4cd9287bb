"""Summarising runs: every run's per-query scores pooled into what ``cv.json`` holds (means over
runs, bootstrap intervals over held-out items, each item's own top-1, the property probes, the
classes and the class heads' calibration), and the constants the other modules share. What
the numbers mean: the package docstring (`lookfeel.crossval`).

With ``n_boot`` 0 (``lookfeel cv --n-boot 0``) no resample is drawn: every number keeps
its value and every interval is NaN (`lookfeel.metrics.bootstrap_ci`'s), ``[null, null]`` in
``cv.json``, and ``cv.md`` says no interval was drawn.

The property probes (``properties`` in ``cv.json``, `_summarise_probes`): ``cv.md`` shows each
label's ``pooled`` scores (``pooled.r2.mean`` [``pooled.r2.ci95``], the same for
``spearman``, ``chance_r2`` and ``chance_spearman``): over every held-out item of a seed's
folds at once. The label's own ``r2`` and ``spearman`` are another number: the mean over runs
of each run's score over its own few held-out items (``per_run`` lists them).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from lookfeel.config._core import ConfigError
from lookfeel.evaluate.core import no_query_scored
from lookfeel.metrics import bootstrap_ci, mean_and_spread
from lookfeel.metrics.bootstrap import fabric_weights, percentile_interval
from lookfeel.metrics.calibration import expected_calibration_error
from lookfeel.metrics.classes import accuracy, logit_temperature, macro_f1, softmax
from lookfeel.metrics.properties import MIN_SPEARMAN, resampled_r2, resampled_spearman
from lookfeel.modality import Pair

__all__ = [
    "CALIBRATION_BINS",
    "CLASS_METHODS",
    "CONTROL_SEED",
    "MIN_SPEARMAN",
    "PER_ITEM_METHODS",
]

_KS = (1, 3)
_METHODS = (
    "model",
    "model_labels",
    "model_labels_swapped",
    "model_mapped",
    "model_mapped_swapped",
    "model_mapped_room",
    "raw_pixels",
    "model_swapped",
    "raw_pixels_swapped",
    "model_room",
    "model_labels_room",
    "raw_pixels_room",
    "model_untouched",
    "raw_pixels_untouched",
)
CONTROL_SEED = 0
"""Seeds the background control's pairing of images with other fabrics' backgrounds."""


def _control_status(results: list[dict], asked: bool) -> dict[str, Any]:
    """``{"on": bool, "seed": int, "skipped": reason or None}`` over the runs."""
    skipped = next(
        (r["background_control_skipped"] for r in results if "background_control_skipped" in r),
        None,
    )
    return {"on": asked and skipped is None, "seed": CONTROL_SEED, "skipped": skipped}


PER_ITEM_METHODS = ("model", "raw_pixels", "model_swapped")
"""The methods `_per_item` breaks down by held-out item (where a run scored them)."""


def _per_item(
    results: list[dict], pair: Pair, names: Mapping[int, str] | None
) -> list[dict[str, Any]]:
    """Each held-out item's top-1 as a query of ``pair``, over every query it made in every
    run: ``[{"item", "fabric_id", "queries", "runs", "model_top1", "raw_pixels_top1", ...}]``,
    worst model first (ties by name). Which fabrics or objects the model cannot tell apart,
    beside what raw pixels make of them; an item a query never came from is absent."""
    per = [r["pairs"][pair] for r in results]
    methods = [m for m in PER_ITEM_METHODS if all(m in p for p in per)]
    ids = np.concatenate([np.asarray(p["query_fabric"]) for p in per])
    runs = np.concatenate([np.full(len(p["query_fabric"]), i) for i, p in enumerate(per)])
    hits = {m: np.concatenate([np.asarray(p[m], np.float64)[:, 0] for p in per]) for m in methods}
    rows = []
    for fid in np.unique(ids):
        at = ids == fid
        scored = at & ~np.isnan(hits["model"])
        if not scored.any():
            continue
        row: dict[str, Any] = {
            "item": names.get(int(fid), f"F{int(fid):04d}") if names else f"F{int(fid):04d}",
            "fabric_id": int(fid),
            "queries": int(scored.sum()),
            "runs": len(np.unique(runs[scored])),
        }
        for m in methods:
            h = hits[m][at]
            row[f"{m}_top1"] = float(np.nanmean(h)) if np.any(~np.isnan(h)) else math.nan
        rows.append(row)
    rows.sort(key=lambda r: (r["model_top1"], r["item"]))
    return rows


def _summarise(
    results: list[dict],
    pairs: Sequence[Pair],
    n_boot: int,
    control: bool = True,
    names: Mapping[int, str] | None = None,
    why: Callable[[Pair], str] | None = None,
    label_values: Mapping[str, Sequence[float]] | None = None,
    noun: str = "fabric",
) -> dict[str, Any]:
    """The runs' scores pooled: per pair and method the mean over runs with a 95% interval
    resampling held-out items, each item's own top-1 (`_per_item`; ``names`` maps fabric ids
    to what the report calls them), the property probes (`_summarise_probes`; ``label_values``:
    each label's known values over the data) and the classes. A pair no query of which was
    scored in any run (none had an item of its own fabric to find) gets, instead of numbers,
    ``not_scored``: ``why(pair)`` (default `no_query_scored` of single presses). A method only
    some runs scored (label space where a fold had too few labelled training items) is left
    out, and ``missing_in`` names the runs without it. ``noun``: what the items are (fabric,
    object)."""
    summary: dict[str, Any] = {"runs": len(results), "pairs": {}, "properties": {}}
    summary["noun"] = noun
    summary["background_control"] = _control_status(results, control)
    seeds = {r.get("seed") for r in results}
    run_names = [
        f"fold {r.get('fold', i)}" + (f" seed {r['seed']}" if len(seeds) > 1 else "")
        for i, r in enumerate(results)
    ]
    for pair in pairs:
        entry: dict[str, Any] = {}
        groups = np.concatenate([r["pairs"][pair]["query_fabric"] for r in results])
        model = [np.asarray(r["pairs"][pair]["model"], np.float64).reshape(-1) for r in results]
        if all(np.isnan(v).all() for v in model):
            entry["not_scored"] = why(pair) if why else no_query_scored(pair, 1, fabrics="held-out")
        for method in _METHODS:
            if "not_scored" in entry or not all(method in r["pairs"][pair] for r in results):
                continue
            per_run = [np.asarray(r["pairs"][pair][method], dtype=np.float64) for r in results]
            pooled = np.concatenate(per_run)
            low, high = bootstrap_ci(pooled, groups, n_boot=n_boot, seed=0)  # NaN: n_boot 0
            for j, k in enumerate(_KS):
                runs = [_scored_mean(v[:, j]) for v in per_run]
                spread = mean_and_spread(runs)
                entry[f"{method}_top{k}"] = {
                    "mean": spread["mean"],
                    "std_over_runs": spread["std"],
                    "ci95": [float(low[j]), float(high[j])],
                    "per_run": runs,
                }
        for j, k in enumerate(_KS):
            entry[f"chance_top{k}"] = float(
                np.mean([r["pairs"][pair]["chance"][j] for r in results])
            )
        missing = {
            method: [
                n for n, r in zip(run_names, results, strict=True) if method not in r["pairs"][pair]
            ]
            for method in _METHODS
            if any(method in r["pairs"][pair] for r in results)
        }
        missing = {k: v for k, v in missing.items() if v}
        if missing and "not_scored" not in entry:
            entry["missing_in"] = missing
        entry["per_item"] = _per_item(results, pair, names)
        summary["pairs"][pair] = entry
    summary["properties"] = _summarise_probes(results, label_values, noun, n_boot)
    summary["classes"] = _summarise_classes(results, n_boot)
    return summary


def _summarise_probes(
    results: list[dict],
    label_values: Mapping[str, Sequence[float]] | None,
    noun: str,
    n_boot: int = 1000,
) -> dict[str, Any]:
    """The property probes over runs: per modality, method (model, raw pixels, room) and label,
    R² and Spearman's mean and std over the runs that could score them (``r2``, ``r2_std``,
    ``spearman``, ``spearman_std``), how many did (``runs``, ``spearman_runs``, of
    ``runs_total``) and on how many labelled held-out items in all (``held_out``); each run's
    own (``per_run``: ``{"seed", "fold", "r2", "spearman", "held_out"}`` a run, in the order
    of ``results``); where no run could, ``not_scored`` (or ``spearman_not_scored``) says why
    (`_probe_reason`). A run's Spearman over fewer than `MIN_SPEARMAN` items is left out
    (NaN in ``per_run`` too). Where every run kept its held-out predictions, also ``pooled``
    (`_pooled_probe`): R², Spearman and chance's over every held-out item of a seed's folds
    at once, with 95% intervals resampling the items (``n_boot`` resamples): what ``cv.md``
    shows."""
    out: dict[str, Any] = {}
    for m, per in results[0]["properties"].items():  # none when no run had training fabrics
        out[m] = {}
        for method in per:
            if not all(method in r["properties"].get(m, {}) for r in results):
                continue
            table: dict[str, dict[str, Any]] = {}
            for label in per[method]:
                cells = [r["properties"][m][method][label] for r in results]
                n_test = np.array([_num(c.get("n_test")) for c in cells])
                r2 = np.array([_num(c["r2"]) for c in cells])
                few = n_test < MIN_SPEARMAN  # NaN (unknown) compares False: kept
                sp = np.array(
                    [
                        math.nan if f else _num(c["spearman"])
                        for c, f in zip(cells, few, strict=True)
                    ]
                )
                row: dict[str, Any] = {}
                for score, vals in (("r2", r2), ("spearman", sp)):
                    spread = mean_and_spread(vals)
                    row[score] = spread["mean"]
                    row[f"{score}_std"] = spread["std"]
                scored = ~np.isnan(r2)
                row["runs"] = int(scored.sum())
                row["spearman_runs"] = int((~np.isnan(sp)).sum())
                row["runs_total"] = len(results)
                row["held_out"] = int(np.nansum(n_test[scored])) if scored.any() else 0
                row["per_run"] = [
                    {
                        "seed": r.get("seed"),
                        "fold": r.get("fold"),
                        "r2": float(r2[i]),
                        "spearman": float(sp[i]),
                        "held_out": None if math.isnan(n_test[i]) else int(n_test[i]),
                    }
                    for i, r in enumerate(results)
                ]
                if not scored.any():
                    row["not_scored"] = _probe_reason(label, cells, label_values, noun)
                elif not row["spearman_runs"]:
                    row["spearman_not_scored"] = (
                        f"at most {MIN_SPEARMAN - 1} labelled held-out {noun}s a fold: "
                        "their Spearman is ±1 whatever the probe predicts"
                        if few[scored].all()
                        else "the probe predicted one value"
                    )
                pooled = _pooled_probe(cells, [r.get("seed") for r in results], n_boot, noun)
                if pooled is not None:
                    if "not_scored" in pooled:  # the data's own reason says more, if any
                        why = _label_reason(label, label_values, noun)
                        pooled["not_scored"] = why or pooled["not_scored"]
                    row["pooled"] = pooled
                table[label] = row
            out[m][method] = table
    return out


def _pooled_probe(
    cells: Sequence[Mapping[str, Any]], seeds: Sequence[Any], n_boot: int, noun: str
) -> dict[str, Any] | None:
    """One label's probe over every held-out item of a seed's folds at once: each run's
    ``held_out`` predictions (`lookfeel.crossval.score._probe`) pooled per seed (the folds of
    one seed hold out each item once), then averaged over the seeds. None where a run kept
    no predictions (a result scored before session 55).

    Per seed: R², Spearman (over `MIN_SPEARMAN` or more items), and those of chance: each
    fold's training mean predicted for its held-out items, what a probe that knows nothing
    does. Pooled over folds, chance is not 0 but below it: a fold's training mean lies away
    from that fold's held-out items (their labels are left out of it), so R² falls below 0
    and the Spearman of chance is negative (-1 where each fold holds out one item). The
    model's pooled scores carry the same bias, and are read against chance's. Chance is
    constant within a fold: its Spearman ranks those ties as one value (mid-ranks, as
    ``scipy.stats.spearmanr``), and training means equal but for rounding are tied too
    (`_tied`). Each 95% interval resamples the items (`fabric_weights`, seed 0: one draw
    shared by every seed, label and method; ``n_boot`` 0 draws none, and every interval is
    NaN). Across seeds, as in the class tables
    (`_summarise_classes`), the number is the mean over seeds and its interval that of the
    mean: each resample's scores are averaged over the seeds before the percentiles are
    taken.

    Returns:
        ``{"r2", "spearman", "chance_r2", "chance_spearman"}``, each ``{"mean", "ci95",
        "per_seed", "per_seed_ci95"}``; ``held_out``, the items pooled (over every seed);
        ``per_seed_held_out``, how many each seed pooled (what each of its numbers is over);
        ``runs``, the runs that predicted any of them, of ``runs_total``; ``seeds``, the
        seeds, in the order of ``per_seed``; ``not_scored`` where items were pooled but R²
        could not be scored, and ``spearman_not_scored`` where R² was scored and Spearman was
        not, each saying why.
    """
    if not all(isinstance(c.get("held_out"), Mapping) for c in cells):
        return None
    by_seed: dict[Any, list[Mapping[str, Any]]] = {}
    for c, seed in zip(cells, seeds, strict=True):
        by_seed.setdefault(seed, []).append(c["held_out"])
    parts = []
    for held in by_seed.values():
        ids = np.array([int(i) for h in held for i in h["fabric"]], dtype=np.int64)
        truth = np.array([_num(v) for h in held for v in h["truth"]])
        pred = np.array([_num(v) for h in held for v in h["pred"]])
        chance = _tied(np.array([_num(h["train_mean"]) for h in held for _ in h["fabric"]]))
        parts.append((ids, truth, pred, chance))
    items = np.unique(np.concatenate([p[0] for p in parts]))
    w = fabric_weights(len(items), n_boot, seed=0)  # (B, F), columns: the sorted items
    scores: dict[str, list[tuple[float, np.ndarray]]] = {k: [] for k in _POOLED_SCORES}
    for ids, truth, pred, chance in parts:
        ws = w[:, np.searchsorted(items, ids)]  # (B, F) -> (B, M): each row its item's draws
        for key, (value, reps) in _seed_scores(truth, pred, chance, ws).items():
            scores[key].append((value, reps))
    out: dict[str, Any] = {}
    for key, per_seed in scores.items():
        values = [v for v, _ in per_seed]
        reps = np.stack([r for _, r in per_seed])  # (S, B)
        n = (~np.isnan(reps)).sum(axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean_reps = np.where(n > 0, np.nansum(reps, axis=0) / n, np.nan)
        out[key] = {
            "mean": mean_and_spread(values)["mean"],
            "ci95": list(percentile_interval(mean_reps)),
            "per_seed": values,
            "per_seed_ci95": [list(percentile_interval(r)) for _, r in per_seed],
        }
    out["held_out"] = len(items)
    out["per_seed_held_out"] = [len(p[0]) for p in parts]
    out["runs"] = sum(len(c["held_out"]["fabric"]) > 0 for c in cells)
    out["runs_total"] = len(cells)
    out["seeds"] = list(by_seed)
    most = max(len(p[0]) for p in parts)
    if math.isnan(out["r2"]["mean"]) and most:
        truths = np.unique(np.concatenate([p[1] for p in parts]))
        out["not_scored"] = (
            f"1 labelled held-out {noun} in all"
            if most < 2
            else f"every labelled held-out {noun}'s value is {truths[0]:g}"
        )
    elif math.isnan(out["spearman"]["mean"]) and most:
        out["spearman_not_scored"] = (
            f"at most {MIN_SPEARMAN - 1} labelled held-out {noun}s in all: their Spearman is ±1 "
            "whatever the probe predicts"
            if most < MIN_SPEARMAN
            else "the probe predicted one value"
        )
    return out


_POOLED_SCORES = ("r2", "spearman", "chance_r2", "chance_spearman")
"""The scores `_pooled_probe` gives a label: the probe's, and chance's (each fold's training
mean predicted)."""


def _tied(x: np.ndarray, rtol: float = 1e-9) -> np.ndarray:
    """``x`` (M,) with values closer than ``rtol`` (relative) made one: each the smallest of
    its run of neighbours. Two folds' training means can be equal but for rounding (the same
    labels summed in another order); ranked apart, they would order what is a tie."""
    if len(x) < 2:
        return x
    order = np.argsort(x, kind="stable")
    s = x[order]
    gap = ~(np.diff(s) <= rtol * np.maximum(np.abs(s[1:]), np.abs(s[:-1])))  # NaN: apart
    start = np.concatenate([[0], np.flatnonzero(gap) + 1])  # where each run of near values begins
    out = np.empty_like(x)
    out[order] = s[start[np.cumsum(np.concatenate([[True], gap])) - 1]]
    return out


def _seed_scores(
    truth: np.ndarray, pred: np.ndarray, chance: np.ndarray, w: np.ndarray
) -> dict[str, tuple[float, np.ndarray]]:
    """One seed's pooled probe: each of `_POOLED_SCORES` as (its value on the items as they
    are, its value in each resample (B,)); ``truth``, ``pred``, ``chance`` (M,): each
    held-out item's label, prediction and fold's training mean; ``w`` (B, M): how many times
    each resample draws each item. NaN where there is nothing to score: fewer than 2 items,
    or fewer than `MIN_SPEARMAN` for Spearman (a resample that draws 2 items keeps its
    Spearman: whether the probe orders those two, not a fixed ±1), or one value predicted
    for Spearman (chance over one fold)."""
    none = (math.nan, np.full(len(w), np.nan))
    out = dict.fromkeys(_POOLED_SCORES, none)
    if len(truth) < 2:
        return out
    one = np.ones((1, len(truth)))
    for name, guess in (("", pred), ("chance_", chance)):
        out[f"{name}r2"] = (
            float(resampled_r2(truth, guess, one)[0]),
            resampled_r2(truth, guess, w),
        )
        if len(truth) >= MIN_SPEARMAN:
            out[f"{name}spearman"] = (
                float(resampled_spearman(truth, guess, one)[0]),
                resampled_spearman(truth, guess, w),
            )
    return out


def _num(x: Any) -> float:
    """A score as a float: NaN for None (a NaN that went through result.json) or missing."""
    return math.nan if x is None else float(x)


def _label_reason(
    label: str, label_values: Mapping[str, Sequence[float]] | None, noun: str
) -> str | None:
    """Why the data itself leaves ``label`` nothing to predict (no item labelled, or every
    value one), from its known values (``label_values``); None where it does not, or where
    they are not known."""
    known = label_values.get(label) if label_values is not None else None
    if known is not None and not known:
        return f"no {noun} labelled"
    if known is not None and len(set(known)) == 1:
        return f"every value {known[0]:g}"
    return None


def _probe_reason(
    label: str,
    cells: Sequence[Mapping[str, Any]],
    label_values: Mapping[str, Sequence[float]] | None,
    noun: str,
) -> str:
    """Why no run's probe scored ``label``: ``cells``, each run's `property_probe` scores of
    it; ``label_values``: the label's known values over the data (None: not known here)."""
    data_reason = _label_reason(label, label_values, noun)
    if data_reason:
        return data_reason
    n_test = [_num(c.get("n_test")) for c in cells]
    n_train = [_num(c.get("n_train")) for c in cells]
    most = max((n for n in n_test if not math.isnan(n)), default=math.nan)
    if most == 0:
        return f"no labelled held-out {noun} in any fold"
    if most == 1:
        return f"at most 1 labelled held-out {noun} a fold"
    if max((n for n in n_train if not math.isnan(n)), default=2) < 2:
        return f"fewer than 2 labelled training {noun}s in every fold"
    return "the held-out values are alike within each fold"


CLASS_METHODS = ("model", "model_pooled", "probe", "raw_pixels", "majority")
"""How a held-out query's class is predicted in the class table (`_classes`)."""


CALIBRATION_BINS = 10
"""Equal-width bins of the expected calibration error of the class heads."""


def _calibration(
    runs: list[dict[str, Any]], folds: Sequence[int] | None = None
) -> dict[str, float]:
    """How far a class head's probability can be trusted on held-out objects, every run's
    held-out presses pooled: the mean probability of the predicted class (``confidence``)
    beside how often it is right (``accuracy``), their expected calibration error (``ece``),
    the temperature that fits them best (``temperature``: what a user would apply; NaN, with
    the edge in ``temperature_search_edge``, where the likelihood is best at the search's
    edge and no temperature was fitted: `lookfeel.metrics.classes.LogitTemperature`), and the
    same confidence and error under a temperature fitted on the runs of *other folds*
    (``*_cross_fitted``: an honest estimate of what the temperature buys, fitted on other
    objects than those it is applied to; NaN when every run is of one fold; applied even at
    the edge, ``cross_fitted_at_edge`` runs of ``cross_fitted_runs``). ``accuracy`` is over
    every held-out press of every run at once, where the classes table's is the mean over
    runs of each run's. ``folds``: each run's fold (default: every run its own)."""

    def known(r: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
        t = np.asarray(r["truth"], dtype=np.int64)
        z = np.asarray(r["logits"], dtype=np.float64).reshape(len(t), -1)
        return z[t >= 0], t[t >= 0]

    parts = [known(r) for r in runs]
    z = np.concatenate([p[0] for p in parts])
    t = np.concatenate([p[1] for p in parts])
    nan = float("nan")
    keys = ("confidence", "accuracy", "ece", "temperature", "temperature_search_edge")
    out = dict.fromkeys((*keys, "confidence_cross_fitted", "ece_cross_fitted"), nan)
    if not len(t):  # no held-out press of a known class
        return out
    hit = (z.argmax(1) == t).astype(np.float64)
    conf = softmax(z).max(1)
    fit = logit_temperature(z, t)
    out |= {
        "confidence": float(conf.mean()),
        "accuracy": float(hit.mean()),
        "ece": expected_calibration_error(conf, hit, CALIBRATION_BINS),
        "temperature": nan if fit.at_edge else fit.value,
        "temperature_search_edge": fit.value if fit.at_edge else nan,
    }
    fold_of = list(range(len(parts))) if folds is None else list(folds)
    if len(set(fold_of)) > 1:
        crossed = []
        edges = 0
        for i, (zi, _) in enumerate(parts):
            others = [p for j, p in enumerate(parts) if fold_of[j] != fold_of[i]]
            temp = logit_temperature(
                np.concatenate([p[0] for p in others]), np.concatenate([p[1] for p in others])
            )
            edges += temp.at_edge
            crossed.append(softmax(zi, temp.value).max(1) if len(zi) else np.zeros(0))
        c = np.concatenate(crossed)
        out["confidence_cross_fitted"] = float(c.mean())
        out["ece_cross_fitted"] = expected_calibration_error(c, hit, CALIBRATION_BINS)
        out["cross_fitted_at_edge"] = float(edges)
        out["cross_fitted_runs"] = float(len(parts))
    return out


def _summarise_classes(results: list[dict], n_boot: int) -> dict[str, Any]:
    """Accuracy (mean over runs, 95% interval resampling objects) and macro-F1 (mean and std
    over runs) of each class-prediction method, per modality and column."""
    out: dict[str, Any] = {}
    for m, per in results[0].get("classes", {}).items():
        out[m] = {}
        for col, first in per.items():
            entry: dict[str, Any] = {"classes": first["classes"]}
            runs = [r["classes"][m][col] for r in results]
            for method in CLASS_METHODS:
                pooled = method == "model_pooled"
                t_key, g_key = ("object_truth", "object") if pooled else ("truth", "query_fabric")
                truth = [np.asarray(r[t_key]) for r in runs]
                pred = [np.asarray(r[method]) for r in runs]
                hits = np.concatenate(
                    [
                        np.where(t >= 0, (t == p).astype(float), np.nan)
                        for t, p in zip(truth, pred, strict=True)
                    ]
                )
                groups = np.concatenate([np.asarray(r[g_key]) for r in runs])
                low, high = bootstrap_ci(hits, groups, n_boot=n_boot, seed=0)
                per_run = [accuracy(t, p) for t, p in zip(truth, pred, strict=True)]
                acc = mean_and_spread(per_run)
                f1 = mean_and_spread(
                    [
                        macro_f1(t, p, len(first["classes"]))
                        for t, p in zip(truth, pred, strict=True)
                    ]
                )
                entry[method] = {
                    "accuracy": acc["mean"],
                    "accuracy_std": acc["std"],
                    "per_run": per_run,
                    "ci95": [float(low), float(high)],
                    "macro_f1": f1["mean"],
                    "macro_f1_std": f1["std"],
                    "queries": int(np.sum(~np.isnan(hits))),
                }
            entry["chance"] = 1.0 / len(first["classes"])
            if all("logits" in r for r in runs):
                folds = [r.get("fold", i) for i, r in enumerate(results)]
                entry["calibration"] = _calibration(runs, folds)
            out[m][col] = entry
    return out


def _check_n_boot(n_boot: int) -> None:
    """Refuse a negative ``n_boot`` (`ConfigError`), before any run is trained or scored; 0 is
    allowed: no resample, no interval."""
    if n_boot < 0:
        raise ConfigError(
            f"n_boot: bootstrap resamples must be >= 0 (0: no intervals), got {n_boot}"
        )


def _scored_mean(values: np.ndarray) -> float:
    """The mean over the queries that were scored (``np.nanmean``); NaN, without numpy's
    warning, when none was."""
    return float(np.nanmean(values)) if (~np.isnan(values)).any() else math.nan
