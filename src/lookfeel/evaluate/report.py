"""Write an evaluation to a folder: ``metrics.json`` (its provenance in ``info``, then every
metric; `write_metrics`), ``report.md`` and ``figures/*.png``."""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import NDArray

from lookfeel.atomic import atomic_write_text
from lookfeel.config import DataConfig
from lookfeel.data import ImageError, ImageLoader
from lookfeel.metrics.bootstrap import MIN_INTERVAL_FABRICS
from lookfeel.metrics.properties import MIN_SPEARMAN
from lookfeel.modality import Modality, Pair
from lookfeel.plots import (
    GlanceLook,
    GlanceRow,
    PickRow,
    confusion_figure,
    glance_figure,
    pick_examples_figure,
    presses_figure,
    reliability_figure,
    save_figure,
)

from .result import CalibrationResult, EvalResult, GlanceExample, PickExample, PressCurve

__all__ = ["ReportFiles", "selection_note", "summary_lines", "write_metrics", "write_report"]

_ARROW = "→"

FEW_MARK = "†"
"""Marks an interval over fewer test fabrics (or objects) than
`lookfeel.metrics.bootstrap.MIN_INTERVAL_FABRICS`, the rule ``reproduce`` and ``cv`` give their
own intervals: the bootstrap resamples only those few, so the interval may be far narrower than
the uncertainty (test fabrics that all score alike give one of width 0), or far wider, and
tells little of how another fabric would fare. The report says so under each table with such a
mark (`_few_lines`), the printed summary beside the pair (`summary_lines`)."""
FEW_FIT_FABRICS = 10
"""A c fitted on fewer reference (training) fabrics than this is flagged in the calibration
table: they are the fabrics the model was trained on, and so few it tells apart far better than
new ones, so a c fitted on them comes out larger than the test fabrics support."""


@dataclass(frozen=True)
class ReportFiles:
    """What `write_report` wrote."""

    metrics: Path
    report: Path
    figures: tuple[Path, ...]


def _json_value(v: float) -> float | None:
    return None if isinstance(v, float) and not math.isfinite(v) else v


METRICS_INFO = (
    "checkpoint",
    "step",
    "embeddings_file",
    "split",
    "data_root",
    "data_fingerprint",
    "software",
)
"""What ``metrics.json``'s ``info`` records of an evaluation's provenance (`EvalResult.info`),
each where it is known: the checkpoint and its step (or the embeddings file scored), the
split, the dataset folder and fingerprint (`lookfeel.data.Catalog.fingerprint`) and the
software versions that embedded it (`lookfeel.provenance.software_versions`)."""


def write_metrics(result: EvalResult, path: str | os.PathLike[str]) -> Path:
    """Write ``metrics.json`` atomically: ``info``, an object naming what was scored (the
    `METRICS_INFO` keys ``result.info`` holds; none for an evaluation of bare embeddings),
    then every metric, flat, each a number or null (NaN and infinity). No metric is named
    ``info``: a reader of the numbers leaves that one key out."""
    info = {k: result.info[k] for k in METRICS_INFO if k in result.info}
    data: dict[str, Any] = {"info": info}
    data |= {k: _json_value(float(v)) for k, v in result.metrics.items()}
    return atomic_write_text(path, json.dumps(data, indent=1, default=str) + "\n")


def _f(v: float | None, digits: int = 3) -> str:
    if v is None or not math.isfinite(v):
        return "–"
    if abs(v) < 0.5 * 10.0**-digits:
        v = 0.0  # never "-0.000"
    return f"{v:.{digits}f}"


def _ci(m: dict[str, float], key: str, digits: int = 3) -> str:
    lo, hi = m.get(f"{key}_ci_low"), m.get(f"{key}_ci_high")
    if lo is None or hi is None or not (math.isfinite(lo) and math.isfinite(hi)):
        return "–"
    return f"{lo:.{digits}f} – {hi:.{digits}f}"


def _n_fabrics(result: EvalResult, pair: Pair) -> int | None:
    """The test fabrics (objects) whose queries ``pair`` scored; None when unknown."""
    v = result.metrics.get(f"{pair}_n_fabrics")
    return int(v) if v is not None and math.isfinite(v) else None


def _few(result: EvalResult, pair: Pair) -> bool:
    """Whether ``pair``'s intervals rest on fewer than `MIN_INTERVAL_FABRICS` test fabrics."""
    n = _n_fabrics(result, pair)
    return n is not None and n < MIN_INTERVAL_FABRICS


def _pci(result: EvalResult, pair: Pair, key: str, digits: int = 3) -> str:
    """`_ci` of ``key``, marked `FEW_MARK` when ``pair``'s queries come from too few fabrics."""
    text = _ci(result.metrics, key, digits)
    return f"{text} {FEW_MARK}" if text != "–" and _few(result, pair) else text


def _with_ci(result: EvalResult, pair: Pair, key: str) -> str:
    """``0.583 (0.500 – 0.667)``: a value and its interval; ``–`` when there is none."""
    m = result.metrics
    if key not in m:
        return "–"
    ci = _pci(result, pair, key)
    return _f(m[key]) if ci == "–" else f"{_f(m[key])} ({ci})"


def _few_lines(result: EvalResult, pairs: Sequence[Pair]) -> list[str]:
    """The rule of `MIN_INTERVAL_FABRICS`, stated under a table whose intervals it marks."""
    counts = sorted({n for p in pairs if (n := _n_fabrics(result, p)) is not None})
    few = [n for n in counts if n < MIN_INTERVAL_FABRICS]
    if not few:
        return []
    unit = result.unit
    over = " or ".join(str(n) for n in few)
    return [
        f"{FEW_MARK} Over {over} test {unit}s only: under {MIN_INTERVAL_FABRICS}, an interval "
        f"says little, as the bootstrap can only resample the few test {unit}s there are: it "
        f"may be far narrower than the uncertainty (test {unit}s that all score alike give an "
        f"interval of width 0), or far wider, and tells little of another {unit}. Hold out "
        f"{MIN_INTERVAL_FABRICS} or more (or cross-validate, `lookfeel cv`) for one that says "
        "more.",
        "",
    ]


def _pretty(pair: Pair) -> str:
    return f"{pair.query.value} {_ARROW} {pair.gallery.value}"


def _table(header: list[str], rows: list[list[str]]) -> list[str]:
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    return [*out, ""]


def _n_effective(result: EvalResult, pair: Pair) -> int:
    """Candidates each pick of ``pair`` offered (fewer than the protocol's n when fewer test
    fabrics were there to offer)."""
    v = result.metrics.get(f"{pair}_n_effective")
    return int(v) if v is not None and math.isfinite(v) else result.config.n


def _pair_rows(result: EvalResult, pair: Pair) -> list[list[str]]:
    m, cfg = result.metrics, result.config
    p = f"{pair}_"
    rows = []
    n_eff = _n_effective(result, pair)
    for k in cfg.ks:
        key = f"{p}top{k}"
        chance = _f(m.get(f"{key}_chance"))
        rows.append(
            [f"top-{k} of {n_eff} (exact)", _f(m.get(key)), _pci(result, pair, key), chance]
        )
        raw = f"{p}raw_pixels_top{k}"
        if raw in m:
            rows.append(
                [
                    f"top-{k} of {n_eff}, raw pixels (exact)",
                    _f(m[raw]),
                    _pci(result, pair, raw),
                    chance,
                ]
            )
        if f"{key}_sampled" in m:
            rows.append(
                [
                    f"top-{k} of {n_eff} (sampled, paper)",
                    f"{_f(m.get(f'{key}_sampled'))} ± {_f(m.get(f'{key}_sampled_se'))} (se)",
                    "",
                    chance,
                ]
            )
        if f"{key}_released" in m:
            rows.append(
                [
                    f"top-{k} of {n_eff} (released code's variant)",
                    f"{_f(m.get(f'{key}_released'))} ± {_f(m.get(f'{key}_released_se'))} (se)",
                    "",
                    "≈ " + chance,
                ]
            )
    rows.append(
        [
            "mAP (whole gallery)",
            _f(m.get(f"{p}map")),
            _pci(result, pair, f"{p}map"),
            _f(m.get(f"{p}map_chance")),
        ]
    )
    for k in cfg.recall_ks:
        key = f"{p}recall{k}"
        rows.append(
            [f"recall@{k}", _f(m.get(key)), _pci(result, pair, key), _f(m.get(f"{key}_chance"))]
        )
    key = f"{p}median_rank"
    rows.append(
        [
            "median rank of the first true item",
            _f(m.get(key), 1),
            _pci(result, pair, key, 1),
            _f(m.get(f"{key}_chance"), 1),
        ]
    )
    rows.append(
        [
            f"queries / test {result.unit}s / candidates per pick",
            f"{_f(m.get(f'{p}n_queries'), 0)} / {_f(m.get(f'{p}n_fabrics'), 0)} / {n_eff}",
            "",
            "",
        ]
    )
    return rows


def _pick_text(result: EvalResult) -> tuple[str, str]:
    """The pick section's heading and what it did: the candidates each pick actually offered
    (every test fabric when there are fewer than the protocol's n), named as the data names
    what it tells apart (fabrics, or objects)."""
    cfg, unit = result.config, result.unit
    scored = [p for p in result.pairs if p not in result.not_scored] or list(result.pairs)
    used = sorted({_n_effective(result, p) for p in scored})
    n = used[0] if len(used) == 1 else None
    heading = f"Pick 1 of {n}" if n is not None else f"Pick 1 of {used[0]} to {used[-1]}"
    if n == cfg.n:
        offered = (
            f"A query is shown {n} candidates of the gallery modality: one item of its own "
            f"{unit} and one of each of {n - 1} other {unit}s drawn at random."
        )
    elif n is not None:
        others = f"the other test {unit}" if n == 2 else f"each of the {n - 1} other test {unit}s"
        offered = (
            f"A query is shown {n} candidates of the gallery modality: one item of its own "
            f"{unit} and one of {others} (the protocol's pick 1 of {cfg.n} needs {cfg.n} test "
            f"{unit}s; with {n}, every one is offered and chance top-1 is 1/{n})."
        )
    else:
        offered = (
            f"A query is shown one item of its own {unit} and one of each of up to {cfg.n - 1} "
            f"other {unit}s drawn at random: as many candidates as the gallery has test "
            f"{unit}s, up to {cfg.n} (each pair's are in its table below)."
        )
    across = any(not p.same for p in result.pairs)
    text = (
        f"{offered} *Exact* is the expectation of this draw computed from the whole distance "
        f"matrix; *sampled* is the paper's protocol ({cfg.queries_per_fabric} queries per "
        f"{unit}, {cfg.repeats} draws each, seed {cfg.seed}). *Raw pixels*: the same queries "
        "matched on the preprocessed images themselves (the network's input; a pooled touch "
        "query the mean of its presses' pixels), for pairs of one modality"
        + (" (no pixel of a drape corresponds to one of a press)" if across else "")
        + f". Intervals: {100 * (1 - cfg.alpha):.0f}% "
        f"percentile bootstrap over test {unit}s ({cfg.n_boot} resamples). Same-modality pairs "
        "never offer the query's own item."
    )
    return heading, text


def _section_pick(result: EvalResult) -> list[str]:
    cfg, m = result.config, result.metrics
    k0 = cfg.ks[0]
    heading, text = _pick_text(result)
    lines = [f"## {heading} (paper section 5.1, Figure 7, Tables 1-2)", "", text, ""]
    rows = []
    for pair in result.pairs:
        p = f"{pair}_top{k0}"
        rows.append(
            [
                _pretty(pair),
                "not scored" if pair in result.not_scored else _f(m.get(p)),
                _pci(result, pair, p),
                _with_ci(result, pair, f"{pair}_raw_pixels_top{k0}"),
                _f(m.get(f"{p}_sampled")),
                _f(m.get(f"{pair}_top{cfg.ks[-1]}")) if len(cfg.ks) > 1 else "–",
                _f(m.get(f"{p}_chance")),
                _f(m.get(f"{pair}_map")),
                _f(m.get(f"{pair}_map_chance")),
                f"{_f(m.get(f'{pair}_n_queries'), 0)} / {_f(m.get(f'{pair}_n_fabrics'), 0)}",
            ]
        )
    top_last = f"top-{cfg.ks[-1]}" if len(cfg.ks) > 1 else "–"
    lines += _table(
        [
            "pair",
            f"top-{k0}",
            "95% interval",
            f"raw pixels top-{k0} (95% interval)",
            f"top-{k0} sampled",
            top_last,
            f"chance top-{k0}",
            "mAP",
            "chance mAP",
            f"queries / {result.unit}s",
        ],
        rows,
    )
    lines += _few_lines(result, result.pairs)
    for pair, why in result.not_scored.items():
        lines += [f"Not scored: {_pretty(pair)}: {why}.", ""]
    for pair in result.pairs:
        lines += [f"### {_pretty(pair)}", ""]
        if pair in result.not_scored:
            lines += [f"Not scored: {result.not_scored[pair]}.", ""]
            continue
        lines += _table(["metric", "value", "95% interval", "chance"], _pair_rows(result, pair))
    return lines


def selection_note(info: Mapping[str, Any]) -> str | None:
    """What an evaluation says of a checkpoint scored on the fabrics it was chosen on: a run's
    ``best.pt`` (chosen as the best by its validation top-1) scored on the run's validation
    fabrics (or held-out items), its scores there optimistic. ``info``: an evaluation's
    provenance, whose ``selected_on`` (`lookfeel.evaluate.from_checkpoint._chosen_on`) says
    how many of the test fabrics (items) it was chosen on; None when none."""
    chosen = info.get("selected_on")
    if not isinstance(chosen, Mapping) or not chosen.get("shared"):
        return None
    shared, of, unit = int(chosen["shared"]), int(chosen.get("of", 0)), str(chosen["unit"])
    name = Path(str(info.get("checkpoint", "best.pt"))).name
    step = chosen.get("step", info.get("step", "?"))
    picked = (
        f"this checkpoint ({name}, step {step}) was chosen as the run's best by its "
        "validation top-1"
    )
    seen = unit == "items"
    held = "the run's held-out items" if seen else f"the run's validation {unit}"
    if shared >= of:
        said = f"{picked} on these same {unit}" + (f" ({held})" if seen else "")
    else:
        said = f"{shared} of these {of} test {unit} are {held}, on which {picked}"
    never = "fabrics" if seen else unit
    return (
        f"{said}, so its scores here are optimistic: evaluate last.pt for an unbiased score "
        f"(the same where best.pt is of the run's last step), or {never} the run never saw"
    )


def _bracket(m: dict[str, float], key: str) -> str:
    """``0.583 [0.500, 0.667]``, or the value alone when it has no interval."""
    v, lo, hi = m[key], m.get(f"{key}_ci_low"), m.get(f"{key}_ci_high")
    if lo is None or hi is None or not (math.isfinite(lo) and math.isfinite(hi)):
        return _f(v)
    return f"{_f(v)} [{_f(lo)}, {_f(hi)}]"


_CONTROLS = (
    ("_swapped", "background swapped"),
    ("_room", "in another fabric's room"),
    ("_untouched", "untouched"),
)
"""The controls' key suffixes (`lookfeel.evaluate.controls`) and how the printed lines name
them."""


def _control_line(m: dict[str, float], whose: str, key: str, with_main: bool) -> str | None:
    """``raw pixels 0.917 [0.833, 1.000], background swapped 0.583 [0.500, 0.667]``: one
    scorer's numbers (``key``: its top-k; ``with_main``: that score too) under each control
    that ran for it, each with its interval; None when there is nothing to add."""
    said = [f"{name} {_bracket(m, key + sfx)}" for sfx, name in _CONTROLS if key + sfx in m]
    if with_main and key in m:
        return ", ".join([f"{whose} {_bracket(m, key)}", *said])
    return f"{whose}, " + ", ".join(said) if said else None


def summary_lines(result: EvalResult) -> list[str]:
    """What `lookfeel evaluate` prints: each pair's first top-k with its interval, the queries
    and test fabrics it rests on (an interval over fewer than `MIN_INTERVAL_FABRICS` said to say
    little) and chance; under it, one line per scorer, each number named as whose it is and
    with its interval: the model under the background and untouched controls, the
    cross-modal map (and it under the controls) and raw pixels (and they under the controls),
    where they ran. A pair none of whose queries could be scored says why instead
    (`EvalResult.not_scored`). A checkpoint scored on the fabrics it was chosen on says so
    first (`selection_note`)."""
    m, k = result.metrics, result.config.ks[0]
    unit = result.unit
    lines = [f"Evaluated {result.info.get('split_description', 'the embeddings')}:"]
    chosen = selection_note(result.info)
    if chosen:
        lines.append(f"  Note: {chosen}.")
    indent = " " * 21  # under the pair's first number
    for pair in result.pairs:
        if pair in result.not_scored:
            lines.append(f"  {pair!s:<16} not scored: {result.not_scored[pair]}")
            continue
        key = f"{pair}_top{k}"
        n_q, n_f = m.get(f"{pair}_n_queries"), _n_fabrics(result, pair)
        basis = f"{_f(n_q, 0)} queries, {n_f} {unit}{'s' if n_f != 1 else ''}"
        if _few(result, pair):
            basis += ": too few for the interval to say much"
        text = (
            f"top-{k} {_bracket(m, key)} ({basis})  chance {m.get(f'{key}_chance', math.nan):.3f}"
        )
        lines.append(f"  {pair!s:<16} {text}")
        more = [
            _control_line(m, "model", key, with_main=False),
            _control_line(m, "through the cross-modal map", f"{key}_mapped", with_main=True),
            _control_line(m, "raw pixels", f"{pair}_raw_pixels_top{k}", with_main=True),
        ]
        lines += [indent + line for line in more if line]
    return lines


def _section_control(result: EvalResult) -> list[str]:
    """The background control beside the scores as they are (when it ran), and the room
    control (registered depth) when it ran too; model and raw pixels, each with its
    interval."""
    m, ks = result.metrics, result.config.ks
    pairs = [p for p in result.pairs if f"{p}_top{ks[0]}_swapped" in m]
    if not pairs:
        return []
    room = any(f"{p}_top{ks[0]}_room" in m for p in pairs)
    unit = result.unit
    lines = [
        "## Background control",
        "",
        f"The same queries with every test depth image's background (room, wall, floor) "
        f"replaced by another {unit}'s, the cloth kept; touch queries pool the same presses "
        "as above. A model that reads the cloth, not the capture session, scores the same; "
        "raw pixels show how much the room alone carries.",
        "",
    ]
    if room:
        lines[-1:-1] = [
            "",
            "Registered depth also gets the room control: each test depth image registered, "
            f"as it was taken, in the room fitted on that other {unit}'s own image (no room "
            "refitted on a composite image).",
        ]
    names = ["", "_swapped", "_room"] if room else ["", "_swapped"]
    rows = []
    for pair in pairs:
        for k in ks:
            model = [_with_ci(result, pair, f"{pair}_top{k}{n}") for n in names]
            raw = [_with_ci(result, pair, f"{pair}_raw_pixels_top{k}{n}") for n in names]
            chance = _f(m.get(f"{pair}_top{k}_chance"))
            rows.append([_pretty(pair), f"top-{k}", *model, *raw, chance])
    headers = ["pair", "metric", "model (95% interval)", "model, background swapped"]
    headers += ["model, in another fabric's room"] if room else []
    headers += ["raw pixels", "raw pixels, background swapped"]
    headers += ["raw pixels, in another fabric's room"] if room else []
    return lines + _table([*headers, "chance"], rows) + _few_lines(result, pairs)


def _section_untouched(result: EvalResult) -> list[str]:
    """The untouched control (press videos) beside the scores as they are, when it ran."""
    m, ks = result.metrics, result.config.ks
    pairs = [p for p in result.pairs if f"{p}_top{ks[0]}_untouched" in m]
    if not pairs:
        return []
    lines = [
        "## Untouched control",
        "",
        "The same queries with every press replaced by a moment of its own video without "
        "contact, preprocessed alike (`lookfeel.data.touch_control`); a pooled touch query "
        "pools the same presses' moments. The sensor's own light and drift identify a "
        "recording session: a model that reads the contact, not the session, falls to chance "
        "here; raw pixels show how much the session alone carries.",
        "",
    ]
    rows = []
    for pair in pairs:
        for k in ks:
            model = [_with_ci(result, pair, f"{pair}_top{k}{n}") for n in ("", "_untouched")]
            raw = [
                _with_ci(result, pair, f"{pair}_raw_pixels_top{k}{n}") for n in ("", "_untouched")
            ]
            chance = _f(m.get(f"{pair}_top{k}_chance"))
            rows.append([_pretty(pair), f"top-{k}", *model, *raw, chance])
    headers = ["pair", "metric", "model (95% interval)", "model, untouched"]
    headers += ["raw pixels", "raw pixels, untouched", "chance"]
    return lines + _table(headers, rows) + _few_lines(result, pairs)


def _section_mapped(result: EvalResult) -> list[str]:
    """Matching through the cross-modal map beside the embedding's own distances (when it ran),
    and under the background and untouched controls when they ran."""
    m, ks = result.metrics, result.config.ks
    pairs = [p for p in result.pairs if f"{p}_top{ks[0]}_mapped" in m]
    if not pairs:
        return []
    lines = [
        "## Through a cross-modal map",
        "",
        "The same queries matched through linear maps between the two modalities' embedding "
        "spaces, fitted on the reference (training) fabrics' mean embeddings, both ways, each "
        "gallery item's distance lowered by its crowding among the reference fabrics (the hub "
        "correction; `lookfeel.metrics.cross_map`; no labels used, nothing fitted on the test "
        "fabrics). "
        "A library (`lookfeel index build`) fits such maps on its own fabrics and matches a pair "
        "through its map when that does better in calibration.",
        "",
    ]
    named = (
        ("_swapped", "background swapped"),
        ("_room", "in another's room"),
        ("_untouched", "untouched"),
    )
    controls = [
        (n, title) for n, title in named if any(f"{p}_top{ks[0]}_mapped{n}" in m for p in pairs)
    ]
    rows = []
    for pair in pairs:
        for k in ks:
            key = f"{pair}_top{k}"
            rows.append(
                [
                    _pretty(pair),
                    f"top-{k}",
                    _with_ci(result, pair, key),
                    _with_ci(result, pair, f"{key}_mapped"),
                    *[_with_ci(result, pair, f"{key}_mapped{n}") for n, _ in controls],
                    _f(m.get(f"{key}_chance")),
                ]
            )
    headers = ["pair", "metric", "embedding (95% interval)", "cross-modal map (95% interval)"]
    headers += [f"map, {title}" for _, title in controls]
    return lines + _table([*headers, "chance"], rows) + _few_lines(result, pairs)


def _curve_n_effective(result: EvalResult, curve: PressCurve) -> int:
    """Candidates per pick at the curve's first press count (the config's n when unknown)."""
    key = f"{Pair(Modality.TOUCH, curve.gallery)}_presses{curve.presses[0]}_n_effective"
    return int(result.metrics.get(key, result.config.n))


def _section_presses(result: EvalResult, figure: str | None) -> list[str]:
    curves = result.press_curves(result.config.ks[0])
    if not curves:
        return []
    k = result.config.ks[0]
    n_eff = _curve_n_effective(result, curves[0])
    lines = [
        "## Touch queries: accuracy against presses (Multi-input Net)",
        "",
        f"Each touch query pools P presses of one fabric {_pooled_by(result)}; exact top-{k} of "
        f"{n_eff} against each gallery (single items; a touch gallery leaves out the query's "
        f"own presses). The main `touch_to_*` keys use P = {result.config.presses}.",
        "",
    ]
    ps = sorted({int(p) for c in curves for p in c.presses})
    rows = []
    for p in ps:
        row = [str(p)]
        for c in curves:
            i = np.flatnonzero(c.presses == p)
            j = int(i[0]) if len(i) else -1
            if j >= 0 and math.isfinite(c.value[j]):
                interval = f" ({_f(c.low[j])} – {_f(c.high[j])})" if math.isfinite(c.low[j]) else ""
                row.append(_f(c.value[j]) + interval)
            else:
                row.append("–")
        row.append(_f(curves[0].chance[0]))
        rows.append(row)
    lines += _table(
        ["presses"] + [f"touch {_ARROW} {c.gallery.value}" for c in curves] + ["chance"], rows
    )
    if figure:
        lines += [f"![accuracy against presses]({figure})", ""]
    return lines


def _section_calibration(result: EvalResult, figures: dict[Pair, list[str]]) -> list[str]:
    lines = [
        "## Calibration of P ∝ exp(-c D²) (paper section 5.2)",
        "",
        "Each query's probability of each gallery fabric (its items' P summed); *fabric accuracy* "
        "is how often the most probable fabric is the query's own, against the mean confidence. "
        "c is fitted by maximum likelihood on the reference (training) fabrics when they are "
        "given, else the paper's 0.085.",
        "",
    ]
    rows = []
    over: list[str] = []
    few: set[int] = set()
    for pair, cal in result.calibration.items():
        m = result.metrics
        source, nll = cal.c_source, _f(cal.nll)
        if source == "fitted" and 0 < cal.fit_fabrics < FEW_FIT_FABRICS:
            source = f"fitted on {cal.fit_fabrics} training fabrics"
            few.add(cal.fit_fabrics)
        if cal.overconfident:
            nll += " (overconfident: NLL clearly above chance's)"
            over.append(_pretty(pair))
        rows.append(
            [
                _pretty(pair),
                f"{cal.c:.4g}",
                source,
                _bracket(m, f"{pair}_fabric_accuracy"),
                _f(m.get(f"{pair}_fabric_accuracy_chance")),
                _f(cal.confidence),
                _f(cal.reliability.ece),
                nll,
                _f(m.get(f"{pair}_nll_chance")),
            ]
        )
    lines += _table(
        [
            "pair",
            "c",
            "c from",
            "fabric accuracy",
            "chance",
            "mean confidence",
            "ECE",
            "NLL",
            "chance NLL",
        ],
        rows,
    )
    if over:
        lines += [
            f"Overconfident: {', '.join(over)}: the NLL is above chance's by more than twice "
            "its standard error over the test fabrics (or is more than twice chance's), so a "
            "uniform guess over the gallery fabrics scores better than these probabilities: "
            "they claim more than the test fabrics' distances know (c is too large for them, "
            "or the distances do not tell them apart).",
            "",
        ]
    if few:
        n = " or ".join(str(v) for v in sorted(few))
        lines += [
            f"c fitted on {n} training fabrics only: those are the fabrics the model was trained "
            f"on, and it tells so few apart far better than new ones, so a c fitted there says "
            f"little of the test fabrics (fewer than {FEW_FIT_FABRICS} are flagged). Fit it on "
            "more fabrics, or fix one (`--set c=VALUE`; the paper's is 0.085).",
            "",
        ]
    for pair, paths in figures.items():
        lines += [f"### {_pretty(pair)}", ""]
        lines += [f"![{Path(p).stem}]({p})" for p in paths] + [""]
    return lines


SPEARMAN_MARK = "‡"
"""Marks a Spearman left out of the properties table: over fewer than
`lookfeel.metrics.properties.MIN_SPEARMAN` test fabrics it is +1 or -1 whatever the probe
predicts."""


def _over(counts: Sequence[int], unit: str) -> str:
    """``2 test fabrics``, ``2 to 5 test fabrics``: what the probes' scores rest on."""
    lo, hi = min(counts), max(counts)
    n = str(lo) if lo == hi else f"{lo} to {hi}"
    return f"{n} test {unit}{'' if n == '1' else 's'}"


def _section_properties(result: EvalResult) -> list[str]:
    """The property probes' table: R², Spearman and MAE of each label over the labelled test
    fabrics, how many beside each; a Spearman over fewer than ``MIN_SPEARMAN`` of them (±1
    whatever the probe predicts) is not shown, as `lookfeel cv` leaves it out."""
    if not result.properties:
        return []
    k, unit = result.config.probe_k, result.unit
    scores = [
        s
        for by_probe in result.properties.values()
        for by_label in by_probe.values()
        for s in by_label.values()
    ]
    fewer = any(math.isfinite(s.get("k", math.nan)) and s["k"] < k for s in scores)
    counts = [int(s["n_test"]) for s in scores if math.isfinite(s.get("n_test", math.nan))]
    lines = [
        "## Physical properties (probes)",
        "",
        "Per fabric (its embeddings averaged), a probe fitted on the reference fabrics predicts "
        f"each label of the test fabrics: k-NN (mean of the nearest {k}"
        + (
            ", but at most half the reference fabrics, k beside the probe where fewer: the "
            f"nearest {k} of {k} or fewer would be all of them, the training mean"
            if fewer
            else ""
        )
        + ") and ridge regression. Chance: R² ≈ 0, Spearman 0, and the "
        "MAE of always answering the training mean."
        + (
            f" Each R², Spearman and MAE is over the test {unit}s with that label: "
            f"{_over(counts, unit)} here (each row's in its last column)."
            if counts
            else ""
        ),
        "",
    ]
    rows = []
    left_out = False
    for m, by_probe in result.properties.items():
        for probe, by_label in by_probe.items():
            for name, s in by_label.items():
                used = s.get("k", math.nan)
                few = s.get("n_test", math.nan) < MIN_SPEARMAN  # NaN (unknown): shown
                left_out |= few
                rows.append(
                    [
                        m.value,
                        name,
                        f"{probe} (k={int(used)})" if math.isfinite(used) and used < k else probe,
                        _f(s["r2"]),
                        f"n/a {SPEARMAN_MARK}" if few else _f(s["spearman"]),
                        _f(s["mae"]),
                        _f(s["mae_chance"]),
                        f"{int(s['n_train'])} / {int(s['n_test'])}",
                    ]
                )
    lines += _table(
        [
            "modality",
            "label",
            "probe",
            "R²",
            "Spearman",
            "MAE",
            "MAE chance",
            f"{unit}s train / test",
        ],
        rows,
    )
    if left_out:
        lines += [
            f"{SPEARMAN_MARK} Not shown: a Spearman over fewer than {MIN_SPEARMAN} test "
            f"{unit}s says nothing (over 2 it is +1 or -1 whatever the probe predicts; "
            f"`lookfeel cv` leaves it out too); hold out {MIN_SPEARMAN} or more labelled "
            f"{unit}s, or cross-validate (`lookfeel cv`), for one that does.",
            "",
        ]
    return lines


def _image(loader: ImageLoader, result: EvalResult, m: Modality, row: int) -> NDArray[np.generic]:
    item = result.embedded[m].items[row]
    img = loader.array(loader.frame_path(item), m)
    # Stacked touch frames (H, W, 3k): the last frame's colours; depth (H, W) as it is.
    return img[..., -3:] if img.ndim == 3 else img


def _pooled_by(result: EvalResult) -> str:
    """How a multi-press touch query was pooled: by the model itself where it pools before a
    projection or normalisation (a checkpoint scored), else by the element-wise max of the
    presses' embeddings (the same where the model pools its final embedding)."""
    info = result.info
    if not info.get("pool_exact", True) and "embeddings_file" not in info:
        return "by the model's own press pooling (inside the network, before its projection)"
    return "by element-wise max of their embeddings"


def _wrap(text: str, width: int = 17) -> str:
    """``text`` on lines of at most ``width`` characters, broken after a space or an underscore
    (``4. rice_spatula_`` / ``handle``): an object's long name under an image would run into
    its neighbours' labels. Short labels (``3. F12``) are left as they are."""
    if len(text) <= width:
        return text
    lines = [""]
    for part in re.split(r"(?<=[ _])", text):
        if lines[-1] and len(lines[-1]) + len(part.rstrip()) > width:
            lines.append(part)
        else:
            lines[-1] += part
    return "\n".join(line.rstrip() for line in lines)


def _query_label(modality: Modality, name: str) -> str:
    """``query: touch F12``; a long name on its own line(s): ``query: touch`` / ``sponge_soft``."""
    label = f"query: {modality.value} {name}"
    return label if len(label) <= 17 else f"query: {modality.value}\n{_wrap(name)}"


def _example_rows(
    result: EvalResult, examples: tuple[PickExample, ...], loader: ImageLoader
) -> list[PickRow]:
    rows = []
    for ex in examples:
        mq, mg = ex.pair.query, ex.pair.gallery
        q_items = result.embedded[mq]
        fid = int(q_items.fabric_ids[ex.query_rows[0]])
        label = _query_label(mq, result.fabric_label(fid))
        if len(ex.query_rows) > 1:
            label += f"\n(1st of {len(ex.query_rows)} presses)"
        g_fab = result.embedded[mg].fabric_ids
        rows.append(
            PickRow(
                query_image=_image(loader, result, mq, ex.query_rows[0]),
                query_label=label,
                candidate_images=[_image(loader, result, mg, c) for c in ex.candidates],
                candidate_labels=[
                    _wrap(f"{i + 1}. {result.fabric_label(int(g_fab[c]))}") + f"\nD = {d:.3g}"
                    for i, (c, d) in enumerate(zip(ex.candidates, ex.distances, strict=True))
                ],
                true_index=ex.true_position,
            )
        )
    return rows


def _value(v: float) -> str:
    return "?" if math.isnan(v) else f"{v:.3g}"


def _glance_rows(
    result: EvalResult, examples: tuple[GlanceExample, ...], loader: ImageLoader
) -> list[GlanceRow]:
    rows = []
    for ex in examples:
        presses = len(ex.query_rows)
        label = _query_label(Modality.TOUCH, result.fabric_label(ex.fabric))
        if presses > 1:
            label += f"\n(1st of {presses} presses)"
        looks = [
            GlanceLook(
                name=g.modality.value,
                images=[_image(loader, result, g.modality, r) for r in g.rows],
                labels=[
                    _wrap(f"{i + 1}. {result.fabric_label(f)}") for i, f in enumerate(g.fabrics)
                ],
                true=[f == ex.fabric for f in g.fabrics],
                note=(
                    f"nearest {g.modality.value} of {g.n_fabrics} fabrics"
                    + (" (through the cross-modal map); " if g.mapped else "; ")
                    + (
                        f"the true one ranks {g.true_rank}"
                        if g.true_rank
                        else "the true one has none"
                    )
                ),
            )
            for g in ex.galleries
        ]
        feel = [
            (name, _value(p), _value(t))
            for name, p, t in zip(ex.label_names, ex.predicted, ex.truth, strict=True)
        ]
        rows.append(
            GlanceRow(
                query_image=_image(loader, result, Modality.TOUCH, ex.query_rows[0]),
                query_label=label,
                looks=looks,
                feel=feel,
                feel_title=_feel_title(ex) if feel else "",
            )
        )
    return rows


def _feel_title(ex: GlanceExample) -> str:
    """The glance's caption over what a query feels like: the mean of how many training fabrics
    nearest in touch (at most half of them, so all of them only where there is one)."""
    n = len(ex.neighbours)
    if n == 1 and ex.n_reference == 1:  # at most half, but at least one: all there is
        return "Feels like (the only training\nfabric with labels)"
    if n == 1:
        return "Feels like (the training fabric\nnearest in touch)"
    return f"Feels like (mean of the {n}\ntraining fabrics nearest in touch)"


def _feel_fewer(result: EvalResult) -> str:
    """The glance paragraph's sentence on a feel that averaged fewer training fabrics than
    ``eval.probe_k`` (at most half of them); empty where none did."""
    k = result.config.probe_k
    fewer = [ex for ex in result.glance if ex.neighbours and len(ex.neighbours) < k]
    if not fewer:
        return ""
    ex = fewer[0]
    n, used = ex.n_reference, len(ex.neighbours)
    covers = "all of them, the same answer for every query" if k >= n else "most of them"
    return (
        f" With {n} training fabrics to choose from, it averages the nearest {used}, not "
        f"eval.probe_k's {k}: at most half of them, since the nearest {k} of {n} would be "
        f"{covers}."
    )


def _cluster_name(c: int | None) -> str:
    return "?" if c is None or c < 0 else str(c)


def _provenance(result: EvalResult) -> list[str]:
    info, cfg = result.info, result.config
    rows = []
    if "checkpoint" in info:
        rows.append(["checkpoint", f"`{info['checkpoint']}` (step {info.get('step', '?')})"])
    if "embeddings_file" in info:
        rows.append(["embeddings", f"`{info['embeddings_file']}`"])
    if "data_root" in info:
        rows.append(["data", f"`{info['data_root']}`"])
    if "split" in info:
        rows.append(["split", f"{info['split']}: {info.get('split_description', '')}"])
    fabrics = info.get("fabrics", [])
    shown = ", ".join(result.names.get(int(f), str(f)) for f in fabrics)  # names, else ids
    rows.append([f"test {result.unit}s", f"{len(fabrics)}: {shown}"])
    items = info.get("items", {})
    rows.append(
        [
            "items",
            ", ".join(f"{m} {n}" + (" presses" if m == "touch" else "") for m, n in items.items()),
        ]
    )
    rows.append(["touch query", f"{cfg.presses} press(es), pooled {_pooled_by(result)}"])
    if (cfg.presses or 1) > 1:
        rows.append(
            [
                "touch candidates",
                f"{cfg.presses} presses pooled for another sense's queries (as the Multi-input "
                "Net embeds touch); single presses for touch to touch",
            ]
        )
    if cfg.space == "labels":
        rows.append(
            [
                "space",
                "label space: each modality mapped onto the labels' normal scores by a ridge "
                "fitted on the reference (training) fabrics (`lookfeel.metrics.label_space`)",
            ]
        )
    return ["# lookfeel evaluation", "", *_table(["", ""], rows)]


FIGURES_MANIFEST = ".lookfeel-figures.json"
"""Beside the figures (``out_dir/figures/``): the names of the figures `write_report` wrote
there, so that a report written again into the folder removes those of the last one it does
not draw again (and never a file it did not write)."""

_FIGURE_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]*\.png$")


def _listed_figures(fig_dir: Path) -> set[str]:
    """The figure names `FIGURES_MANIFEST` lists: plain ``.png`` names only (nothing outside
    the folder); none when it is missing or unreadable."""
    try:
        data = json.loads((fig_dir / FIGURES_MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return set()
    names = data.get("figures") if isinstance(data, dict) else None
    if not isinstance(names, list):
        return set()
    return {n for n in names if isinstance(n, str) and _FIGURE_NAME.match(n)}


def _list_figures(fig_dir: Path, names: set[str]) -> None:
    text = json.dumps({"written_by": "lookfeel evaluate", "figures": sorted(names)}, indent=1)
    atomic_write_text(fig_dir / FIGURES_MANIFEST, text + "\n")


def _remove_stale_figures(fig_dir: Path, listed: set[str], written: set[str]) -> None:
    """Remove the figures a previous report wrote (``listed``) that this one did not, then
    list this one's alone."""
    for name in sorted(listed - written):
        p = fig_dir / name
        if p.is_file() and not p.is_symlink():
            p.unlink(missing_ok=True)
    _list_figures(fig_dir, written)


def write_report(result: EvalResult, out_dir: str | os.PathLike[str]) -> ReportFiles:
    """Write ``metrics.json``, ``report.md`` and the figures under ``out_dir/figures/``.

    Figures: accuracy against presses (``presses.png``); per figure pair a reliability
    diagram, fabric- and cluster-level confusion matrices ordered by cluster (Figure 8) and
    pick examples (Figure 6); touch queries at a glance (``glance.png``: nearest drapes and
    photos, what each feels like against the truth). Images are read with the run's
    preprocessing; a figure whose files cannot be read is skipped with a note.

    Written again into the same folder, the figures of the last report that this one does
    not draw are removed (they are listed in ``figures/`` `FIGURES_MANIFEST`), so that
    ``figures/`` and ``report.md`` agree; any other file there is left alone. The last
    ``metrics.json`` and ``report.md`` are removed first, so that a rewrite stopped half way
    never leaves them beside the new figures. Every name is
    listed before its figure is written: a report killed midway leaves none unlisted.

    Returns:
        `ReportFiles` with every path written.
    """
    out = Path(out_dir)
    fig_dir = out / "figures"
    written: list[Path] = []
    notes = list(result.notes)
    listed = _listed_figures(fig_dir)  # the last report's figures (and this one's so far)
    # The last report's numbers go before its figures are redrawn: a rewrite stopped half way
    # leaves no report rather than old numbers beside new figures (written again, the folder
    # is still taken as a report's by its figure list).
    for old in (out / "metrics.json", out / "report.md"):
        old.unlink(missing_ok=True)

    def save(fig: Figure, name: str) -> str:
        if name not in listed:
            listed.add(name)
            _list_figures(fig_dir, listed)
        written.append(save_figure(fig, fig_dir / name))
        return f"figures/{name}"

    presses_png = None
    curves = result.press_curves(result.config.ks[0])
    if curves:
        name = {c.gallery: f"touch {_ARROW} {c.gallery.value}" for c in curves}
        n_eff = _curve_n_effective(result, curves[0])
        presses_png = save(
            presses_figure(
                curves[0].presses,
                {name[c.gallery]: c.value for c in curves},
                low={name[c.gallery]: c.low for c in curves},
                high={name[c.gallery]: c.high for c in curves},
                chance=curves[0].chance,
                ylabel=f"top-{result.config.ks[0]} accuracy, pick 1 of {n_eff}",
            ),
            "presses.png",
        )
    cal_figures: dict[Pair, list[str]] = {}
    for pair in result.figure_pairs:
        cal: CalibrationResult = result.calibration[pair]
        q, g = pair.query.value, pair.gallery.value
        paths = []
        rel = cal.reliability
        paths.append(
            save(
                reliability_figure(
                    rel.edges,
                    rel.confidence,
                    rel.accuracy,
                    rel.count,
                    ece=rel.ece,
                    title=f"Reliability, {q} {_ARROW} {g}, c = {cal.c:.3g}",
                ),
                f"reliability_{pair}.png",
            )
        )
        if cal.confusion is not None:
            con = cal.confusion
            row_groups = col_groups = None
            if any(v is not None for v in result.clusters.values()):
                row_groups = [_cluster_name(result.clusters.get(int(f))) for f in con.rows]
                col_groups = [_cluster_name(result.clusters.get(int(f))) for f in con.cols]
            paths.append(
                save(
                    confusion_figure(
                        con.matrix,
                        [result.names.get(int(x), str(x)) for x in con.rows],
                        [result.names.get(int(x), str(x)) for x in con.cols],
                        row_groups=row_groups,
                        col_groups=col_groups,
                        title=f"Fabric confusion, {q} {_ARROW} {g} (ordered by cluster)",
                        xlabel=f"gallery fabric ({g})",
                        ylabel=f"query fabric ({q})",
                        colorbar_label="mean P(query matched to fabric)",
                    ),
                    f"confusion_{pair}.png",
                )
            )
        if cal.cluster_confusion is not None:
            cc = cal.cluster_confusion
            names = [_cluster_name(int(x)) for x in cc.rows]
            cols = [_cluster_name(int(x)) for x in cc.cols]
            paths.append(
                save(
                    confusion_figure(
                        cc.matrix,
                        names,
                        cols,
                        title=f"Cluster confusion, {q} {_ARROW} {g}",
                        xlabel=f"gallery cluster ({g})",
                        ylabel=f"query cluster ({q})",
                        colorbar_label="mean P(query matched to cluster)",
                    ),
                    f"confusion_clusters_{pair}.png",
                )
            )
        cal_figures[pair] = paths

    # One loader for every figure's images: a query drawn in two figures is decoded once.
    loader = ImageLoader(result.data_config or DataConfig(image_size=128))
    glance_lines: list[str] = []
    if result.glance:
        n = max((g.n_fabrics for ex in result.glance for g in ex.galleries), default=0)
        try:
            figure = glance_figure(
                _glance_rows(result, result.glance, loader),
                title="Feel to look at a glance (green: the query's own fabric)\n"
                f"each touch query beside the nearest drapes and photos of {n} test fabrics",
            )
        except (ImageError, OSError, ValueError) as e:
            notes.append(f"glance figure not drawn: {e}")
        else:
            png = save(figure, "glance.png")
            glance_lines = [
                "## At a glance",
                "",
                "Touch queries drawn at random from the test fabrics (not picked by score); "
                "beside each, the test fabrics whose look is nearest (through the cross-modal "
                "map where one was fitted: see its section), and what the query "
                "feels like (the mean label of the training fabrics nearest in touch) against "
                "the truth." + _feel_fewer(result),
                "",
                f"![at a glance]({png})",
                "",
            ]

    example_lines: list[str] = []
    for pair, examples in result.examples.items():
        if not examples:
            continue
        try:
            rows = _example_rows(result, examples, loader)
        except (ImageError, OSError) as e:
            notes.append(f"pick examples of {pair} not drawn: {e}")
            continue
        q, g = pair.query.value, pair.gallery.value
        png = save(
            pick_examples_figure(
                rows,
                title=f"Pick 1 of {len(examples[0].candidates)}: {q} query, {g} candidates "
                "nearest first (green: the true fabric)",
            ),
            f"examples_{pair}.png",
        )
        example_lines += [f"### {_pretty(pair)}", "", f"![pick examples]({png})", ""]

    metrics_path = write_metrics(result, out / "metrics.json")
    lines = _provenance(result)
    chosen = selection_note(result.info)
    if chosen:  # said where the scores are read
        lines += [f"**Optimistic scores:** {chosen}.", ""]
    lines += glance_lines
    lines += _section_pick(result)
    lines += _section_control(result)
    lines += _section_untouched(result)
    lines += _section_mapped(result)
    lines += _section_presses(result, presses_png)
    lines += _section_calibration(result, cal_figures)
    lines += _section_properties(result)
    if example_lines:
        lines += ["## Pick examples (paper Figure 6)", "", *example_lines]
    if notes:
        lines += ["## Notes", "", *(f"- {n}" for n in notes), ""]
    report = atomic_write_text(out / "report.md", "\n".join(lines))
    if listed:  # this report's figures, or the last one's
        _remove_stale_figures(fig_dir, listed, {p.name for p in written})
    return ReportFiles(metrics_path, report, tuple(written))
