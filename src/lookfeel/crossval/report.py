"""The Markdown report of a cross-validation (``cv.md``): `format_cv_summary` and the helpers that
write each of its tables from the summary (`lookfeel.crossval.summary`). What each table
measures: the package docstring (`lookfeel.crossval`). A summary of ``n_boot`` 0 (``lookfeel
cv --n-boot 0``) has no interval: its tables give the numbers alone and its sentences say
`NO_INTERVAL` where they would describe the intervals.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from lookfeel.crossval.summary import CALIBRATION_BINS, CLASS_METHODS, MIN_SPEARMAN
from lookfeel.metrics.bootstrap import MIN_INTERVAL_FABRICS as FEW_FABRICS
from lookfeel.metrics.label_space import MIN_FABRICS
from lookfeel.modality import Modality

__all__ = ["NO_INTERVAL", "WORST_ITEMS", "format_cv_summary"]

NO_INTERVAL = "no interval (--n-boot 0: none was drawn)"
"""What ``cv.md`` says where a summary of ``n_boot`` 0 has no intervals (`lookfeel reproduce`'s
words for its own ``--n-boot 0``)."""


def _drawn(summary: dict[str, Any]) -> bool:
    """Whether the summary's intervals were drawn: not where ``n_boot`` is 0 (a summary
    without ``n_boot``, made elsewhere, is taken to have them)."""
    return summary.get("n_boot") != 0


def _count(n: int, noun: str) -> str:
    """``1 object``, ``3 objects``."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


def _fmt(x: dict[str, Any]) -> str:
    """``mean [low, high]``, with ``(k of n runs)`` where only k of the n runs scored it
    (``per_run`` NaN elsewhere); the mean alone where it has no interval (``n_boot`` 0: NaN,
    or null read back from ``cv.json``); ``n/a`` where no run scored it."""
    if x["mean"] is None or math.isnan(x["mean"]):
        return "n/a"
    lo, hi = x.get("ci95") or (None, None)
    if lo is None or hi is None or math.isnan(lo) or math.isnan(hi):
        return f"{x['mean']:.3f}" + _of_runs(x.get("per_run"))
    return f"{x['mean']:.3f} [{lo:.3f}, {hi:.3f}]" + _of_runs(x.get("per_run"))


def _of_runs(per_run: Sequence[float | None] | None) -> str:
    """`` (k of n runs)`` where only k of a number's n runs scored it, else nothing."""
    if not per_run:
        return ""
    k = sum(v is not None and not math.isnan(v) for v in per_run)
    return "" if k == len(per_run) else f" ({k} of {len(per_run)} runs)"


def _pm(scores: dict[str, Any], name: str) -> str:
    """``mean ± std`` over runs (just the mean for one run; ``n/a`` for none), with ``(k of
    n runs)`` where fewer runs than the row's scored it."""
    mean = scores[name]
    if mean is None or math.isnan(mean):
        return "n/a"
    std = scores[f"{name}_std"]
    text = f"{mean:.2f}" + ("" if std is None or math.isnan(std) else f" ± {std:.2f}")
    k, n = scores.get(f"{name}_runs" if name != "r2" else "runs"), scores.get("runs_total")
    return text + (f" ({k} of {n} runs)" if k is not None and n and k < n else "")


def _plural(noun: str) -> str:
    """``presses``, ``images``, ``objects``."""
    return noun + ("es" if noun.endswith(("s", "sh", "ch", "x")) else "s")


def _na_top3(summary: dict[str, Any]) -> list[str]:
    """The pairs whose top-3 says nothing: every fold held out 3 or fewer items to pick among
    (chance top-3 is 1), so every query's top-3 is right."""
    return [
        p
        for p, e in summary["pairs"].items()
        if e.get("chance_top3", 0.0) >= 1.0 - 1e-9 and "not_scored" not in e
    ]


def _pair_table(
    summary: dict[str, Any],
    intro: str,
    columns: tuple[tuple[str, str], ...],
    chance: bool = True,
    name: str = "",
) -> list[str]:
    """A table of every pair scored with ``columns[1]``'s key: one cell per (header, key)
    column (``-`` where a pair lacks it; a column no such pair has is left out; top-3 ``n/a``
    where it says nothing, `_na_top3`), then chance; nothing when no pair has it. Under it,
    which pairs' intervals rest on too few held-out items to say much (`_few_line`, pointing
    at the first table, which says why; nothing where no interval was drawn). Where some
    runs lacked that key's method (``missing_in``), a line says which, and that the table
    (``name``) leaves such pairs out."""
    key = columns[1][1]
    rows = [(p, e) for p, e in summary["pairs"].items() if key in e]
    method = key.rsplit("_top", 1)[0]
    lacking = [
        (p, e["missing_in"][method])
        for p, e in summary["pairs"].items()
        if method in e.get("missing_in", {})
    ]
    lines: list[str] = []
    if rows:
        columns = tuple(c for c in columns if any(c[1] in e for _, e in rows))
        headers = [h for h, _ in columns] + (["chance"] if chance else [])
        lines = ["", intro, "", f"| pair | {' | '.join(headers)} |"]
        lines.append("|---" * (len(headers) + 1) + "|")
        na3 = _na_top3(summary)
        for pair, e in rows:
            cells = [
                "-" if k not in e else "n/a" if pair in na3 and k.endswith("_top3") else _fmt(e[k])
                for _, k in columns
            ]
            if chance:
                cells.append(f"{e['chance_top1']:.3f}")
            lines.append(f"| {pair} | {' | '.join(cells)} |")
        nouns = _plural(summary.get("noun", "fabric"))
        if _drawn(summary):
            lines += _few_line(_pick_counts(summary, [p for p, _ in rows]), nouns, first=False)
    if lacking and name:
        why = _MISSING_WHY.get(method, "").format(noun=summary.get("noun", "fabric"))
        said = "; ".join(f"{p.replace('_', ' ')}: {', '.join(runs)}" for p, runs in lacking)
        lines += [
            "",
            f"{name}: not shown for pairs some run could not score ({said}"
            + (f": {why}" if why else "")
            + "); a pair is shown only when every run scored it.",
        ]
    return lines


_MISSING_WHY = {
    "model_labels": (
        f"no label column had {MIN_FABRICS} or more labelled training {{noun}}s with differing "
        "values"
    ),
    "model_mapped": "no cross-modal map could be fitted on the training {noun}s",
}
"""Why a run has no scores of a method (`_pair_table`'s line); ``{noun}``: fabric, object."""


def _has(summary: dict[str, Any], key: str) -> bool:
    """Whether any pair of the summary has ``key``."""
    return any(key in e for e in summary["pairs"].values())


def _control_lines(summary: dict[str, Any]) -> list[str]:
    """The background control's table (model and raw pixels, as they are, swapped and, for
    registered depth, in another fabric's room)."""
    status = summary.get("background_control") or {}
    if status.get("skipped"):
        return ["", f"Background control: skipped ({status['skipped']})."]
    room = _has(summary, "model_room_top1")
    intro = (
        "Background control: the same queries with every depth image's background replaced "
        "by another fabric's (the cloth kept). A model that reads the cloth, not the room, "
        "scores the same."
    )
    if room:
        intro += (
            " Room control (registered depth): each depth image registered, as it was taken, "
            "against the room fitted on that other fabric's own image, nothing refitted: "
            "another session's registration of the same cloth (where the rooms differ by "
            "more than the margin, room becomes cloth or cloth is lost)."
        )
    columns = (
        ("model top-1", "model_top1"),
        ("model top-1, background swapped", "model_swapped_top1"),
        ("model top-1, in another fabric's room", "model_room_top1"),
        ("raw pixels top-1", "raw_pixels_top1"),
        ("raw pixels top-1, background swapped", "raw_pixels_swapped_top1"),
        ("raw pixels top-1, in another fabric's room", "raw_pixels_room_top1"),
    )
    return _pair_table(summary, intro, columns, chance=False, name="Background control")


def _label_space_lines(summary: dict[str, Any]) -> list[str]:
    """The table of matching in label space beside matching in the embedding."""
    columns = (
        ("model top-1", "model_top1"),
        ("label space top-1", "model_labels_top1"),
        ("label space top-1, background swapped", "model_labels_swapped_top1"),
        ("label space top-1, in another fabric's room", "model_labels_room_top1"),
        ("model top-3", "model_top3"),
        ("label space top-3", "model_labels_top3"),
    )
    intro = (
        "Matching in label space (`lookfeel.metrics.label_space`): the same queries, each "
        "modality's embeddings mapped onto the labels' normal scores by a ridge fitted on the "
        f"run's training {_plural(summary.get('noun', 'fabric'))} only, and a query matched to "
        "the gallery item whose predicted labels are nearest"
    )
    if _has(summary, "model_labels_swapped_top1"):  # the background control ran
        room = _has(summary, "model_labels_room_top1")
        also = " (and registered in another fabric's room)" if room else ""
        intro += (
            f"; for pairs with depth also with every depth image's background swapped{also}, "
            "as in the background control below"
        )
    return _pair_table(summary, intro + ".", columns, name="Matching in label space")


def _mapped_lines(summary: dict[str, Any]) -> list[str]:
    """The table of matching through the cross-modal maps beside the other readings."""
    columns = (
        ("model top-1", "model_top1"),
        ("cross-modal map top-1", "model_mapped_top1"),
        ("cross-modal map top-1, background swapped", "model_mapped_swapped_top1"),
        ("cross-modal map top-1, in another fabric's room", "model_mapped_room_top1"),
        ("label space top-1", "model_labels_top1"),
        ("cross-modal map top-3", "model_mapped_top3"),
    )
    nouns = _plural(summary.get("noun", "fabric"))
    return _pair_table(
        summary,
        "Matching through a cross-modal map (`lookfeel.metrics.cross_map`; no labels used): "
        "the same queries, the query modality's embeddings carried into the gallery "
        f"modality's and back by linear maps fitted on the run's training {nouns} only, a "
        "query matched to the gallery item nearest by both routes, each gallery item's "
        f"distance lowered by its crowding among the training {nouns} (the hub correction).",
        columns,
        name="Matching through a cross-modal map",
    )


def _untouched_lines(summary: dict[str, Any]) -> list[str]:
    """The untouched control's table (model and raw pixels, pressed and with no contact)."""
    return _pair_table(
        summary,
        "Untouched control: the same queries with every press replaced by a moment of its video "
        "with no contact, preprocessed alike (`lookfeel.data.touch_control`). A model that reads "
        "the contact, not the sensor's own light or the session, falls to chance.",
        (
            ("model top-1", "model_top1"),
            ("model top-1, untouched", "model_untouched_top1"),
            ("raw pixels top-1", "raw_pixels_top1"),
            ("raw pixels top-1, untouched", "raw_pixels_untouched_top1"),
        ),
        name="Untouched control",
    )


WORST_ITEMS = 8
"""Held-out items per pair that the report lists, worst first (`cv.json` keeps every one)."""


def _per_item_lines(summary: dict[str, Any]) -> list[str]:
    """The held-out items each pair matches worst, beside raw pixels (`_per_item`)."""
    rows = [(p, e["per_item"]) for p, e in summary["pairs"].items() if e.get("per_item")]
    if not rows:
        return []
    swapped = any("model_swapped_top1" in r for _, items in rows for r in items)
    lines = [
        "",
        f"Held-out items matched worst: each item's top-1 over every query it made, in every "
        f"run (the {WORST_ITEMS} worst per pair; `cv.json` lists all under `per_item`), beside raw "
        "pixels: where they score higher, the pixels hold something of the item that the model "
        "does not use.",
        "",
        "| pair | item | queries | model top-1 | raw pixels top-1 |"
        + (" background swapped |" if swapped else ""),
        "|---|---|---|---|---|" + ("---|" if swapped else ""),
    ]

    def cell(r: dict[str, Any], key: str) -> str:
        v = r.get(key)
        return "-" if v is None or math.isnan(v) else f"{v:.3f}"

    for pair, items in rows:
        perfect = sum(r["model_top1"] >= 1.0 for r in items)
        for r in items[:WORST_ITEMS]:
            cells = [str(r["queries"]), cell(r, "model_top1"), cell(r, "raw_pixels_top1")]
            if swapped:
                cells.append(cell(r, "model_swapped_top1"))
            lines.append(f"| {pair} | {r['item']} | {' | '.join(cells)} |")
        lines.append(
            f"| {pair} | ({perfect} of {len(items)} items always right) | | | |"
            + (" |" if swapped else "")
        )
    return lines


def _coverage_text(summary: dict[str, Any]) -> str:
    """What cv.md's first line says the folds held out: every fabric (object) once, or how
    many of how many, which folds were not run, and which were never used and why
    (``coverage``, `_fold_plan`); without it (a summary made elsewhere), the fold size."""
    noun = summary.get("noun", "fabric")
    cov = summary.get("coverage")
    if cov is None:
        size = summary["fold_size"]
        return f"every {noun} held out once" if size is None else f"{size} {noun}s per fold"
    sizes = cov["fold_sizes"]
    lo, hi = min(sizes), max(sizes)
    per = f"{lo} per fold" if lo == hi else f"{lo} to {hi} per fold"
    held, total = len(cov["held_out"]), cov["items"]
    if held == total:
        text = f"every {noun} held out once, {per}"
    else:
        text = f"{held} of the {_count(total, noun)} held out, each once, {per}"
    not_run = cov["not_run"]
    if not_run["folds"]:
        folds = ", ".join(map(str, not_run["folds"]))
        text += (
            f"; fold{'s' if len(not_run['folds']) > 1 else ''} {folds} of "
            f"{cov['folds_total']} not run (--only-folds): "
            f"{_count(len(not_run['items']), noun)} not held out"
        )
    if cov["train_only"]:
        text += (
            f"; {_count(len(cov['train_only']), noun)} in no fold, only trained on "
            f"({cov['folds_total']} folds of train.fold_size={summary['fold_size']})"
        )
    never = cov["never_used"]
    if never["items"]:
        shown = ", ".join(never["items"][:10]) + (", ..." if len(never["items"]) > 10 else "")
        text += (
            f"; {_count(len(never['items']), noun)} never used, neither trained on nor held "
            f"out ({shown}): {never['why']}"
        )
    return text


def format_cv_summary(summary: dict[str, Any]) -> str:
    """The cross-validation summary as Markdown: pick 1 of 10 per pair, then properties.
    Under each table with intervals, which of them rest on fewer held-out items than
    `FEW_FABRICS` (`_few_line`). With ``n_boot`` 0 the numbers stand alone and the sentences
    that describe the intervals say `NO_INTERVAL` instead."""
    drawn = _drawn(summary)
    noun = summary.get("noun", "fabric")
    nouns = _plural(noun)
    fewer = any(e.get("chance_top1", 0.0) > 0.1 + 1e-9 for e in summary["pairs"].values())
    runs = summary["runs"]
    touch_pair = summary["pairs"].get("touch_to_touch", {})
    same_touch = ""
    if "touch_to_touch" in summary["pairs"]:
        same_touch = "; touch to touch picks among the single presses outside the query" + (
            " (none is left here: see below)" if "not_scored" in touch_pair else ""
        )
    lines = [
        f"{noun.capitalize()}-disjoint cross-validation: {runs} run{'' if runs == 1 else 's'} "
        f"(folds {summary['folds']}, seeds {summary['seeds']}; {_coverage_text(summary)}). "
        f"Pick 1 of 10 among each fold's held-out {nouns}"
        + (" (1 of all of them where a fold holds fewer than 10: see chance)" if fewer else "")
        + (
            f"; mean over runs [95% interval, resampling held-out {nouns}]."
            if drawn
            else f"; mean over runs, {NO_INTERVAL}."
        )
        + (
            f" Touch pools {summary['presses']} presses of one {noun}, as a query and as the "
            f"candidates of another sense's queries (the Multi-input Net's protocol){same_touch}."
            if summary.get("presses", 1) > 1
            else ""
        ),
        "",
        "| pair | model top-1 | model top-3 | raw pixels top-1 | raw pixels top-3 | chance |",
        "|---|---|---|---|---|---|",
    ]
    na3 = _na_top3(summary)
    for pair, e in summary["pairs"].items():
        if "not_scored" in e:
            lines.append(f"| {pair} | not scored | - | - | - | n/a |")
            continue
        top3 = {
            k: "n/a" if pair in na3 else _fmt(e[k])
            for k in e
            if k.endswith("_top3") and k != "chance_top3"
        }
        raw = (
            (_fmt(e["raw_pixels_top1"]), top3["raw_pixels_top3"])
            if "raw_pixels_top1" in e
            else ("-", "-")
        )
        lines.append(
            f"| {pair} | {_fmt(e['model_top1'])} | {top3['model_top3']} | {raw[0]} | {raw[1]} "
            f"| {e['chance_top1']:.3f} / {e['chance_top3']:.3f} |"
        )
    if drawn:
        lines += _few_line(_pick_counts(summary, list(summary["pairs"])), nouns)
    if na3:
        lines += [
            "",
            f"Top-3 is n/a for {', '.join(p.replace('_', ' ') for p in na3)}: no fold held out "
            f"more than 3 {nouns} to pick among, so every query's top-3 is right (chance "
            "1.000); read top-1.",
        ]
    unscored = [(p, e["not_scored"]) for p, e in summary["pairs"].items() if "not_scored" in e]
    if unscored:
        lines += [""] + [f"Not scored: {pair.replace('_', ' ')}: {why}." for pair, why in unscored]
    lines += _label_space_lines(summary)
    lines += _mapped_lines(summary)
    lines += _control_lines(summary)
    lines += _untouched_lines(summary)
    lines += _per_item_lines(summary)
    for m, per in summary["properties"].items():
        if not per.get("model"):
            continue
        lines += _probe_lines(m, per, runs, nouns, _pooled_scope(summary), drawn)
    for m, per in summary.get("classes", {}).items():
        unit = "press" if m == Modality.TOUCH.value else "image"
        interval = f" [95% interval, resampling held-out {nouns}]" if drawn else ""
        lines += [
            "",
            f"Classes from {m}: accuracy{interval} / macro-F1, "
            + ("" if drawn else f"{NO_INTERVAL}, ")
            + f"each the mean over runs of the run's accuracy over its held-out {_plural(unit)} "
            f"(n/a where no held-out {noun} is labelled). model: the class head on one {unit}; "
            f"pooled: every {unit} of one {noun} at once; probe: 5-NN on the training embeddings; "
            "raw pixels: 5-NN on training pixels; majority: the training majority class.",
            "",
            "| label | model | pooled | probe | raw pixels | majority | chance |",
            "|---|---|---|---|---|---|---|",
        ]
        for col, e in per.items():
            cells = [
                "n/a"
                if e[k]["accuracy"] is None or math.isnan(e[k]["accuracy"])
                else f"{_fmt({'mean': e[k]['accuracy'], 'ci95': e[k]['ci95']})} / "
                f"{e[k]['macro_f1']:.2f}{_of_runs(e[k].get('per_run'))}"
                for k in CLASS_METHODS
            ]
            lines.append(f"| {col} | {' | '.join(cells)} | {e['chance']:.2f} |")
        lines += _calibration_lines(m, per)
    return "\n".join(lines) + "\n"


def _pooled_scope(summary: dict[str, Any]) -> str:
    """The sentence the property tables add where the folds run did not hold out every
    item that cv could (``--only-folds``, or a ``train.fold_size`` that leaves some in no
    fold): which items the pooled numbers are over; nothing otherwise."""
    cov = summary.get("coverage")
    if not cov or not (cov["not_run"]["items"] or cov["train_only"]):
        return ""
    noun = summary.get("noun", "fabric")
    why = []
    if cov["not_run"]["folds"]:
        n = len(cov["not_run"]["folds"])
        why.append(f"{n} of the {cov['folds_total']} folds not run: --only-folds")
    if cov["train_only"]:
        why.append(f"{_count(len(cov['train_only']), noun)} in no fold")
    return (
        f" Pooled over the {_count(len(cov['held_out']), noun)} the folds run held out, not "
        f"every {noun} ({'; '.join(why)})."
    )


def _interval(x: dict[str, Any] | None) -> str:
    """A pooled probe score (`_pooled_probe`) as ``mean [low, high]``: just the mean where
    the interval is not known, ``n/a`` where the score is not. Never ``-0.00``."""
    if x is None or x["mean"] is None or math.isnan(x["mean"]):
        return "n/a"

    def f(v: float) -> str:
        return f"{v:.2f}" if abs(v) >= 0.005 else "0.00"

    lo, hi = x["ci95"]
    if lo is None or hi is None or math.isnan(lo) or math.isnan(hi):
        return f(x["mean"])
    return f"{f(x['mean'])} [{f(lo)}, {f(hi)}]"


_PROBE_METHODS = (("model", "model"), ("raw_pixels", "raw pixels"), ("room", "room alone"))
"""The probes a property table shows, as ``cv.json`` names them and as the table does."""


def _probe_lines(
    modality: str,
    per: dict[str, Any],
    runs: int,
    nouns: str,
    scope: str = "",
    drawn: bool = True,
) -> list[str]:
    """The property probes' tables of one modality (`_summarise_probes`): per label, R² in
    one table and Spearman in the next, each over every held-out item of a seed's folds at
    once, with 95% intervals (``pooled``), for the model, raw pixels, the room alone and
    chance, and how many items and runs each row is over; ``n/a: why`` where a label could
    not be scored. Under them: why chance is the mark to beat, and which rows rest on too few
    items for their intervals to say much (`_few_items_line`). ``scope``: `_pooled_scope`'s
    sentence. ``drawn``: whether the intervals were (not with ``n_boot`` 0: the sentence says
    `NO_INTERVAL`, and no row is said to rest on too few items for its interval). A summary
    made before the pooled scores (session 55) gets its table as it was
    (`_per_run_probe_lines`)."""
    rows = per["model"]
    if not any("pooled" in row for row in rows.values()):
        return _per_run_probe_lines(modality, per, runs, nouns)
    noun = nouns[:-1]
    seeds = max(len(row["pooled"].get("seeds", ())) for row in rows.values() if "pooled" in row)
    methods = [(k, name) for k, name in _PROBE_METHODS if k in per]
    lines = [
        "",
        f"Physical properties from {modality}: a ridge probe on {noun}-mean embeddings, "
        f"fitted on each fold's training {nouns}, predicts that fold's held-out {nouns}. R² "
        f"and Spearman are over a seed's held-out {nouns} of every fold at once"
        + (f" [95% interval, resampling those {nouns}]" if drawn else f", {NO_INTERVAL}")
        + (f", the mean over {seeds} seeds" if seeds > 1 else "")
        + ". Chance: each fold's training mean as the prediction, what a probe that knows "
        f"nothing scores.{scope} {nouns.capitalize()} (runs): how many held-out {nouns} each "
        "number is over"
        + (" (each seed's)" if seeds > 1 else "")
        + ", and how many runs predicted them. Each run's own R² and Spearman, and their mean "
        "± std over runs, are in `cv.json` (`per_run`, `r2`, `spearman`); these tables are "
        "its `pooled`.",
    ]
    for score, title in (("r2", "R²"), ("spearman", "Spearman")):
        lines += [
            "",
            "| label | "
            + " | ".join(f"{name} {title}" for _, name in methods)
            + f" | chance {title} | {nouns} (runs) |",
            "|---" * (len(methods) + 3) + "|",
        ]
        for label, row in rows.items():
            pooled = row.get("pooled")
            cells = [_probe_cell(per[k].get(label), score) for k, _ in methods]
            cells.append(_interval(pooled.get(f"chance_{score}")) if pooled else "-")
            why = _not_scored(row, score)
            if why:
                cells[0] = f"n/a: {why}"
            cells.append(_items_cell(pooled) if pooled else "-")
            lines.append(f"| {label} | {' | '.join(cells)} |")
    lines += [
        "",
        "Pooling folds pulls R² and Spearman down, chance's and the model's alike (a known "
        "bias of cross-validated R² and correlation: each fold's training mean lies away from "
        f"that fold's held-out {nouns}), so read the model's numbers against the chance "
        "column, not against 0.",
    ]
    if drawn:
        lines += _few_items_line(rows, nouns)
    if any(
        row.get("pooled")
        and _nan(row["pooled"].get("chance_spearman"))
        and not _nan(row["pooled"]["spearman"])
        for row in rows.values()
    ):
        lines += [
            "",
            f"Chance Spearman is n/a where every held-out {noun} got the same training mean "
            "(as when one fold is run): a prediction of one value has no order.",
        ]
    return lines + _room_note("room" in per)


def _nan(x: dict[str, Any] | None) -> bool:
    """Whether a pooled score (`_pooled_probe`) is missing or has no number."""
    return x is None or x["mean"] is None or math.isnan(x["mean"])


def _not_scored(row: dict[str, Any], score: str) -> str | None:
    """Why the model's pooled ``score`` (``r2``, ``spearman``) of a label has no number (R²'s
    reason stands for Spearman too); None where it has one. A label some run could not score
    on its own may still be scored over every fold pooled: the runs' reason
    (``not_scored``) is given only where the pooled score has none of its own."""
    pooled = row.get("pooled")
    if pooled is None:
        return row.get("not_scored") if score == "r2" else row.get("spearman_not_scored")
    if _nan(pooled["r2"]):
        return pooled.get("not_scored") or row.get("not_scored") or "not scored"
    if score == "spearman" and _nan(pooled["spearman"]):
        return pooled.get("spearman_not_scored") or "not scored"
    return None


def _items_cell(pooled: dict[str, Any]) -> str:
    """``20 (5 of 5 runs)``: the held-out items a label's pooled numbers are over (a seed's;
    ``16-20`` where seeds differ) and the runs whose predictions they are."""
    per_seed = pooled.get("per_seed_held_out") or [pooled["held_out"]]
    low, high = min(per_seed), max(per_seed)
    n = str(low) if low == high else f"{low}-{high}"
    runs, total = pooled.get("runs"), pooled.get("runs_total")
    return n if runs is None else f"{n} ({runs} of {total} runs)"


def _few_items_line(rows: dict[str, dict[str, Any]], nouns: str) -> list[str]:
    """The line under the property tables that says which labels' intervals rest on fewer
    than `FEW_FABRICS` held-out items (`_few_line`). A label with no R² has no interval and
    is not counted."""
    counts = {
        label: min(pooled.get("per_seed_held_out") or [pooled["held_out"]])
        for label, row in rows.items()
        if (pooled := row.get("pooled")) is not None and not _nan(pooled["r2"])
    }
    return _few_line(counts, nouns)


def _pick_counts(summary: dict[str, Any], pairs: Sequence[str]) -> dict[str, int]:
    """The held-out items each pair's pick intervals resample: those a scored query came from
    in any run (``per_item``, which lists every one; a fabric held out by several seeds is one
    item, as the bootstrap draws it). A pair of a summary without ``per_item`` is not
    counted."""
    entries = summary["pairs"]
    return {
        p.replace("_", " "): len(entries[p]["per_item"])
        for p in pairs
        if "not_scored" not in entries[p] and "per_item" in entries[p]
    }


def _few_line(counts: dict[str, int], nouns: str, first: bool = True) -> list[str]:
    """The line under a table that says which rows' intervals rest on fewer than
    `FEW_FABRICS` held-out items (``counts``: row -> items;
    `lookfeel.metrics.bootstrap.MIN_INTERVAL_FABRICS`: the rule and the words ``reproduce``
    gives its own intervals): all of them (``The intervals rest on 4 fabrics``) or some (``The
    intervals of density (6 fabrics)``); nothing where none does. ``first``: whether to say
    why and what to do, or only point at the first table that said it (the pick tables
    after the first, over the same queries)."""
    few = {label: n for label, n in counts.items() if n < FEW_FABRICS}
    if not few:
        return []
    noun = nouns[:-1]
    if len(few) == len(counts):
        low, high = min(few.values()), max(few.values())
        where = "rest on " + (_count(low, noun) if low == high else f"{low} to {high} {nouns}")
    else:
        where = "of " + ", ".join(f"{label} ({_count(n, noun)})" for label, n in few.items())
    said = f"**The intervals {where}: under {FEW_FABRICS}, they say little**"
    if not first:
        return ["", f"{said}, as under the first table."]
    return [
        "",
        f"{said}, as the bootstrap can only resample the few {nouns} there are: an interval may "
        f"be far narrower than the uncertainty, or far wider. Hold out more {nouns} (every fold "
        "rather than `--only-folds`, more or larger folds) for intervals that say more.",
    ]


def _probe_cell(row: dict[str, Any] | None, name: str) -> str:
    """A method's score ``name`` (``r2``, ``spearman``) of one label: pooled, with its
    interval, where the runs kept their predictions, else its mean ± std over runs; ``-``
    where the method has no row for the label."""
    if row is None:
        return "-"
    return _interval(row["pooled"][name]) if "pooled" in row else _pm(row, name)


def _room_note(room: bool) -> list[str]:
    """What the room-alone column means, under a probe table that has it."""
    if not room:
        return []
    return [
        "",
        "Room alone: the same probe on each raw depth image's background pixels (no "
        "cloth; `lookfeel data leakage`'s rule). Where it scores, the background "
        "follows the labels (as it does when each fabric was captured in its own "
        "session and the sessions follow the labels): read the model's probe against "
        "it, not against zero.",
    ]


def _per_run_probe_lines(modality: str, per: dict[str, Any], runs: int, nouns: str) -> list[str]:
    """The property probes' table of one modality as summaries made before session 55 have
    it (no held-out predictions kept, so no pooled scores): each score's mean ± std over
    runs; ``n/a: why`` where no run could score a label, and on how many runs and held-out
    items each row rests."""
    counted = any("runs" in row for row in per["model"].values())
    lines = [
        "",
        f"Physical properties from {modality} (ridge probe on {nouns[:-1]}-mean embeddings, "
        f"fitted on each fold's training {nouns}"
        + (
            f"; mean ± std over the runs that could score each label, "
            f"with a fold's Spearman over fewer than {MIN_SPEARMAN} {nouns} left out):"
            if runs > 1
            else "):"
        ),
        "",
        "| label | model R² | model Spearman | raw pixels R² | raw pixels Spearman |"
        + (" room alone R² | room alone Spearman |" if "room" in per else "")
        + (f" runs (held-out {nouns}) |" if counted else ""),
        "|---|---|---|---|---|"
        + ("---|---|" if "room" in per else "")
        + ("---|" if counted else ""),
    ]
    methods = [k for k in ("model", "raw_pixels", "room") if k in per]
    for label, row in per["model"].items():
        cells = [_pm(per[k][label], score) for k in methods for score in ("r2", "spearman")]
        why = row.get("not_scored")
        if why:
            cells[0] = f"n/a: {why}"
        elif row.get("spearman_not_scored"):
            cells[1] = f"n/a: {row['spearman_not_scored']}"
        if counted:
            cells.append(f"{row['runs']} of {row['runs_total']} ({row['held_out']})")
        lines.append(f"| {label} | {' | '.join(cells)} |")
    return lines + _room_note("room" in per)


def _calibration_lines(modality: str, per: dict[str, Any]) -> list[str]:
    """The class heads' calibration table (`_calibration`), when the runs kept their logits;
    a temperature at the search's edge is marked not fitted and left out of the line that
    says what to put in ``model.class_temperature``."""
    cols = [(col, e["calibration"]) for col, e in per.items() if "calibration" in e]
    if not cols:
        return []
    unit = "press" if modality == Modality.TOUCH.value else "image"
    units = _plural(unit)
    lines = [
        "",
        f"How far the class heads' probabilities from {modality} can be trusted (one {unit}, "
        f"every run's held-out {units} at once: right is over them all, where the classes "
        "table averages each run's accuracy): the mean probability of the predicted class "
        f"beside how often it is right, and their expected calibration error ({CALIBRATION_BINS} "
        f"bins); then a temperature fitted on the other folds' held-out {units} applied to "
        "each run's (- where there are none), and the temperature fitted on them all "
        "(`model.class_temperature` applies one in `predict`).",
        "",
        "| label | probability | right | error | probability, other folds' temperature "
        "| error, other folds' temperature | temperature |",
        "|---|---|---|---|---|---|---|",
    ]
    fitted, edge = [], []
    for col, c in cols:
        cells = [
            c["confidence"], c["accuracy"], c["ece"], c["confidence_cross_fitted"],
            c["ece_cross_fitted"],
        ]  # fmt: skip
        text = ["-" if v is None or math.isnan(v) else f"{v:.3f}" for v in cells]
        at_edge, crossed = c.get("cross_fitted_at_edge") or 0, c.get("cross_fitted_runs")
        if at_edge and text[3] != "-":
            text[3] += f" (at the search edge in {int(at_edge)} of {int(crossed or 0)} runs)"
        t, t_edge = c["temperature"], c.get("temperature_search_edge")
        if t is not None and not math.isnan(t):
            temp = f"{t:.2f}"
            fitted.append(f"{col}: {t:.2f}")
        elif t_edge is not None and not math.isnan(t_edge):
            temp = f"n/a: at the search edge ({t_edge:.3g}): not fitted"
            edge.append(col)
        else:
            temp = "-"
        lines.append(f"| {col} | {' | '.join(text)} | {temp} |")
    if edge:
        lines += [
            "",
            f"Not fitted: {', '.join(edge)}: the likelihood is best at the edge of the "
            f"temperature search (too few or too certain classes: a head no better than a "
            f"guess on these {units} wants an infinite temperature, one never wrong a zero one); "
            "such a value calibrates nothing: leave it out of `model.class_temperature`.",
        ]
    if fitted:
        lines += [
            "",
            f"`model.class_temperature: {{{', '.join(fitted)}}}` applies the fitted "
            "temperatures in `predict`.",
        ]
    return lines
