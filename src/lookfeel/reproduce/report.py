"""The reproduction report: our numbers beside the paper's, and whether each finding holds."""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
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

__all__ = ["findings", "verdict_text", "write_reproduction_report"]

_COLOR_PAIRS = ("touch_to_color", "color_to_touch", "depth_to_color", "color_to_depth")


Interval = tuple[float, float, float]
"""A number and its 95% interval: (value, low, high); low = high = value when there is none."""

HOLDS, NOT_HOLD, NOISE, UNTESTED = "holds", "does not hold", "within noise", "not tested"
"""The verdicts a finding gets (`findings`)."""

TOO_FEW = "too few fabrics"
"""What a finding gets instead of a verdict when an interval it rests on is over fewer than
`MIN_FABRICS` fabrics (`findings`; the count is its ``fabrics``)."""

MIN_FABRICS = 10
"""Below this many test fabrics an interval over fabrics decides no finding (`TOO_FEW`), and
the report says its intervals say little. Pick 1 of 10 offers 10 fabrics a draw (the paper's
split needs 10 of its test fabrics for it), and a bootstrap over fewer fabrics can only
resample those few, so an interval can come out far narrower than the uncertainty: over 4
fabrics one cell read 0.019 [0.00, 0.04] with chance at 0.250."""


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


def _cell_fabrics(results: Mapping[str, Any], model: str, pair: str) -> int | None:
    """The fabrics ``model``'s ``pair`` interval is over: those with a query
    (``pair_n_fabrics``), else the run's test fabrics; None when neither is recorded or the
    cell is NaN."""
    row = results.get(model, {})
    m = row.get("metrics", {})
    top1 = m.get(f"{pair}_top1")
    if top1 is None or top1 != top1:
        return None
    n = m.get(f"{pair}_n_fabrics", row.get("test_fabrics"))
    return None if n is None else round(n)


def _side_fabrics(results: Mapping[str, Any], model: str, side: str) -> int | None:
    """The fabrics a Table 4 side's interval is over (`_cell_fabrics`' counterpart): its
    ``n_fabrics``, else the run's novel (``test_fabrics``) or seen (``seen_fabrics``) ones."""
    row = results.get(model, {})
    got = row.get(side, {})
    if got.get("top1") is None or got["top1"] != got["top1"]:
        return None
    n = got.get("n_fabrics", row.get("test_fabrics" if side == "novel" else "seen_fabrics"))
    return None if n is None else round(n)


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


def _verdict(
    sides: list[int] | None, detail: str, reason: str = "", fabrics: Sequence[int | None] = ()
) -> dict[str, Any]:
    """The finding's verdict from its comparisons (`_side`, each the paper's way round);
    `TOO_FEW` instead when one of the intervals compared is over fewer than `MIN_FABRICS`
    (``fabrics``: how many each is over, None where not recorded), with the fewest."""
    if not sides:
        return {"verdict": UNTESTED, "detail": reason}
    counts = [n for n in fabrics if n is not None]
    if counts and min(counts) < MIN_FABRICS:
        n = min(counts)
        why = f"an interval here is over {n} fabric{'' if n == 1 else 's'}, under {MIN_FABRICS}"
        return {"verdict": TOO_FEW, "detail": f"{detail} ({why})", "fabrics": n}
    if all(s > 0 for s in sides):
        return {"verdict": HOLDS, "detail": detail}
    if any(s < 0 for s in sides):
        return {"verdict": NOT_HOLD, "detail": detail}
    return {"verdict": NOISE, "detail": f"{detail} (95% intervals overlap)"}


def verdict_text(finding: Mapping[str, Any]) -> str:
    """A finding's verdict as printed: ``holds``, ..., ``too few fabrics (4)``."""
    n = finding.get("fabrics")
    return f"{finding['verdict']} ({n})" if finding["verdict"] == TOO_FEW else finding["verdict"]


def findings(results: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """Check each of the paper's findings (`PAPER_FINDINGS`) on our numbers.

    Each finding is one or more comparisons (Multi-input above Auxiliary, ...). A comparison is
    decided only when the two numbers' 95% intervals (over test fabrics) do not overlap: the
    finding ``holds`` when every comparison goes the paper's way so, ``does not hold`` when one
    goes the other way so, and is ``within noise`` otherwise. Numbers recorded without an
    interval are compared as they are. A finding one of whose intervals is over fewer than
    `MIN_FABRICS` fabrics gets no verdict but `TOO_FEW`, with the count as ``fabrics``: a
    bootstrap over so few fabrics can come out far narrower than the uncertainty.
    """
    out: dict[str, dict[str, Any]] = {}
    rows, sides = [], []
    fabrics: list[int | None] = []
    for m in MODEL_COLUMNS:
        for pair in ("touch_to_depth", "touch_to_color"):
            cell = _top1_interval(results, m, pair)
            chance = results.get(m, {}).get("metrics", {}).get(f"{pair}_top1_chance")
            if cell is None or chance is None or cell[0] != cell[0]:
                continue
            side = _side(cell, (chance, chance, chance))
            sides.append(side)
            fabrics.append(_cell_fabrics(results, m, pair))
            if side <= 0:  # the cells that do not clear chance beyond their interval
                rows.append(f"{m} {pair} {cell[0]:.3f} (chance {chance:.3f})")
    detail = (
        f"{len(sides) - len(rows)} of {len(sides)} cells above chance beyond their interval"
        + (f"; not: {', '.join(rows)}" if rows else "")
    )
    out["above_chance"] = _verdict(
        sides, detail, "no model with touch and depth or colour", fabrics
    )
    order = [m for m in ("multi_input", "auxiliary", "cross_modal", "flat")]
    vals = {m: _top1_interval(results, m, "touch_to_depth") for m in order}
    known = {m: v for m, v in vals.items() if v is not None}
    if len(known) == len(order):
        sides = [_side(known[a], known[b]) for a, b in itertools.pairwise(order)]
        detail = "in the paper's order: " + ", ".join(f"{m} {known[m][0]:.3f}" for m in order)
        fabrics = [_cell_fabrics(results, m, "touch_to_depth") for m in order]
        out["model_order"] = _verdict(sides, detail, fabrics=fabrics)
    else:
        missing = [m for m, v in vals.items() if v is None]
        out["model_order"] = _verdict(None, "", f"not run: {', '.join(missing)}")
    rows, sides, fabrics = [], [], []
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
                fabrics += [_cell_fabrics(results, m, p) for p in (with_depth, with_color)]
    out["depth_beats_color"] = _verdict(
        sides, "; ".join(rows), "no model with touch, depth and colour", fabrics
    )
    rows, sides, fabrics = [], [], []
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
            fabrics += [_cell_fabrics(results, m, p) for p in (*TABLE_2, *across)]
    out["within_beats_across"] = _verdict(
        sides, "; ".join(rows), "no model scored within and across modalities", fabrics
    )
    rows, sides, fabrics = [], [], []
    for base in ("cross_modal", "multi_input"):
        a = [_top1_interval(results, base, p) for p in _COLOR_PAIRS]
        b = [_top1_interval(results, base + "_aug", p) for p in _COLOR_PAIRS]
        if all(x is not None for x in a + b):
            ma = _mean_interval([x for x in a if x is not None])
            mb = _mean_interval([x for x in b if x is not None])
            sides.append(_side(mb, ma))
            runs = (base, base + "_aug")
            fabrics += [_cell_fabrics(results, r, p) for r in runs for p in _COLOR_PAIRS]
            up = sum(
                y[0] > x[0] for x, y in zip(a, b, strict=True) if x is not None and y is not None
            )
            rows.append(
                f"{base}: {ma[0]:.3f} -> {mb[0]:.3f} with augmentation (mean of the colour pairs; "
                f"{up} of {len(a)} up, the paper: all)"
            )
    out["augmentation_helps_color"] = _verdict(
        sides, "; ".join(rows), "augmentation runs not run", fabrics
    )
    snn, joint = results.get("snn_depth", {}), results.get("cross_modal_depth_touch", {})
    both = [s for s in ("novel", "seen") if s in snn and s in joint]
    both = [s for s in both if snn[s]["top1"] == snn[s]["top1"]]  # drop NaN (n/a) sides
    pairs = {s: (_interval(joint[s], "top1"), _interval(snn[s], "top1")) for s in both}
    sides = [_side(j, n) for j, n in pairs.values() if j is not None and n is not None]
    fabrics = [
        _side_fabrics(results, run, s)
        for s, (j, n) in pairs.items()
        if j is not None and n is not None
        for run in ("snn_depth", "cross_modal_depth_touch")
    ]
    detail = "; ".join(
        f"{s}: SNN {snn[s]['top1']:.3f} vs joint {joint[s]['top1']:.3f}" for s in both
    )
    reason = (
        "no side with two held-out items per fabric"
        if "snn_depth" in results and "cross_modal_depth_touch" in results
        else "needs both Table 4 runs (depth and touch data)"
    )
    out["touch_helps_depth"] = _verdict(sides, detail, reason, fabrics)
    for k, v in out.items():
        v["claim"] = PAPER_FINDINGS[k]
    return out


NOT_SCORED = "n/a"
"""A cell without a number, marked with a note (``n/a^1``) that says why under its table: no
query had an item of its own fabric to find (the Multi-input Net's touch to touch with one
group of presses per fabric), or a top-k that is 1 whatever the model (k candidates or fewer)."""

_UNMEASURED = (
    "reason not recorded (computed by an earlier lookfeel): delete the run's eval.json and "
    "rerun to record it"
)
"""Why a number is NaN when its run recorded no reason and none could be derived (an
``eval.json`` from before reasons: `lookfeel.reproduce.run` derives them from the run's
``config.yaml`` where it can). Deleting ``eval.json`` rescores the finished run."""

_TABLE_3_COLUMNS = ("cross_modal", "cross_modal_aug", "multi_input", "multi_input_aug")
_SCORED_ON_HELD_OUT = (*MODEL_COLUMNS, "cross_modal_aug", "multi_input_aug")
"""The runs of Tables 1-3, all scored on the same held-out fabrics."""


class _Notes:
    """The notes under one table: each distinct reason a cell is n/a, numbered in order."""

    def __init__(self) -> None:
        self.cells: dict[str, list[str]] = {}
        """reason -> the cells it explains (``"multi_input touch_to_touch"``)."""

    def mark(self, reason: str, cell: str) -> str:
        """``n/a`` with the number of ``reason``'s note (``n/a^1``), ``cell`` listed there."""
        cells = self.cells.setdefault(reason, [])
        if cell not in cells:
            cells.append(cell)
        return f"{NOT_SCORED}^{list(self.cells).index(reason) + 1}"

    def lines(self) -> list[str]:
        """The notes, one list item each: which cells, and why."""
        out = [""] if self.cells else []
        for i, (reason, cells) in enumerate(self.cells.items(), 1):
            out.append(f"- ^{i} {', '.join(cells)}: {reason}.")
        return out


def _cell(
    results: Mapping[str, Any], model: str, pair: str, paper: float | None, notes: _Notes
) -> str:
    row = results.get(model, {})
    m = row.get("metrics")
    if m is None or f"{pair}_top1" not in m:
        ours = "-"
    elif m[f"{pair}_top1"] != m[f"{pair}_top1"]:  # NaN: not scored, with its reason
        ours = notes.mark(row.get("not_scored", {}).get(pair, _UNMEASURED), f"{model} {pair}")
    else:
        ours = f"{m[f'{pair}_top1']:.3f}"
        if f"{pair}_top1_ci_low" in m:
            ours += f" [{m[f'{pair}_top1_ci_low']:.2f}, {m[f'{pair}_top1_ci_high']:.2f}]"
        spread = row.get("spread", {}).get(f"{pair}_top1")
        if spread and row.get("seeds", 1) > 1:
            ours += f" ±{spread:.3f}"
    return ours + (f" ({paper:.3f})" if paper is not None else "")


def _span(values: list[int]) -> str:
    """``4`` or ``4-12``: the range of some counts."""
    lo, hi = min(values), max(values)
    return str(lo) if lo == hi else f"{lo}-{hi}"


def _counts(results: Mapping[str, Any], columns: tuple[str, ...], pair: str) -> str:
    """``fabrics / queries`` behind a row's numbers (their ranges over the columns)."""
    fabrics, queries = [], []
    for model in columns:
        m = results.get(model, {}).get("metrics", {})
        top1 = m.get(f"{pair}_top1")
        if top1 is None or top1 != top1 or f"{pair}_n_queries" not in m:
            continue
        fabrics.append(int(m[f"{pair}_n_fabrics"]))
        queries.append(int(m[f"{pair}_n_queries"]))
    return f"{_span(fabrics)} / {_span(queries)}" if fabrics else "-"


def _table(
    results: Mapping[str, Any], table: Mapping[str, Mapping[str, float]], columns: tuple[str, ...]
) -> list[str]:
    lines = [
        "| pair | " + " | ".join(columns) + " | chance | fabrics / queries |",
        "|---" * (len(columns) + 3) + "|",
    ]
    notes = _Notes()
    for pair, paper in table.items():
        chance = next(
            (
                results[m]["metrics"].get(f"{pair}_top1_chance")
                for m in columns
                if results.get(m, {}).get("metrics", {}).get(f"{pair}_top1_chance") is not None
            ),
            None,
        )
        cells = [_cell(results, m, pair, paper.get(m), notes) for m in columns]
        cells.append("-" if chance is None else f"{chance:.3f}")
        cells.append(_counts(results, columns, pair))
        lines.append(f"| {pair} | " + " | ".join(cells) + " |")
    return lines + notes.lines()


def _fabrics(run: Mapping[str, Any]) -> str:
    """``4 fabrics (4, 7, 12, 13)``: a run's test fabrics, listed when there are 20 or fewer."""
    n, ids = run.get("test_fabrics"), run.get("test_fabric_ids")
    text = f"{n} fabric{'' if n == 1 else 's'}"
    return text + (f" ({', '.join(map(str, ids))})" if ids and len(ids) <= 20 else "")


def _where_scored(result: ReproduceResult, meta: Mapping[str, Any]) -> list[str]:
    """The paragraph on which fabrics each table scores (or that no run was made)."""
    r = result.results
    if not r:
        why = (
            "every experiment asked for was skipped (see Skipped below), so there are no numbers "
            "of ours, only the paper's"
            if result.skipped
            else "no experiment was asked for"
        )
        return [f"**No run was made**: {why}.", ""]
    paper_test = meta.get("paper_test_fabrics")
    lines = []
    held = next((r[n] for n in _SCORED_ON_HELD_OUT if "test_fabrics" in r.get(n, {})), None)
    if held is not None:
        if meta.get("split") == "paper":
            text = f"the data's {_fabrics(held)} marked paper_split=test (the paper's split)"
        else:
            text = f"{_fabrics(held)} held out of the training fabrics (cluster-stratified)"
            if paper_test:
                text += (
                    f"; the data's {paper_test} paper_split=test "
                    f"fabric{'' if paper_test == 1 else 's'} are not used there (neither trained "
                    f"on nor scored): the paper's split needs at least {MIN_FABRICS}, the "
                    "candidates of pick 1 of 10"
                )
            elif paper_test == 0:
                text += "; the data marks no fabric paper_split=test"
        lines.append(f"- Tables 1-3 score on {text}.")
    vision = next((r[n] for n in TABLE_4 if "test_fabrics" in r.get(n, {})), None)
    if vision is not None:
        if paper_test is None:  # a report without the split's facts
            novel = (
                f"{_fabrics(vision)} never trained on, the data's paper_split=test fabrics "
                "where it marks any, else held-out training fabrics"
            )
        elif paper_test:
            novel = f"the data's {_fabrics(vision)} marked paper_split=test"
        else:
            novel = f"{_fabrics(vision)} held out of the training fabrics"
        if held is not None and held.get("test_fabric_ids") is not None:
            same = held.get("test_fabric_ids") == vision.get("test_fabric_ids")
            novel += (
                ", the same as Tables 1-3's"
                if same
                else f", not the {held['test_fabrics']} that Tables 1-3 score on"
            )
        seen = vision.get("seen_fabrics")
        trains = f"each of the {seen} fabrics it trains on" if seen else "each fabric it trains on"
        lines.append(
            f"- Table 4 scores its novel side on {novel}; its seen side on the held-out fifth "
            f"of the depth images of {trains}."
        )
    return ["Test fabrics, never trained on:", "", *lines, ""] if lines else []


def _few_fabrics(results: Mapping[str, Any]) -> tuple[str, bool]:
    """How many test fabrics the intervals rest on (``4 test fabrics (Tables 1-3) and 2
    (Table 4's novel side)``), and whether any is under `MIN_FABRICS`."""
    parts = []
    held = next(
        (results[n] for n in _SCORED_ON_HELD_OUT if "test_fabrics" in results.get(n, {})), None
    )
    if held is not None:
        parts.append((held["test_fabrics"], "Tables 1-3"))
    vision = next((results[n] for n in TABLE_4 if "test_fabrics" in results.get(n, {})), None)
    if vision is not None and any("novel" in results.get(n, {}) for n in TABLE_4):
        parts.append((vision["test_fabrics"], "Table 4's novel side"))
    text = " and ".join(
        f"{n}{' test fabrics' if i == 0 else ''} ({where})" for i, (n, where) in enumerate(parts)
    )
    return text, any(n < MIN_FABRICS for n, _ in parts)


def _mean_width(results: Mapping[str, Any]) -> float | None:
    """The mean width of the top-1 intervals in the tables (None: none recorded)."""
    widths = []
    for row in results.values():
        m = row.get("metrics", {})
        cells = [(m, key.removesuffix("_ci_low")) for key in m if key.endswith("_top1_ci_low")]
        cells += [(row[s], "top1") for s in ("seen", "novel") if s in row]
        for table, key in cells:
            low, high = table.get(f"{key}_ci_low"), table.get(f"{key}_ci_high")
            if low is not None and high is not None and low == low and high == high:
                widths.append(float(high) - float(low))
    return sum(widths) / len(widths) if widths else None


def _intervals_note(results: Mapping[str, Any]) -> str:
    """What the intervals rest on, in the sentence defining the verdicts."""
    where, few = _few_fabrics(results)
    width = _mean_width(results)
    if not where:
        return "so a gap smaller than the intervals cannot be decided either way"
    text = f"here they rest on {where}" + (
        f" and are on average {width:.2f} wide" if width is not None else ""
    )
    text += ", so a smaller gap cannot be decided either way"
    if few:
        text += (
            f"; below {MIN_FABRICS} test fabrics they say little, as the bootstrap can only "
            "resample the few fabrics there are: an interval may be far narrower than the "
            "uncertainty"
        )
    return text


def _table_4(results: Mapping[str, Any]) -> list[str]:
    """Table 4 (depth to depth, seen and novel fabrics), its chance and counts, and notes."""
    lines = [
        "| model | seen top-1 | seen top-3 | novel top-1 | novel top-3 |",
        "|---|---|---|---|---|",
    ]
    notes = _Notes()
    for name, paper in TABLE_4.items():
        row = results.get(name, {})
        cells = []
        for side in ("seen", "novel"):
            got = row.get(side, {})
            for k in (1, 3):
                ours = got.get(f"top{k}")
                n_eff = _candidates(got)
                if ours is None:
                    cell = "-"
                elif ours != ours:
                    why = row.get("not_scored", {}).get(side, _UNMEASURED)
                    cell = notes.mark(why, f"{name} {side}")
                elif n_eff is not None and k >= n_eff:
                    why = (
                        f"top-{k} of {n_eff} candidates is always 1 (the {side} side has "
                        f"{n_eff} fabrics to offer, the paper 10)"
                    )
                    cell = notes.mark(why, f"{name} {side} top-{k}")
                else:
                    cell = f"{ours:.3f}"
                    if k == 1 and "top1_ci_low" in got:
                        cell += f" [{got['top1_ci_low']:.2f}, {got['top1_ci_high']:.2f}]"
                cells.append(cell + f" ({paper[f'{side}_top{k}']:.3f})")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    chance, counts = [], []
    for side in ("seen", "novel"):
        got = next((results[n][side] for n in TABLE_4 if side in results.get(n, {})), {})
        n_eff = _candidates(got)
        for k in (1, 3):
            chance.append("-" if n_eff is None else f"{min(k, n_eff) / n_eff:.3f}")
        queries = [
            f"{int(r[side]['n_fabrics'])} / {int(r[side]['n_queries'])}"
            for r in (results.get(n, {}) for n in TABLE_4)
            if "n_queries" in r.get(side, {})
        ]
        counts += [queries[0] if queries else "-"] * 2
    lines.append("| chance | " + " | ".join(chance) + " |")
    lines.append("| fabrics / queries | " + " | ".join(counts) + " |")
    return lines + notes.lines()


def _candidates(side: Mapping[str, Any]) -> int | None:
    """Candidates a draw offers on one side of Table 4 (``n_effective``, else 1 / chance)."""
    if "n_effective" in side:
        return int(side["n_effective"])
    chance = side.get("chance")
    return round(1 / chance) if chance else None


def write_reproduction_report(result: ReproduceResult, meta: Mapping[str, Any]) -> None:
    """Write ``report.md``: which fabrics each table scores on, tables with ours and (the
    paper's) numbers and notes on the cells without one, findings, skipped runs."""
    r = result.results
    where, few = _few_fabrics(r)
    lines = [
        "# Reproducing *Connecting Look and Feel* (CVPR 2017)",
        "",
        f"Data: `{meta['data']}`; budget: **{meta['budget']}**; seeds: {meta['seeds']}; "
        f"{meta['minutes']} min.",
        "",
        *_where_scored(result, meta),
        "Each cell: our top-1 accuracy of pick 1 of 10 (exact expectation over the draw), its 95% "
        "bootstrap interval over test fabrics (first seed), the spread over seeds when there are "
        "several, and (the paper's number); `fabrics / queries`: the test fabrics and queries "
        f"behind a row's numbers; {NOT_SCORED}^k: no number, note k under the table says why. "
        "Query modality first: `touch_to_depth` is a GelSight press matched against depth "
        "images. Touch inputs carry the model's number of presses (3 for the Multi-input Net).",
        "",
        "## Findings",
        "",
    ]
    if few:
        lines += [
            f"**The intervals rest on {where}: under {MIN_FABRICS}, they say little, and the "
            f"findings that rest on them get no verdict ({TOO_FEW}).**",
            "",
        ]
    lines += ["| finding (paper) | here | evidence |", "|---|---|---|"]
    for f in result.findings.values():
        lines.append(f"| {f['claim']} | **{verdict_text(f)}** | {f['detail']} |")
    too_few = any(f["verdict"] == TOO_FEW for f in result.findings.values())
    lines += [
        "",
        f"A finding is one or more comparisons of two of our numbers. It **{HOLDS}** when every "
        "comparison goes the paper's way with the two 95% intervals (over test fabrics) apart, "
        f"**{NOT_HOLD}** when one goes the other way with them apart, and is **{NOISE}** when "
        f"the intervals overlap ({_intervals_note(r)}; **{UNTESTED}**: its runs were skipped"
        + (
            f"; **{TOO_FEW}** (how many): no verdict, as an interval it rests on is over fewer "
            f"than {MIN_FABRICS} fabrics"
            if too_few
            else ""
        )
        + "). "
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
    lines += _table(r, TABLE_3, _TABLE_3_COLUMNS)
    lines += ["", "## Table 4: touch helps vision (depth to depth)", ""]
    lines += _table_4(r)
    if any(s in r.get(n, {}) for n in TABLE_4 for s in ("seen", "novel")):
        lines += [
            "",
            "Seen: the held-out fifth of the depth images of each fabric the run trains on; "
            "novel: fabrics it never trains on (which ones: see Test fabrics above).",
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
