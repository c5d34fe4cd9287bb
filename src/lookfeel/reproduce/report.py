"""The reproduction report: our numbers beside the paper's, and whether each finding holds."""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from lookfeel.atomic import atomic_write_text
from lookfeel.metrics.bootstrap import MIN_INTERVAL_FABRICS
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
EXPERIMENT_NAMES = (*MODEL_COLUMNS, "cross_modal_aug", "multi_input_aug", *TABLE_4)
"""The experiments behind the findings and tables."""


Interval = tuple[float, float, float]
"""A number and its 95% interval: (value, low, high); low = high = value when there is none."""

HOLDS, NOT_HOLD, NOISE, UNTESTED = "holds", "does not hold", "within noise", "not tested"
"""The verdicts a finding gets (`findings`)."""

TOO_FEW = "too few fabrics"
"""What a finding gets instead of a verdict when an interval it rests on is over fewer than
`MIN_FABRICS` fabrics (`findings`; the count is its ``fabrics``)."""

MIN_FABRICS = MIN_INTERVAL_FABRICS
"""Below this many test fabrics an interval over fabrics decides no finding (`TOO_FEW`), and
the report says its intervals say little (`lookfeel.metrics.bootstrap.MIN_INTERVAL_FABRICS`,
which says why)."""


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


def _shown(value: Interval) -> str:
    """``0.127 [0.09, 0.17]``, as the tables show a number with its interval (``0.127`` when
    it has none)."""
    v, lo, hi = value
    return f"{v:.3f}" if (lo, hi) == (v, v) else f"{v:.3f} [{lo:.2f}, {hi:.2f}]"


def _against(expected_above: Interval, other: Interval) -> bool:
    """Whether ``other`` is above ``expected_above`` beyond both intervals: the other way
    from the paper's, decided (equal values without intervals are not)."""
    return other[1] > expected_above[2]


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
    sides: list[int] | None,
    detail: str,
    reason: str = "",
    fabrics: Sequence[int | None] = (),
    overlap: str = "95% intervals overlap",
) -> dict[str, Any]:
    """The finding's verdict from its comparisons (`_side`, each the paper's way round);
    `TOO_FEW` instead when one of the intervals compared is over fewer than `MIN_FABRICS`
    (``fabrics``: how many each is over, None where not recorded), with the fewest;
    ``overlap``: what the evidence adds when it is `NOISE`."""
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
    return {"verdict": NOISE, "detail": f"{detail} ({overlap})"}


def verdict_text(finding: Mapping[str, Any]) -> str:
    """A finding's verdict as printed: ``holds``, ..., ``too few fabrics (4)``."""
    n = finding.get("fabrics")
    return f"{finding['verdict']} ({n})" if finding["verdict"] == TOO_FEW else finding["verdict"]


MEANS_NOTE = "the means' 95% intervals overlap"
"""What a finding that compares means over pairs (`_mean_interval`) adds when it is `NOISE`."""


def only_reason(only: Sequence[str]) -> str:
    """Why a run `lookfeel reproduce --only` left out has no numbers: ``not run (--only a, b)``."""
    return f"not run (--only {', '.join(only)})"


def findings(
    results: Mapping[str, Any], only: Sequence[str] | None = None
) -> dict[str, dict[str, Any]]:
    """Check each of the paper's findings (`PAPER_FINDINGS`) on our numbers.

    Each finding is one or more comparisons (Multi-input above Auxiliary, ...). A comparison is
    decided only when the two numbers' 95% intervals (over test fabrics) do not overlap: the
    finding ``holds`` when every comparison goes the paper's way so, ``does not hold`` when one
    goes the other way so, and is ``within noise`` otherwise. Numbers recorded without an
    interval are compared as they are. A finding one of whose intervals is over fewer than
    `MIN_FABRICS` fabrics gets no verdict but `TOO_FEW`, with the count as ``fabrics``: a
    bootstrap over so few fabrics can come out far narrower than the uncertainty.

    Two findings compare means over pairs (`_mean_interval`): within against across one
    modality, and colour augmentation (the paper's claims are about the pairs on average).
    Their verdict is the means'; a single pair that goes the other way beyond both intervals
    is named in the evidence (``detail``) but does not decide it.

    ``only``: the experiments `lookfeel reproduce --only` was asked for (None: all). A finding
    each of whose ways to be tested lacks a run --only left out (one not in ``results`` either)
    is ``not tested`` with `only_reason`; where its runs were asked for but not run (the data
    lacks a sense they need), the reason says what they need.
    """

    left_out = {r for r in EXPERIMENT_NAMES if only and r not in only and r not in results}

    def untested(ways: Iterable[tuple[str, ...]], reason: str) -> str:
        """``reason``, or `only_reason` when each of ``ways`` (the runs that together could
        test the finding) lacks a run that --only left out."""
        if only and all(any(run in left_out for run in way) for way in ways):
            return only_reason(only)
        return reason

    models = [(m,) for m in MODEL_COLUMNS]
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
        sides, detail, untested(models, "no model with touch and depth or colour"), fabrics
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
        why = untested([tuple(order)], f"not run: {', '.join(missing)}")
        out["model_order"] = _verdict(None, "", why)
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
    why = untested(models, "no model with touch, depth and colour")
    out["depth_beats_color"] = _verdict(sides, "; ".join(rows), why, fabrics)
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
            named = dict(zip(TABLE_2, within, strict=True)) | dict(zip(across, other, strict=True))
            cells = {p: x for p, x in named.items() if x is not None and x[0] == x[0]}
            wrong = []  # each within pair below an across one beyond both intervals
            for w in TABLE_2:
                above = [p for p in across if p in cells and w in cells]
                above = [p for p in above if _against(cells[w], cells[p])]
                if above:
                    top = max(above, key=lambda p: cells[p][0])
                    wrong.append(f"{w} {_shown(cells[w])} below {top} {_shown(cells[top])}")
            against = f"; went the other way beyond both intervals: {', '.join(wrong)}"
            rows.append(
                f"{m}: within {_shown(mw)} vs across {_shown(ma)} (means"
                + (against if wrong else "")
                + ")"
            )
            fabrics += [_cell_fabrics(results, m, p) for p in (*TABLE_2, *across)]
    why = untested(models, "no model scored within and across modalities")
    out["within_beats_across"] = _verdict(sides, "; ".join(rows), why, fabrics, MEANS_NOTE)
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
            up, wrong = 0, []
            for pair, x, y in zip(_COLOR_PAIRS, a, b, strict=True):
                if x is not None and y is not None:
                    up += y[0] > x[0]
                    if _against(y, x):
                        wrong.append(f"{pair} {_shown(x)} -> {_shown(y)}")
            against = f"; went the other way beyond both intervals: {', '.join(wrong)}"
            rows.append(
                f"{base}: {_shown(ma)} -> {_shown(mb)} with augmentation (means of the colour "
                f"pairs; {up} of {len(a)} up, the paper: all" + (against if wrong else "") + ")"
            )
    why = untested(
        [(m, m + "_aug") for m in ("cross_modal", "multi_input")], "augmentation runs not run"
    )
    out["augmentation_helps_color"] = _verdict(sides, "; ".join(rows), why, fabrics, MEANS_NOTE)
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
    reason = untested(
        [tuple(TABLE_4)],
        "no side with two held-out items per fabric"
        if "snn_depth" in results and "cross_modal_depth_touch" in results
        else "needs both Table 4 runs (depth and touch data)",
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
    """The notes under one table: each distinct reason a cell is n/a (or ``-``: its run was not
    run), numbered in order."""

    def __init__(self) -> None:
        self.cells: dict[str, list[str]] = {}
        """reason -> the cells it explains (``"multi_input touch_to_touch"``)."""

    def mark(self, reason: str, cell: str, shown: str = NOT_SCORED) -> str:
        """``shown`` with the number of ``reason``'s note (``n/a^1``), ``cell`` listed there."""
        cells = self.cells.setdefault(reason, [])
        if cell not in cells:
            cells.append(cell)
        return f"{shown}^{list(self.cells).index(reason) + 1}"

    def lines(self) -> list[str]:
        """The notes, one list item each: which cells, and why."""
        out = [""] if self.cells else []
        for i, (reason, cells) in enumerate(self.cells.items(), 1):
            out.append(f"- ^{i} {', '.join(cells)}: {reason}.")
        return out


def _unrun_reasons(result: ReproduceResult, only: Sequence[str] | None) -> dict[str, str]:
    """Why each experiment of the tables that has no numbers was not run: left out by
    ``--only`` (`only_reason`), or skipped (the data cannot serve it)."""
    names = [r for r in EXPERIMENT_NAMES if r not in result.results]
    out = {r: only_reason(only) for r in names if only and r not in only}
    return out | {r: "skipped (see Skipped below)" for r in names if r in result.skipped}


def _cell(
    results: Mapping[str, Any],
    model: str,
    pair: str,
    paper: float | None,
    notes: _Notes,
    unrun: Mapping[str, str],
) -> str:
    row = results.get(model, {})
    m = row.get("metrics")
    why = unrun.get(model)
    if why is not None:
        ours = notes.mark(why, model, "-")
    elif m is None or f"{pair}_top1" not in m:
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
    results: Mapping[str, Any],
    table: Mapping[str, Mapping[str, float]],
    columns: tuple[str, ...],
    unrun: Mapping[str, str],
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
        cells = [_cell(results, m, pair, paper.get(m), notes, unrun) for m in columns]
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


_CONTROL_ROWS = (
    ("top{k}_swapped", "{name}, background swapped", "background swapped", "swapped"),
    ("top{k}_room", "{name}, in another fabric's room", "in another room", "swapped"),
    ("raw_pixels_top{k}", "raw pixels, {name}'s queries", "raw pixels", "raw_pixels"),
    (
        "raw_pixels_top{k}_swapped",
        "raw pixels, {name}'s queries, background swapped",
        "raw pixels background swapped",
        "swapped",
    ),
    (
        "raw_pixels_top{k}_room",
        "raw pixels, {name}'s queries, in another fabric's room",
        "raw pixels in another room",
        "swapped",
    ),
)
"""The rows under each model of Table 4 (`lookfeel.reproduce.run.CONTROL_KEYS`): the key of
its numbers on a side, its label, what a note calls it, and the ``not_scored`` key
(``{side}_{...}``) of why it is NaN. The room rows are there for registered depth only
(`lookfeel.data.background_swap`)."""

CONTROLS_NOTE = (
    "Under each model, on the same queries: the model with each depth image's background "
    "replaced by that of an image of another fabric, the cloth kept (background swapped), and "
    "raw pixels (the preprocessed depth images themselves, matched as they are). A model that "
    "reads the cloth, not the room, keeps its score when the background is swapped; raw pixels "
    "show what the pixels alone give. On GelFabric each fabric was captured in its own "
    "session, so the room behind the cloth can identify the fabric."
)
"""What Table 4's control rows mean, under the table."""


def _side_cell(
    row: Mapping[str, Any],
    name: str,
    side: str,
    key: str,
    k: int,
    notes: _Notes,
    control: tuple[str, str] | None = None,
) -> str:
    """One cell of Table 4: ``row[side][key]`` (top-``k``) with its interval and, over several
    seeds, ±its standard deviation over them (as `_cell` shows Tables 1-3's), or ``-`` when
    not recorded, or n/a with a note saying why. An interval that could not be had is
    ``[n/a^k]``, its reason under ``not_scored`` (``{side}_{key}_interval``). ``control``: for
    a control row, its label and the ``not_scored`` key of its reason; a control is NaN for
    the side's own reason when the model's number is."""
    got = row.get(side, {})
    ours = got.get(key)
    n_eff = _candidates(got)
    not_scored = row.get("not_scored", {})
    if ours is None:
        return "-"
    if ours != ours:
        if control is None or got.get(f"top{k}") != got.get(f"top{k}"):
            return notes.mark(not_scored.get(side, _UNMEASURED), f"{name} {side}")
        label, why = control
        return notes.mark(not_scored.get(why, _UNMEASURED), f"{name} {side} {label}")
    if n_eff is not None and k >= n_eff:
        why = (
            f"top-{k} of {n_eff} candidates is always 1 (the {side} side has "
            f"{n_eff} fabrics to offer, the paper 10)"
        )
        return notes.mark(why, f"{name} {side} top-{k}")
    cell = f"{ours:.3f}"
    low, high = got.get(f"{key}_ci_low"), got.get(f"{key}_ci_high")
    if low is not None and high is not None:
        if low == low and high == high:
            cell += f" [{low:.2f}, {high:.2f}]"
        else:  # NaN: a run of an earlier lookfeel recorded none
            why = not_scored.get(f"{side}_{key}_interval", _UNMEASURED)
            cell += f" [{notes.mark(why, f'{name} {side} top-{k} interval')}]"
    spread = row.get(f"{side}_spread", {}).get(key)
    if spread and row.get("seeds", 1) > 1:
        cell += f" ±{spread:.3f}"
    return cell


def _table_4(results: Mapping[str, Any], unrun: Mapping[str, str]) -> list[str]:
    """Table 4 (depth to depth, seen and novel fabrics): each model with its raw pixels and
    background control under it (`_CONTROL_ROWS`), chance and counts, and notes."""
    lines = [
        "| model | seen top-1 | seen top-3 | novel top-1 | novel top-3 |",
        "|---|---|---|---|---|",
    ]
    notes = _Notes()
    controls = False
    for name, paper in TABLE_4.items():
        row = results.get(name, {})
        cells = []
        for side in ("seen", "novel"):
            for k in (1, 3):
                unscored = unrun.get(name)
                if unscored is not None:
                    cell = notes.mark(unscored, name, "-")
                else:
                    cell = _side_cell(row, name, side, f"top{k}", k, notes)
                cells.append(cell + f" ({paper[f'{side}_top{k}']:.3f})")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
        if name in unrun:
            continue
        for key, label, what, why in _CONTROL_ROWS:
            if not any(key.format(k=1) in row.get(side, {}) for side in ("seen", "novel")):
                continue
            controls = True
            cells = [
                _side_cell(row, name, side, key.format(k=k), k, notes, (what, f"{side}_{why}"))
                for side in ("seen", "novel")
                for k in (1, 3)
            ]
            lines.append(f"| {label.format(name=name)} | " + " | ".join(cells) + " |")
    chance, counts = [], []
    for side in ("seen", "novel"):
        had = [results[n] for n in TABLE_4 if side in results.get(n, {})]
        scored = [r[side] for r in had if _scored(r[side])]
        n_eff = _candidates(scored[0]) if scored else None
        for k in (1, 3):
            if had and not scored:  # no query, so no pick and no chance: the side's reason
                why = had[0].get("not_scored", {}).get(side, _UNMEASURED)
                chance.append(notes.mark(why, f"{side} chance"))
            else:
                chance.append("-" if n_eff is None else f"{min(k, n_eff) / n_eff:.3f}")
        queries = [
            f"{int(r[side]['n_fabrics'])} / {int(r[side]['n_queries'])}"
            for r in (results.get(n, {}) for n in TABLE_4)
            if "n_queries" in r.get(side, {})
        ]
        counts += [queries[0] if queries else "-"] * 2
    lines.append("| chance | " + " | ".join(chance) + " |")
    lines.append("| fabrics / queries | " + " | ".join(counts) + " |")
    return lines + (["", CONTROLS_NOTE] if controls else []) + notes.lines()


def _scored(side: Mapping[str, Any]) -> bool:
    """Whether one side of a Table 4 run has a number: a query was scored there."""
    top1 = side.get("top1")
    return top1 is not None and top1 == top1


def _candidates(side: Mapping[str, Any]) -> int | None:
    """Candidates a draw offers on one side of Table 4 (``n_effective``, else 1 / chance)."""
    if "n_effective" in side:
        return int(side["n_effective"])
    chance = side.get("chance")
    return round(1 / chance) if chance else None


def _pick(results: Mapping[str, Any]) -> str:
    """``pick 1 of 10``, or of the candidates a draw has (``n_effective``) where the test
    fabrics offer fewer than 10: ``pick 1 of 6 (the paper's pick 1 of 10, but ...)``."""
    parts: list[tuple[list[int], str]] = []
    held = []
    for run in _SCORED_ON_HELD_OUT:
        m = results.get(run, {}).get("metrics", {})
        for key, n in m.items():
            top1 = m.get(key.removesuffix("_n_effective") + "_top1")
            if key.endswith("_n_effective") and top1 is not None and top1 == top1:
                held.append(round(n))
    if held:
        parts.append((held, "Tables 1-3"))
    for side in ("seen", "novel"):  # a side where no query was scored picks from none
        sides = [results[n][side] for n in TABLE_4 if side in results.get(n, {})]
        got = [_candidates(s) for s in sides if _scored(s)]
        counts = [n for n in got if n is not None]
        if counts:
            parts.append((counts, f"Table 4's {side} side"))
    if all(min(counts) >= 10 for counts, _ in parts):
        return "pick 1 of 10"
    spans = [(_span(counts), where) for counts, where in parts]
    if len({span for span, _ in spans}) == 1:
        return (
            f"pick 1 of {spans[0][0]} (the paper's pick 1 of 10, but the test fabrics offer "
            f"only {spans[0][0]} candidates a draw)"
        )
    here = ", ".join(f"1 of {span} on {where}" for span, where in spans)
    return (
        "pick 1 of as many candidates as the test fabrics offer, up to the paper's 10 (here "
        f"{here})"
    )


def _seeds(meta: Mapping[str, Any]) -> str:
    """The seeds a reproduction trained: their count, and which where they are not 0..N-1
    (``seed_list``, kept since ``reproduce --seeds`` took a list; an older results.json has
    the count only)."""
    count, given = meta.get("seeds", 1), meta.get("seed_list")
    if not isinstance(given, list) or given == list(range(len(given))):
        return str(count)
    return f"{count} ({', '.join(str(s) for s in given)})"


def _what_a_cell_is(results: Mapping[str, Any], seeds: int, n_boot: int = 1) -> str:
    """The sentence on what a cell of the tables shows: with several seeds, each number and
    each interval bound is the mean over the seeds (`lookfeel.reproduce.run`'s aggregate);
    with ``n_boot`` 0 (``--n-boot 0``) no interval."""
    pick = (
        "top-1 accuracy (top-1 or top-3 in Table 4's columns; exact expectation over the draw) "
        f"of {_pick(results)}"
    )
    interval = (
        "its 95% bootstrap interval over test fabrics"
        if n_boot
        else "no interval (--n-boot 0: none was drawn)"
    )
    if seeds <= 1:
        return f"Each cell: our {pick}, {interval}"
    bounds = f" (each bound the mean over the {seeds} seeds of that seed's interval)"
    return (
        f"Each cell: the mean over the {seeds} seeds of our {pick}, {interval}"
        + (bounds if n_boot else "")
        + ", ±the standard deviation over the seeds"
    )


def _earlier(meta: Mapping[str, Any]) -> str:
    """`` (and flat from finished runs of an earlier reproduction in this folder)``: the
    experiments ``--only`` left out that the report shows all the same (``meta["earlier"]``)."""
    earlier = meta.get("earlier") or []
    if not earlier:
        return ""
    return f" (and {', '.join(earlier)} from finished runs of an earlier reproduction here)"


def _time_behind(meta: Mapping[str, Any]) -> str:
    """The header's time: the work behind the numbers (``runs``, ``run_minutes``: each run's
    training and scoring, resumes included) beside this reproduction's own minutes, which a
    reproduction that found its runs finished spends almost none of."""
    if meta.get("runs") is None or meta.get("run_minutes") is None:
        return f"{meta['minutes']} min."
    n = int(meta["runs"])
    return (
        f"{n} run{'' if n == 1 else 's'} behind these numbers, {meta['run_minutes']} min of "
        f"training and scoring; this reproduction {meta['minutes']} min."
    )


def _data_root(meta: Mapping[str, Any]) -> str:
    """The dataset folder ``meta`` names: ``data_root``, or ``data`` as results.json named it
    before lookfeel named it as index info and cv do."""
    return str(meta["data_root"] if "data_root" in meta else meta["data"])


def write_reproduction_report(result: ReproduceResult, meta: Mapping[str, Any]) -> None:
    """Write ``report.md``: which fabrics each table scores on, tables with ours and (the
    paper's) numbers and notes on the cells without one, findings, skipped runs.

    ``meta["only"]``: the experiments ``--only`` ran (absent or None: all were asked for); the
    header names them, and the cells of the runs it left out say so in a note."""
    r = result.results
    where, few = _few_fabrics(r)
    only = meta.get("only") or None
    unrun = _unrun_reasons(result, only)
    lines = [
        "# Reproducing *Connecting Look and Feel* (CVPR 2017)",
        "",
        f"Data: `{_data_root(meta)}`; budget: **{meta['budget']}**; seeds: {_seeds(meta)}; "
        + (f"--only: {', '.join(only)}{_earlier(meta)}; " if only else "")
        + _time_behind(meta),
        "",
        *_where_scored(result, meta),
        f"{_what_a_cell_is(r, int(meta.get('seeds', 1)), int(meta.get('n_boot', 1)))}, and (the "
        "paper's number); "
        "`fabrics / queries`: the test fabrics and queries behind a row's numbers; "
        f"{NOT_SCORED}^k: no number, note k under the table says why"
        + ("; -^k: the column's run was not run, note k says why" if unrun else "")
        + ". Query modality first: `touch_to_depth` is a GelSight press matched against depth "
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
    untested = (
        f"a run it needs was {only_reason(only)}" + (" or was skipped" if result.skipped else "")
        if only
        else "its runs were skipped"
    )
    lines += [
        "",
        f"A finding is one or more comparisons of two of our numbers. It **{HOLDS}** when every "
        "comparison goes the paper's way with the two 95% intervals (over test fabrics) apart, "
        f"**{NOT_HOLD}** when one goes the other way with them apart, and is **{NOISE}** when "
        f"the intervals overlap ({_intervals_note(r)}; **{UNTESTED}**: {untested}"
        + (
            f"; **{TOO_FEW}** (how many): no verdict, as an interval it rests on is over fewer "
            f"than {MIN_FABRICS} fabrics"
            if too_few
            else ""
        )
        + "). "
        "Two findings compare means over pairs: within against across one modality (the mean "
        "of the Table 2 pairs against that of the pairs across), and colour augmentation (the "
        "mean of the four pairs with colour before and after); each mean's interval is the mean "
        "of its pairs' bounds, and the verdict is the means', as the paper's claims are about "
        "the pairs on average. A single pair that goes the other way beyond both intervals is "
        "named in the evidence but does not decide the verdict. "
        "The paper's numbers are from real fabrics, AlexNets with ImageNet weights and 25,000 "
        "steps; a short run on a synthetic world is not expected to reach them, only to show "
        "whether their order holds.",
    ]
    lines += ["", "## Figure 7 and Table 1: matching across modalities", ""]
    cross = {"touch_to_depth": {}, "touch_to_color": {}, **TABLE_1}
    lines += _table(r, cross, MODEL_COLUMNS, unrun)
    lines += ["", "## Table 2: matching within a modality", ""]
    lines += _table(r, TABLE_2, MODEL_COLUMNS, unrun)
    lines += ["", "## Table 3: colour augmentation", ""]
    lines += _table(r, TABLE_3, _TABLE_3_COLUMNS, unrun)
    lines += ["", "## Table 4: touch helps vision (depth to depth)", ""]
    lines += _table_4(r, unrun)
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
