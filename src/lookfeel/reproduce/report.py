"""The reproduction report: our numbers beside the paper's, and whether each finding holds."""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from typing import Any

from lookfeel.atomic import atomic_write_text
from lookfeel.reproduce.paper import (
    MODEL_COLUMNS,
    PAPER_FINDINGS,
    TABLE_1,
    TABLE_2,
    TABLE_3,
    TABLE_4,
)
from lookfeel.reproduce.result import ReproduceResult

__all__ = ["findings", "write_reproduction_report"]

_COLOR_PAIRS = ("touch_to_color", "color_to_touch", "depth_to_color", "color_to_depth")


Interval = tuple[float, float, float]
"""A number and its 95% interval: (value, low, high); low = high = value when there is none."""

HOLDS, NOT_HOLD, NOISE, UNTESTED = "holds", "does not hold", "within noise", "not tested"
"""The verdicts a finding gets (`findings`)."""


def _interval(table: Mapping[str, Any] | None, key: str) -> Interval | None:
    """``table[key]`` with its interval (``key_ci_low``, ``key_ci_high``) when recorded."""
    if table is None or key not in table:
        return None
    v = float(table[key])
    lo, hi = table.get(f"{key}_ci_low"), table.get(f"{key}_ci_high")
    if lo is None or hi is None:
        return v, v, v
    return v, float(lo), float(hi)


def _top1_interval(results: Mapping[str, Any], model: str, pair: str) -> Interval | None:
    return _interval(results.get(model, {}).get("metrics"), f"{pair}_top1")


def _mean_interval(values: list[Interval]) -> Interval:
    """The mean of several numbers, with the mean of their bounds as its interval: as wide as
    their average interval, which is conservative (a mean's standard error is at most the mean
    of its terms' standard errors, whatever their correlation)."""
    n = len(values)
    return (
        sum(v[0] for v in values) / n,
        sum(v[1] for v in values) / n,
        sum(v[2] for v in values) / n,
    )


def _side(better: Interval, worse: Interval) -> int:
    """+1 if ``better`` is above ``worse`` beyond both intervals, -1 if below beyond them, 0 if
    the intervals overlap (without intervals, the values decide)."""
    if better[1] > worse[2]:
        return 1
    if worse[1] > better[2]:
        return -1
    if better[1:] == (better[0], better[0]) and worse[1:] == (worse[0], worse[0]):
        return -1  # no intervals recorded and equal values: not above, so against the paper
    return 0


def _verdict(sides: list[int] | None, detail: str, reason: str = "") -> dict[str, Any]:
    """The finding's verdict from its comparisons (`_side`, each the paper's way round)."""
    if not sides:
        return {"verdict": UNTESTED, "detail": reason}
    if all(s > 0 for s in sides):
        return {"verdict": HOLDS, "detail": detail}
    if any(s < 0 for s in sides):
        return {"verdict": NOT_HOLD, "detail": detail}
    return {"verdict": NOISE, "detail": f"{detail} (95% intervals overlap)"}


def findings(results: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """Check each of the paper's findings (`PAPER_FINDINGS`) on our numbers.

    Each finding is one or more comparisons (Multi-input above Auxiliary, ...). A comparison is
    decided only when the two numbers' 95% intervals (over test fabrics) do not overlap: the
    finding ``holds`` when every comparison goes the paper's way so, ``does not hold`` when one
    goes the other way so, and is ``within noise`` otherwise. Numbers recorded without an
    interval are compared as they are.
    """
    out: dict[str, dict[str, Any]] = {}
    rows, sides = [], []
    for m in MODEL_COLUMNS:
        for pair in ("touch_to_depth", "touch_to_color"):
            cell = _top1_interval(results, m, pair)
            chance = results.get(m, {}).get("metrics", {}).get(f"{pair}_top1_chance")
            if cell is None or chance is None or cell[0] != cell[0]:
                continue
            side = _side(cell, (chance, chance, chance))
            sides.append(side)
            if side <= 0:  # the cells that do not clear chance beyond their interval
                rows.append(f"{m} {pair} {cell[0]:.3f} (chance {chance:.3f})")
    detail = (
        f"{len(sides) - len(rows)} of {len(sides)} cells above chance beyond their interval"
        + (f"; not: {', '.join(rows)}" if rows else "")
    )
    out["above_chance"] = _verdict(sides, detail, "no model with touch and depth or colour")
    order = [m for m in ("multi_input", "auxiliary", "cross_modal", "flat")]
    vals = {m: _top1_interval(results, m, "touch_to_depth") for m in order}
    known = {m: v for m, v in vals.items() if v is not None}
    if len(known) == len(order):
        sides = [_side(known[a], known[b]) for a, b in itertools.pairwise(order)]
        detail = "in the paper's order: " + ", ".join(f"{m} {known[m][0]:.3f}" for m in order)
        out["model_order"] = _verdict(sides, detail)
    else:
        missing = [m for m, v in vals.items() if v is None]
        out["model_order"] = _verdict(None, "", f"not run: {', '.join(missing)}")
    rows = []
    sides = []
    for m in MODEL_COLUMNS:  # Figure 7: touch as the query; Table 1: touch as the candidates
        for with_depth, with_color in (
            ("touch_to_depth", "touch_to_color"),
            ("depth_to_touch", "color_to_touch"),
        ):
            d = _top1_interval(results, m, with_depth)
            c = _top1_interval(results, m, with_color)
            if d is not None and c is not None:
                sides.append(_side(d, c))
                rows.append(f"{m} {with_depth} {d[0]:.3f} vs {with_color} {c[0]:.3f}")
    out["depth_beats_color"] = _verdict(
        sides, "; ".join(rows), "no model with touch, depth and colour"
    )
    rows, sides = [], []
    across = ("touch_to_depth", "touch_to_color", *TABLE_1)
    for m in MODEL_COLUMNS:
        within = [_top1_interval(results, m, p) for p in TABLE_2]
        other = [_top1_interval(results, m, p) for p in across]
        inside = [x for x in within if x is not None and x[0] == x[0]]
        between = [x for x in other if x is not None and x[0] == x[0]]
        if inside and between:
            mw, ma = _mean_interval(inside), _mean_interval(between)
            sides.append(_side(mw, ma))
            rows.append(f"{m}: within {mw[0]:.3f} vs across {ma[0]:.3f} (means)")
    out["within_beats_across"] = _verdict(
        sides, "; ".join(rows), "no model scored within and across modalities"
    )
    rows, sides = [], []
    for base in ("cross_modal", "multi_input"):
        a = [_top1_interval(results, base, p) for p in _COLOR_PAIRS]
        b = [_top1_interval(results, base + "_aug", p) for p in _COLOR_PAIRS]
        if all(x is not None for x in a + b):
            ma = _mean_interval([x for x in a if x is not None])
            mb = _mean_interval([x for x in b if x is not None])
            sides.append(_side(mb, ma))
            up = sum(
                y[0] > x[0] for x, y in zip(a, b, strict=True) if x is not None and y is not None
            )
            rows.append(
                f"{base}: {ma[0]:.3f} -> {mb[0]:.3f} with augmentation (mean of the colour pairs; "
                f"{up} of {len(a)} up, the paper: all)"
            )
    out["augmentation_helps_color"] = _verdict(sides, "; ".join(rows), "augmentation runs not run")
    snn, joint = results.get("snn_depth", {}), results.get("cross_modal_depth_touch", {})
    both = [s for s in ("novel", "seen") if s in snn and s in joint]
    both = [s for s in both if snn[s]["top1"] == snn[s]["top1"]]  # drop NaN (n/a) sides
    pairs = {s: (_interval(joint[s], "top1"), _interval(snn[s], "top1")) for s in both}
    sides = [_side(j, n) for j, n in pairs.values() if j is not None and n is not None]
    detail = "; ".join(
        f"{s}: SNN {snn[s]['top1']:.3f} vs joint {joint[s]['top1']:.3f}" for s in both
    )
    reason = (
        "no side with two held-out items per fabric"
        if "snn_depth" in results and "cross_modal_depth_touch" in results
        else "needs both Table 4 runs (depth and touch data)"
    )
    out["touch_helps_depth"] = _verdict(sides, detail, reason)
    for k, v in out.items():
        v["claim"] = PAPER_FINDINGS[k]
    return out


def _cell(results: Mapping[str, Any], model: str, pair: str, paper: float | None) -> str:
    m = results.get(model, {}).get("metrics")
    ours = "-" if m is None or f"{pair}_top1" not in m else _number(m[f"{pair}_top1"])
    if ours != NOT_SCORED and m is not None and f"{pair}_top1_ci_low" in m:
        ours += f" [{m[f'{pair}_top1_ci_low']:.2f}, {m[f'{pair}_top1_ci_high']:.2f}]"
    spread = results.get(model, {}).get("spread", {}).get(f"{pair}_top1")
    if spread and results.get(model, {}).get("seeds", 1) > 1:
        ours += f" ±{spread:.3f}"
    return ours + (f" ({paper:.3f})" if paper is not None else "")


NOT_SCORED = "n/a"
"""A cell whose number could not be measured (NaN: no query had an item of its own fabric to
find, e.g. the Multi-input Net's touch to touch with one group of presses per fabric)."""


def _number(v: float) -> str:
    return NOT_SCORED if v != v else f"{v:.3f}"


def _table(
    results: Mapping[str, Any], table: Mapping[str, Mapping[str, float]], columns: tuple[str, ...]
) -> list[str]:
    lines = ["| pair | " + " | ".join(columns) + " | chance |", "|---" * (len(columns) + 2) + "|"]
    for pair, paper in table.items():
        chance = next(
            (
                results[m]["metrics"].get(f"{pair}_top1_chance")
                for m in columns
                if results.get(m, {}).get("metrics", {}).get(f"{pair}_top1_chance") is not None
            ),
            None,
        )
        cells = [_cell(results, m, pair, paper.get(m)) for m in columns]
        lines.append(
            f"| {pair} | "
            + " | ".join(cells)
            + f" | {'-' if chance is None else f'{chance:.3f}'} |"
        )
    return lines


def write_reproduction_report(result: ReproduceResult, meta: Mapping[str, Any]) -> None:
    """Write ``report.md``: tables with ours and (the paper's) numbers, findings, skipped runs."""
    r = result.results
    lines = [
        "# Reproducing *Connecting Look and Feel* (CVPR 2017)",
        "",
        f"Data: `{meta['data']}`; budget: **{meta['budget']}**; seeds: {meta['seeds']}; "
        f"test fabrics (Tables 1-3): {meta['split']}; {meta['minutes']} min.",
        "",
        "Each cell: our top-1 accuracy of pick 1 of 10 (exact expectation over the draw), its 95% "
        "bootstrap interval over test fabrics (first seed), the spread over seeds when there are "
        "several, and (the paper's number). Query modality first: `touch_to_depth` is a GelSight "
        "press matched against depth images. Touch inputs carry the model's number of presses "
        "(3 for the Multi-input Net).",
        "",
        "## Findings",
        "",
        "| finding (paper) | here | evidence |",
        "|---|---|---|",
    ]
    for f in result.findings.values():
        lines.append(f"| {f['claim']} | **{f['verdict']}** | {f['detail']} |")
    lines += [
        "",
        f"A finding is one or more comparisons of two of our numbers. It **{HOLDS}** when every "
        "comparison goes the paper's way with the two 95% intervals (over test fabrics) apart, "
        f"**{NOT_HOLD}** when one goes the other way with them apart, and is **{NOISE}** when "
        "the intervals overlap (over 18 test fabrics an interval is about 0.15 wide, so a "
        f"smaller gap cannot be decided either way; **{UNTESTED}**: its runs were skipped). "
        "The paper's numbers are from real fabrics, AlexNets with ImageNet weights and 25,000 "
        "steps; a short run on a synthetic world is not expected to reach them, only to show "
        "whether their order holds.",
    ]
    lines += ["", "## Figure 7 and Table 1: matching across modalities", ""]
    cross = {"touch_to_depth": {}, "touch_to_color": {}, **TABLE_1}
    lines += _table(r, cross, MODEL_COLUMNS)
    lines += ["", "## Table 2: matching within a modality", ""]
    lines += _table(r, TABLE_2, MODEL_COLUMNS)
    lines += ["", "## Table 3: colour augmentation", ""]
    lines += _table(
        r, TABLE_3, ("cross_modal", "cross_modal_aug", "multi_input", "multi_input_aug")
    )
    lines += [
        "",
        "## Table 4: touch helps vision (depth to depth)",
        "",
        "| model | seen top-1 | seen top-3 | novel top-1 | novel top-3 |",
        "|---|---|---|---|---|",
    ]
    for name, paper in TABLE_4.items():
        row = r.get(name, {})
        cells = []
        for side in ("seen", "novel"):
            got = row.get(side, {})
            for k in ("top1", "top3"):
                ours = got.get(k)
                cell = "-" if ours is None else _number(ours)
                if k == "top1" and "top1_ci_low" in got and cell != NOT_SCORED:
                    cell += f" [{got['top1_ci_low']:.2f}, {got['top1_ci_high']:.2f}]"
                cells.append(cell + f" ({paper[f'{side}_{k}']:.3f})")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    sides = {
        s: row[s]["chance"]
        for row in (r.get(n, {}) for n in TABLE_4)
        for s in ("seen", "novel")
        if s in row and "chance" in row[s]
    }
    novel_fabrics = next(
        (r[n]["test_fabrics"] for n in TABLE_4 if "test_fabrics" in r.get(n, {})), None
    )
    if sides:
        lines += [
            "",
            "Seen: the held-out fifth of each training fabric's depth images"
            + (f" (top-1 chance {sides['seen']:.3f})" if "seen" in sides else "")
            + "; novel: "
            + (f"{novel_fabrics} fabrics" if novel_fabrics is not None else "fabrics")
            + " never trained on, the data's paper_split=test fabrics where it marks any, else "
            "held-out training fabrics"
            + (f" (top-1 chance {sides['novel']:.3f})" if "novel" in sides else "")
            + f". {NOT_SCORED}: fewer than two held-out items per fabric.",
        ]
    if result.skipped:
        lines += ["", "## Skipped", ""]
        lines += [f"- `{name}`: {why}" for name, why in result.skipped.items()]
    lines += [
        "",
        "Per-run details (config, split, training log, checkpoints, all metrics with chance "
        "levels and intervals) are under `runs/<experiment>/seed<k>/`; every number is in "
        "`results.json`.",
        "",
    ]
    atomic_write_text(result.report, "\n".join(lines))
