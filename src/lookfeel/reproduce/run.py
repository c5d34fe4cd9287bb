"""`reproduce`: every experiment of the paper on a dataset, our numbers beside the paper's.

Experiments are the configs under ``configs/paper/`` (one per column of the paper's tables),
trained with a *budget* and scored on fabrics held out from training:

- ``paper``: the configs as written (ImageNet AlexNet at 227 px, fc6 frozen, 25,000 steps of
  batch 128); needs the ImageNet weights (``pretrained``), since training a whole AlexNet on a
  CPU is out of reach.
- ``small``: the compact CNN at 64 px, 1,500 steps of batch 64 (about 34 min a run, two at a
  time on 2 cores: 0.73 steps/s over a run's first 150 steps, session 51, on a loaded machine).
- ``tiny``: the compact CNN at 40 px, 120 steps of batch 32 (seconds a run; the demo's eight
  took 39 s side by side on 2 cores, session 46).

The architectures stay the paper's under every budget: which presses (flat or fold), the
cluster head, three pooled presses, colour augmentation and the modalities of each run. Runs
the data cannot serve (modalities or touch presses it lacks, or fewer presses a fabric than the
run pools into one touch input) are listed as skipped with the reason, before any training.
Each finished run writes ``runs/<name>/seed<k>/eval.json``; a killed reproduction resumes where
it stopped. A reproduction into a folder that holds finished runs of experiments it was not
asked for (``only``) reports them too when they were trained with its settings, so results
accumulate; one with other settings is left out with a line saying how it differs (a finished
run it was asked for that differs is an error, before any training). A folder holding runs
(finished or started) trained on another dataset, or on this one before its files or labels
changed (`Catalog.matches_fingerprint` of what each run's checkpoint recorded), is refused
before any training. A finished run scored with another ``n_boot`` is scored again from its
checkpoint (not trained again), so that its intervals are those of a fresh run; refused when
its checkpoint is gone. ``results.json``'s ``meta`` records ``n_boot``, ``workers``, the
dataset's fingerprint and the software versions. A number the held-out data cannot give (no
query has an item of its own fabric to find) is NaN, with the reason under ``not_scored`` (the
report shows it as n/a with a note).

Each side of Table 4 (depth to depth) also records, on the same queries by the same protocol,
raw pixels' scores and the background control's (`_controls`, `CONTROL_KEYS`): the model's
and raw pixels' scores with each depth image's background swapped for another fabric's, the
cloth kept. On GelFabric each fabric was captured in its own session, so the room behind the
cloth identifies it; a model that reads the cloth keeps its score with the backgrounds
swapped. Where no background can be swapped, those are NaN with the reason
(``{side}_swapped``). The model's top-1 and top-3 each have their interval, as each control's
does. A finished Table 4 run scored without the controls or without the top-3 interval (by an
earlier lookfeel) is scored again from its checkpoint; without one they are NaN, with the
reason. As each run starts a line says whether it trains (``run``), is read back from its
``eval.json`` (``read``) or is scored again from its checkpoint (``score``).
"""

from __future__ import annotations

import json
import math
import os
import pickle
import re
import signal
import sys
import threading
import time
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np
import torch

from lookfeel.atomic import atomic_write_json, atomic_write_text
from lookfeel.checkpoint import load_model
from lookfeel.config import ConfigError, EvalConfig, RunConfig, load_config
from lookfeel.config._core import Override
from lookfeel.config.recipes import recipe_path
from lookfeel.data import Catalog, DatasetError, ImageLoader, paper_split, scan
from lookfeel.embedding import EmbeddedItems, embed_catalog
from lookfeel.evaluate.controls import background_control, raw_pixel_baseline
from lookfeel.evaluate.core import no_query_scored
from lookfeel.evaluate.result import EvalResult
from lookfeel.locks import exclusive
from lookfeel.metrics import (
    EXACT_PICK,
    ScoringProtocol,
    flat_metrics,
    group_queries,
    mean_and_spread,
    score_pairs,
)
from lookfeel.modality import Modality, Pair
from lookfeel.plugins import load_plugins
from lookfeel.processes import available_cores, die_with_parent
from lookfeel.provenance import software_versions
from lookfeel.reproduce.report import findings, write_reproduction_report
from lookfeel.reproduce.result import ReproduceResult
from lookfeel.train import run_started, train
from lookfeel.train.loop import MEMBERS, config_changes, resume_checkpoint

__all__ = [
    "BUDGETS",
    "EXPERIMENTS",
    "EXPERIMENT_NAMES",
    "Experiment",
    "ReproduceResult",
    "config_dir",
    "experiment_overrides",
    "headline",
    "reproduce",
    "split_overrides",
]


@dataclass(frozen=True)
class Experiment:
    """One column of the paper's tables: a config under ``configs/paper/``."""

    name: str
    cites: str
    table: str
    """``models`` (Figure 7, Tables 1-2), ``augmentation`` (Table 3) or ``vision`` (Table 4)."""


EXPERIMENTS = (
    Experiment("flat", "Figure 7, Tables 1-2 (Flat)", "models"),
    Experiment("cross_modal", "Figure 7, Tables 1-2 (Cross-mdl)", "models"),
    Experiment("auxiliary", "Figure 7, Tables 1-2 (Auxiliary)", "models"),
    Experiment("multi_input", "Figure 7, Tables 1-2 (Multi-in)", "models"),
    Experiment("cross_modal_aug", "Table 3 (Cross-mdl with aug)", "augmentation"),
    Experiment("multi_input_aug", "Table 3 (Multi-in with aug)", "augmentation"),
    Experiment("snn_depth", "Table 4 (SNN, only depth)", "vision"),
    Experiment("cross_modal_depth_touch", "Table 4 (Cross-mdl, depth & Gel)", "vision"),
)
EXPERIMENT_NAMES = tuple(e.name for e in EXPERIMENTS)
"""The experiments' names, in the report's order (``lookfeel reproduce --only``)."""

_COMPACT = ["model.backbone=compact", "model.freeze=none", "model.pretrained=null"]
BUDGETS: dict[str, tuple[str, ...]] = {
    "tiny": (
        *_COMPACT,
        "model.width=12",
        "model.dropout=0.0",
        "data.image_size=40",
        "train.steps=120",
        "train.batch_size=32",
        "train.lr=0.001",
    ),
    "small": (
        *_COMPACT,
        "model.width=32",
        "model.dropout=0.2",
        "data.image_size=64",
        "train.steps=1500",
        "train.batch_size=64",
        "train.lr=0.001",
    ),
    "paper": (),
}
"""Overrides of each budget on top of the paper configs."""


def config_dir() -> Path:
    """The shipped ``configs/paper`` folder."""
    return recipe_path("paper")


# ---------------------------------------------------------------------------------------------


def _needs(config: RunConfig, catalog: Catalog) -> str | None:
    """Why the data cannot serve this config, or None."""
    have = set(catalog.modalities)
    missing = [m.value for m in config.train.modalities if m not in have]
    if missing:
        has = ", ".join(m.value for m in catalog.modalities) or "nothing"
        return f"needs {', '.join(missing)}; the data has {has}"
    if Modality.TOUCH in config.train.modalities:
        kinds = config.data.touch_kinds
        names = "/".join(k.value for k in kinds)
        if not catalog.items(Modality.TOUCH, kinds):
            return f"needs {names} touch presses; the data has none"
        presses = config.data.presses
        most = catalog.most_presses(kinds)
        if most < presses:  # its touch queries and candidates pool P presses of one fabric
            return (
                f"pools {presses} {names} touch presses of one fabric into each touch input "
                f"(data.presses); the data has at most {most} per fabric"
            )
    return None


def _pooled(
    emb: np.ndarray, fabric: np.ndarray, presses: int, seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """Touch embeddings of single presses -> of P-press inputs (the Multi-input Net's max).

    Raises:
        DatasetError: no fabric has ``presses`` presses, so there is no touch input to score.
    """
    if presses <= 1:
        return emb, fabric
    groups = group_queries(emb, fabric, presses=presses, seed=seed)
    if not len(groups.fabric):
        ids, counts = np.unique(fabric, return_counts=True)
        top = int(np.argmax(counts))
        raise DatasetError(
            f"touch inputs pool {presses} presses of one fabric (data.presses), but none of the "
            f"{len(ids)} held-out fabrics has {presses}: fabric {ids[top]} has the most, "
            f"{counts[top]}"
        )
    return groups.emb, groups.fabric


def _why_not_scored(pair: Pair, config: RunConfig) -> str:
    """Why no query of ``pair`` could be scored on the held-out fabrics (one sentence).

    Touch inputs pool ``data.presses`` presses of a fabric, as queries and as candidates alike
    (`_pooled`), so touch to touch needs two such inputs of one fabric: twice the presses."""
    presses = config.data.presses
    kinds = "/".join(k.value for k in config.data.touch_kinds)
    if pair.same and pair.query is Modality.TOUCH and presses > 1:
        return (
            f"each touch input pools {presses} {kinds} presses of one fabric, and no held-out "
            f"fabric has {2 * presses} to make a second input for a query to find"
        )
    return no_query_scored(pair, 1, fabrics="held-out")


def _score(
    model: Any, catalog: Catalog, config: RunConfig, n_boot: int, seed: int
) -> tuple[dict[str, float], dict[str, str]]:
    """All pairs of pick 1 of 10 (exact and sampled), gallery metrics and intervals; and why,
    by pair name, each pair none of whose queries could be scored (its numbers are NaN)."""
    loader = ImageLoader(config.data)
    emb = embed_catalog(model, catalog, loader)
    vectors: dict[Modality, np.ndarray] = {}
    fabrics: dict[Modality, np.ndarray] = {}
    for m, e in emb.items():
        vectors[m], fabrics[m] = e.embeddings, e.fabric_ids
        if m is Modality.TOUCH:
            vectors[m], fabrics[m] = _pooled(e.embeddings, e.fabric_ids, config.data.presses, seed)
    protocol = ScoringProtocol(n_boot=n_boot, seed=seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # fewer than 10 fabrics: n_effective is in the result
        scores = score_pairs(vectors, fabrics, protocol)
    why = {str(p): _why_not_scored(p, config) for p, s in scores.items() if not s.pick.n_queries}
    return flat_metrics(scores), why


_DEPTH_TO_DEPTH = Pair(Modality.DEPTH, Modality.DEPTH)


def _depth_why(side: str) -> str:
    """Why no query of Table 4's ``side`` (``seen`` or ``novel``) could be scored."""
    where = " in the held-out fifth of its images" if side == "seen" else ""
    return f"no {side} fabric has two depth images{where}, one to query and one to find"


def _depth_pick(
    model: Any, catalog: Catalog, config: RunConfig, n_boot: int, seed: int, side: str
) -> tuple[dict[str, float], dict[str, str]]:
    """Exact pick 1 of 10 of depth against depth (Table 4) on one ``side`` (``seen`` or
    ``novel``): top-1 and top-3, each with its 95% interval over the fabrics (``n_boot``
    resamples; none when 0), their chance levels, the candidates per draw (``n_effective``),
    the queries and their fabrics, and beside them raw pixels and the background control on
    the same queries (`_controls`). Also why, by ``not_scored`` key, what is NaN: ``side``
    when no query could be scored (every number is then NaN), ``{side}_swapped`` when no
    background could be swapped."""
    loader = ImageLoader(config.data)
    emb = embed_catalog(model, catalog, loader, modalities=[Modality.DEPTH])
    if Modality.DEPTH not in emb:  # not one depth image on this side
        nan = float("nan")
        out = {"top1": nan, "top3": nan, "n_queries": 0.0, "n_fabrics": 0.0}
        return out | dict.fromkeys(CONTROL_KEYS, nan), {side: _depth_why(side)}
    d = emb[Modality.DEPTH]
    protocol = replace(EXACT_PICK, n_boot=n_boot, seed=seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # fewer than 10 fabrics: chance says so
        scores = score_pairs(
            {Modality.DEPTH: d.embeddings},
            {Modality.DEPTH: d.fabric_ids},
            protocol,
            [_DEPTH_TO_DEPTH],
        )
    m = scores[_DEPTH_TO_DEPTH].metrics
    out = {"top1": m["top1"], "top3": m["top3"], "chance": m["top1_chance"]}
    out |= {"top3_chance": m["top3_chance"], "n_effective": m["n_effective"]}
    out |= {"n_queries": m["n_queries"], "n_fabrics": m["n_fabrics"]}
    out |= {k: m[k] for k in _INTERVAL_KEYS if k in m}
    why = {} if m["n_queries"] else {side: _depth_why(side)}
    controls, not_swapped = _controls(model, loader, d, n_boot, seed, bool(m["n_queries"]))
    if not_swapped is not None:
        why[f"{side}_swapped"] = not_swapped
    return out | controls, why


_INTERVAL_KEYS = tuple(f"top{k}_ci_{end}" for k in (1, 3) for end in ("low", "high"))
"""The bounds of the model's top-1 and top-3 intervals on a side of Table 4 (`_depth_pick`)."""

CONTROL_KEYS = tuple(
    key.format(k=k)
    for key in ("raw_pixels_top{k}", "top{k}_swapped", "raw_pixels_top{k}_swapped")
    for k in (1, 3)
)
"""The numbers beside the model's on each side of Table 4 (`_controls`), in every record of a
side (NaN where not measured, with the reason under ``not_scored``): raw pixels' top-k, and the
model's and raw pixels' top-k with each depth image's background swapped for another fabric's.
Each one measured has its interval (``_ci_low``, ``_ci_high``)."""


def _controls(
    model: Any,
    loader: ImageLoader,
    depth: EmbeddedItems,
    n_boot: int,
    seed: int,
    scored: bool,
) -> tuple[dict[str, float], str | None]:
    """Raw pixels and the background control of Table 4's depth to depth on the queries of
    ``depth`` (the model's embeddings of one side's images), as ``lookfeel evaluate`` scores
    them (`lookfeel.evaluate.controls`) and by the same exact pick 1 of 10 as the model's
    number, with its ``seed`` and ``n_boot``:

    - ``raw_pixels_top{k}``: the preprocessed images themselves matched (``loader`` reads them
      as it read them for the model);
    - ``top{k}_swapped`` and ``raw_pixels_top{k}_swapped``: the model and raw pixels on the
      same images with each one's background replaced by that of an image of another fabric,
      the cloth kept (`lookfeel.data.background_swap.BackgroundControl`, partners drawn with
      ``seed``); for registered depth also the room control (``_room``).

    Every key of `CONTROL_KEYS` is there, NaN when not measured: none is when no query could
    be scored (``scored`` false: the side's own reason says why). Also why no background
    could be swapped (the images' sizes differ, one fabric only, a room that cannot be
    fitted), else None."""
    result = EvalResult(
        metrics={},
        config=EvalConfig(sampled=False, n_boot=n_boot, seed=seed, presses=1),
        pairs=(_DEPTH_TO_DEPTH,),
        calibration={},
        examples={},
        properties={},
        embedded={Modality.DEPTH: depth},
        not_scored={} if scored else {_DEPTH_TO_DEPTH: "no query"},
    )
    got = raw_pixel_baseline(result, loader)
    swapped, skipped = background_control(model, loader.config, result.embedded, result)
    prefix = f"{_DEPTH_TO_DEPTH}_"
    out = dict.fromkeys(CONTROL_KEYS, float("nan"))
    out |= {k.removeprefix(prefix): v for k, v in (got | swapped).items()}
    return out, (skipped[0] if skipped else None)


def _run_one(
    exp: Experiment,
    config: RunConfig,
    catalog: Catalog,
    data: Path,
    run_dir: Path,
    n_boot: int,
    saved: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """Train the run at ``run_dir`` (resuming a started one) and score its last checkpoint on
    its held-out fabrics; its ``eval.json``'s record. A finished run is read from its
    ``eval.json`` (``saved``: its record, when already read); one scored with another
    ``n_boot`` (or before ``eval.json`` recorded it), or a Table 4 run scored without raw
    pixels and the background control (`_missing_controls`) or without its top-3 interval
    (`_missing_top3_interval`), is scored again from its kept checkpoint, its training time
    kept (`_rescored`). Without that checkpoint those numbers are NaN, with the reason
    (`_without_controls`, `_without_top3_interval`)."""
    done = run_dir / "eval.json"
    if saved is None and done.exists():
        saved = json.loads(done.read_text(encoding="utf-8"))
    if saved is not None:
        kept: dict[str, Any] = dict(saved)  # the caller's stays as read
        last = run_dir / "checkpoints" / "last.pt"
        if _rescored(kept, run_dir, n_boot):
            # What a fresh run with this n_boot would record, but its training: as it was;
            # scored on the threads it was scored on (the numbers depend on them).
            with _torch_threads(kept.get("threads")):
                record = _evaluate(exp, config, catalog, load_model(last), n_boot)
            record["seconds"], record["threads"] = kept.get("seconds"), kept.get("threads")
            atomic_write_text(done, json.dumps(record, indent=1) + "\n")
            return record
        if kept.get("n_boot", n_boot) != n_boot:  # refused before any training: `reproduce`
            raise ConfigError(_cannot_rescore(run_dir, kept["n_boot"], n_boot))
        if "not_scored" not in kept:  # an earlier lookfeel's: derive its reasons
            kept["not_scored"] = _old_reasons(kept, run_dir)
        return _without_top3_interval(_without_controls(kept))
    started = time.perf_counter()
    resume = run_started(run_dir)
    before = _logged_seconds(run_dir / "metrics.jsonl") if resume else 0.0
    result = train(config, data, run_dir, resume=resume)
    loaded = load_model(
        result.last_checkpoint
    )  # the last step, as the paper: no test-set selection
    record = _evaluate(exp, config, catalog, loaded, n_boot)
    # The run's own time: its training and scoring here, and the training a killed
    # reproduction did on it before this one resumed it.
    record["seconds"] = round(before + time.perf_counter() - started, 1)
    record["threads"] = torch.get_num_threads()
    atomic_write_text(done, json.dumps(record, indent=1) + "\n")
    return record


def _evaluate(
    exp: Experiment, config: RunConfig, catalog: Catalog, loaded: Any, n_boot: int
) -> dict[str, Any]:
    """A trained run's ``eval.json`` record but its time and threads: ``loaded`` (its last
    checkpoint, `load_model`) scored on its held-out fabrics of ``catalog`` with ``n_boot``
    bootstrap resamples for the intervals (recorded, with the dataset it was trained on)."""
    split = loaded.split
    record: dict[str, Any] = {
        "experiment": exp.name,
        "seed": config.train.seed,
        "split": split["kind"],
    }
    not_scored: dict[str, str] = {}
    if exp.table == "vision":
        seen_paths = set(split.get("val_items", []))
        seen = catalog.with_items(
            it for m in catalog.modalities for it in catalog.items(m) if str(it.path) in seen_paths
        )
        seed = config.train.seed
        sides = {"seen": seen}
        if split.get("novel"):
            sides["novel"] = catalog.subset(split["novel"])
        for side, part in sides.items():
            record[side], why = _depth_pick(loaded.model, part, loaded.config, n_boot, seed, side)
            not_scored |= why
        record["seen_fabrics"] = len(split["val"])
    else:
        held_out = catalog.subset(split["val"])
        record["metrics"], not_scored = _score(
            loaded.model, held_out, loaded.config, n_boot, config.train.seed
        )
    record["not_scored"] = not_scored
    test_ids = split.get("novel") or split["val"]
    record["test_fabrics"] = len(test_ids)
    record["test_fabric_ids"] = sorted(int(i) for i in test_ids)
    record["n_boot"] = n_boot
    record["data_fingerprint"] = loaded.data_fingerprint
    return record


@contextmanager
def _torch_threads(threads: Any) -> Iterator[None]:
    """Run with ``threads`` torch threads (a run's recorded count), then as before; as it is
    when ``threads`` is not a positive count (not recorded)."""
    before = torch.get_num_threads()
    if isinstance(threads, int) and threads > 0 and threads != before:
        torch.set_num_threads(threads)
    try:
        yield
    finally:
        if torch.get_num_threads() != before:
            torch.set_num_threads(before)


def _scored_otherwise(saved: Mapping[str, Any], n_boot: int) -> bool:
    """Whether a finished run's ``eval.json`` record was scored with another ``n_boot`` than
    ``n_boot``, or with one it does not record (an earlier lookfeel's): its intervals are
    then not those this reproduction asks for."""
    return saved.get("n_boot") != n_boot


def _rescored(saved: Mapping[str, Any] | None, run_dir: Path, n_boot: int) -> bool:
    """Whether the finished run at ``run_dir``, whose ``eval.json`` record is ``saved`` (None:
    not read), is scored again from its checkpoint rather than read back (`_run_one`): it was
    scored with another ``n_boot`` or without a number Table 4 records now, and its
    ``checkpoints/last.pt`` is there."""
    if saved is None:
        return False
    stale = (
        _scored_otherwise(saved, n_boot)
        or _missing_controls(saved)
        or _missing_top3_interval(saved)
    )
    return bool(stale) and (run_dir / "checkpoints" / "last.pt").is_file()


def _missing_controls(saved: Mapping[str, Any]) -> list[str]:
    """The Table 4 sides (``seen``, ``novel``) of a finished run's ``eval.json`` record that
    lack raw pixels and the background control (`CONTROL_KEYS`): an earlier lookfeel scored
    them without. Empty for the runs of Tables 1-3."""
    return [s for s in ("seen", "novel") if s in saved and "raw_pixels_top1" not in saved[s]]


NO_CHECKPOINT = (
    "scored by an earlier lookfeel without raw pixels or the background control, and the "
    "run's checkpoints/last.pt, needed to add them, is gone"
)
"""Why a Table 4 side has no raw pixels or background control (`_without_controls`)."""


def _without_controls(saved: dict[str, Any]) -> dict[str, Any]:
    """``saved``, a finished run's record, with every key of `CONTROL_KEYS` NaN on each Table
    4 side that lacks them (`_missing_controls`: its checkpoint is gone, so they cannot be
    scored), and why under ``not_scored`` (``{side}_raw_pixels``, ``{side}_swapped``)."""
    for side in _missing_controls(saved):
        saved[side] = dict.fromkeys(CONTROL_KEYS, float("nan")) | saved[side]
        reasons = {f"{side}_raw_pixels": NO_CHECKPOINT, f"{side}_swapped": NO_CHECKPOINT}
        saved["not_scored"] = {**saved["not_scored"], **reasons}
    return saved


def _missing_top3_interval(saved: Mapping[str, Any]) -> list[str]:
    """The Table 4 sides of a finished run's ``eval.json`` record whose top-1 has its interval
    but top-3 none: an earlier lookfeel recorded the top-1 interval alone (an ``n_boot`` of 0
    records neither, so misses none)."""
    return [
        s
        for s in ("seen", "novel")
        if s in saved and "top1_ci_low" in saved[s] and "top3_ci_low" not in saved[s]
    ]


NO_TOP3_INTERVAL = (
    "scored by an earlier lookfeel without the top-3 interval, and the run's "
    "checkpoints/last.pt, needed to add it, is gone"
)
"""Why a Table 4 side's top-3 has no interval (`_without_top3_interval`)."""


def _without_top3_interval(saved: dict[str, Any]) -> dict[str, Any]:
    """``saved``, a finished run's record, with the model's top-3 interval NaN on each Table 4
    side that lacks it (`_missing_top3_interval`: its checkpoint is gone, so it cannot be
    scored), and why under ``not_scored`` (``{side}_top3_interval``)."""
    for side in _missing_top3_interval(saved):
        saved[side] = saved[side] | dict.fromkeys(("top3_ci_low", "top3_ci_high"), float("nan"))
        saved["not_scored"] = {**saved["not_scored"], f"{side}_top3_interval": NO_TOP3_INTERVAL}
    return saved


def _cannot_rescore(run_dir: Path, was: int, now: int) -> str:
    """Why the finished run at ``run_dir``, scored with ``--n-boot was``, cannot be scored
    with ``now``: its checkpoint is gone (one line, with what to do)."""
    return (
        f"{run_dir} is a finished run scored with --n-boot {was}, and its checkpoint "
        f"checkpoints/last.pt, needed to score it again with --n-boot {now}, is gone: rerun "
        f"with --n-boot {was}, reproduce into another --out, or delete the run to train it anew"
    )


def _logged_seconds(path: Path) -> float:
    """The training time ``metrics.jsonl`` at ``path`` records: each logged window's steps over
    its ``steps_per_s`` (the time of validations and checkpoints between windows is not in it).
    0 without the file; a line that cannot be read counts nothing."""
    total, last = 0.0, 0
    try:
        lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        return 0.0
    for line in lines:
        try:
            entry = json.loads(line)
            step, rate = int(entry["step"]), entry.get("steps_per_s")
        except (ValueError, KeyError, TypeError):
            continue
        if isinstance(rate, (int, float)) and rate > 0 and step > last:
            total += (step - last) / rate
            last = step
    return total


def _old_reasons(record: Mapping[str, Any], run_dir: Path) -> dict[str, str]:
    """Why each NaN number of an ``eval.json`` that recorded no reasons (an earlier lookfeel's)
    is NaN, where what is stored tells: a Table 4 side's reason depends on the side alone, a
    pair's on the run's ``config.yaml`` (the presses its touch inputs pool). Where it does not
    (no readable config), none: the report says the reason was not recorded."""
    sides = {s: record[s].get("top1") for s in ("seen", "novel") if s in record}
    out = {side: _depth_why(side) for side, top1 in sides.items() if top1 != top1}
    nan = [
        k.removesuffix("_top1")
        for k, v in record.get("metrics", {}).items()
        if k.endswith("_top1") and v != v
    ]
    if nan:
        try:
            config = load_config(RunConfig, run_dir / "config.yaml")
            out |= {p: _why_not_scored(Pair.parse(p), config) for p in nan}
        except (ConfigError, OSError, ValueError):
            pass  # the report's "not recorded" stands for these
    return out


def _over_seeds(tables: Sequence[Mapping[str, float]], stat: str) -> dict[str, float]:
    """``mean`` or ``std`` over seeds of every number in per-seed tables, over the seeds that
    have it (a number NaN or missing in one seed is left out there: `mean_and_spread`)."""
    keys = dict.fromkeys(k for t in tables for k in t)
    nan = float("nan")
    return {k: mean_and_spread([t.get(k, nan) for t in tables])[stat] for k in keys}


def _aggregate(records: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Mean over seeds of every number, each interval bound included (a bound is the mean over
    the seeds of that seed's bootstrap bound over test fabrics), and its standard deviation over
    seeds when there are several; Table 4's raw pixels and background control (`CONTROL_KEYS`)
    as its other numbers. ``not_scored``: why each number that is NaN in any seed is (every
    seed's reasons, by pair name, Table 4 side or ``{side}_raw_pixels``/``{side}_swapped``)."""
    out: dict[str, Any] = {"seeds": len(records)}
    for part in ("metrics", "seen", "novel"):
        if part not in records[0]:
            continue
        tables = [r[part] for r in records]
        out[part] = _over_seeds(tables, "mean")
        if len(records) > 1:
            std = _over_seeds(tables, "std")
            name = "spread" if part == "metrics" else f"{part}_spread"
            out[name] = {k: v for k, v in std.items() if part != "metrics" or "_top" in k}
    out["not_scored"] = {k: v for r in records for k, v in r.get("not_scored", {}).items()}
    for key in ("test_fabrics", "test_fabric_ids", "seen_fabrics"):
        if key in records[0]:
            out[key] = records[0][key]
    return out


@dataclass(frozen=True)
class _Job:
    """One training run of the reproduction: an experiment at one seed."""

    exp: Experiment
    config: RunConfig
    run_dir: Path
    saved: dict[str, Any] | None = field(default=None, compare=False, repr=False)
    """Its ``eval.json``'s record as the reproduction found it (`_saved_records`); None when
    it has none (or one that cannot be read: `_run_one` reads it again and says why)."""

    def start_line(self, n_boot: int) -> str:
        """The line logged as the run starts: ``run  flat seed 0 (Figure 7, ...)`` when it
        trains (or resumes), ``read ...`` when it is finished and read back from its
        ``eval.json``, ``score ...`` when it is finished and scored again from its checkpoint
        (`_rescored`, with ``n_boot``)."""
        run = f"{self.exp.name} seed {self.config.train.seed} ({self.exp.cites})"
        if not self.finished:
            return f"run  {run}"
        if _rescored(self.saved, self.run_dir, n_boot):
            return f"score {run}: finished, scored again from its checkpoint, not trained"
        return f"read {run}: finished, read back from its eval.json"

    @property
    def finished(self) -> bool:
        return (self.run_dir / "eval.json").exists()


def _on_cuda(config: RunConfig) -> bool:
    device = config.train.device
    return device == "cuda" or (device == "auto" and torch.cuda.is_available())


def _workers_for(jobs: Sequence[_Job], workers: int) -> int:
    """How many runs train at once: ``workers``, or by default one per available core on a
    CPU and one on CUDA; never more than the runs left to train. (Small runs side by side on
    one GPU, each in its own process, may well be faster, as the compact nets are bound by
    launching kernels there; not measured yet, so CUDA keeps one at a time unless asked.)"""
    todo = sum(not j.finished for j in jobs)
    if workers <= 0:
        workers = 1 if any(_on_cuda(j.config) for j in jobs) else available_cores()
    return max(1, min(workers, todo))


def _run_jobs(
    jobs: Sequence[_Job],
    catalog: Catalog,
    data: Path,
    n_boot: int,
    workers: int,
    log: Callable[[str], None],
) -> list[dict[str, Any]]:
    """Train and score every job; their records in the order of ``jobs``.

    With more than one worker the runs train in spawned worker processes (which die with
    this one: `die_with_parent`), each with ``cores // workers`` torch threads: the
    reproduction's small networks gain nothing from a second thread on one run (on 2 cores of
    an AMD EPYC the tiny budget's eight runs took 41 s on one thread and 44 s on two), so
    runs side by side use the cores fully. A run's numbers depend on its thread count (the
    rounding of the sums), which its ``eval.json`` records; `lookfeel reproduce --workers 1`
    trains in this process with every core's thread. A line is logged as each run starts.

    The warnings a worker's run raises are raised again here as it finishes (`_relay`), so
    that they are shown as this process shows its own (``lookfeel: warning: ...`` under the
    command). An interrupt (Ctrl-C, or SIGINT sent to this process alone; the workers ignore
    it) ends the workers at once (`_stop_workers`) and goes on up: runs resume from their last
    checkpoint. An error of a run lets the others running finish first (each writes its own
    ``eval.json``), and starts no more.
    """
    n = _workers_for(jobs, workers)
    if n == 1:
        records = []
        for job in jobs:
            log(job.start_line(n_boot))
            records.append(
                _run_one(job.exp, job.config, catalog, data, job.run_dir, n_boot, job.saved)
            )
        return records
    threads = max(1, available_cores() // n)
    out: list[dict[str, Any] | None] = [None] * len(jobs)
    waiting = iter(range(len(jobs)))
    pool = ProcessPoolExecutor(
        n,
        mp_context=get_context("spawn"),
        initializer=_start_worker,
        initargs=(os.getpid(), threads),
    )
    try:
        running: dict[Future[tuple[dict[str, Any], list[_Caught]]], int] = {}

        def start_next() -> None:
            for i in waiting:
                job = jobs[i]
                if job.finished:  # nothing to train: read it here
                    log(job.start_line(n_boot))
                    out[i] = _run_one(
                        job.exp, job.config, catalog, data, job.run_dir, n_boot, job.saved
                    )
                    continue
                log(job.start_line(n_boot))
                running[pool.submit(_run_in_worker, job, data, n_boot)] = i
                return

        with _interrupt_between_waits() as interrupted:
            for _ in range(n):
                start_next()
            while running:
                done = interrupted.wait_for(running)
                for future in done:
                    record, caught = future.result()
                    out[running.pop(future)] = record
                    _relay(caught)
                    start_next()
    except KeyboardInterrupt:
        _stop_workers(pool)
        raise
    finally:
        try:
            pool.shutdown(wait=True, cancel_futures=True)
        except KeyboardInterrupt:  # while the others' runs end after a run's error
            _stop_workers(pool)
            raise
    return [r for r in out if r is not None]


class _Interrupts:
    """SIGINT while waiting on the pool, taken at a known point (`_interrupt_between_waits`)."""

    def __init__(self) -> None:
        self.waiting = False
        self.pending = False

    def handle(self, signum: int, frame: Any) -> None:
        """The SIGINT handler: a KeyboardInterrupt now, except inside `wait_for`'s wait, where
        it is only noted (and raised there as the wait returns)."""
        if not self.waiting:
            raise KeyboardInterrupt
        self.pending = True

    def wait_for(self, running: Mapping[Future[Any], int]) -> set[Future[Any]]:
        """The futures of ``running`` that are done, waiting up to 0.2 s at a time for one;
        KeyboardInterrupt once SIGINT came while waiting."""
        while True:
            self.waiting = True
            try:
                done, _ = wait(running, timeout=0.2, return_when=FIRST_COMPLETED)
            finally:
                self.waiting = False
            if self.pending:
                raise KeyboardInterrupt
            if done:
                return done


@contextmanager
def _interrupt_between_waits() -> Iterator[_Interrupts]:
    """While waiting on the pool's futures, take SIGINT as a note, raised as KeyboardInterrupt
    when the wait returns (`_Interrupts.wait_for`), never inside ``concurrent.futures.wait``:
    raised there, it can leave the futures' locks held (between acquiring them and releasing
    them), and the pool's manager thread, which sets those futures once the workers are
    stopped, then blocks on them and the shutdown waits for it forever. Outside the wait
    SIGINT raises at once, as Python's own handler does. Only the main thread can set a
    signal handler; elsewhere, or where SIGINT is not Python's default handler (ignored, or the
    caller's own), it is left as it is."""
    interrupts = _Interrupts()
    if (
        threading.current_thread() is not threading.main_thread()
        or signal.getsignal(signal.SIGINT) is not signal.default_int_handler
    ):
        yield interrupts
        return
    signal.signal(signal.SIGINT, interrupts.handle)
    try:
        yield interrupts
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def _stop_workers(pool: ProcessPoolExecutor) -> None:
    """End ``pool``'s worker processes now, with the runs they are training (SIGTERM, then
    SIGKILL to one still there after 5 s; their own workers die with them), so that its
    shutdown waits for nothing (`ProcessPoolExecutor.shutdown` alone waits for the runs).
    Python 3.11 has no public way to do so: the pool's ``_processes``, which the shutdown
    clears only after the wait."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    for process in processes:
        if process.is_alive():
            process.terminate()
    for process in processes:
        process.join(5.0)
        if process.is_alive():
            process.kill()
            process.join(5.0)


def _start_worker(parent: int, threads: int) -> None:
    """Initializer of a reproduction worker: die with ``parent``, ignore SIGINT (Ctrl-C
    reaches every process of the terminal's group; ``parent`` ends its workers itself, so a
    worker waiting for its next run prints no traceback), use ``threads`` threads, and
    import the user's plugins (`load_plugins`: ``LOOKFEEL_PLUGINS``, inherited from the parent,
    and entry points), so that a config naming their own backbone or loss trains here too (a
    spawned worker runs none of the parent's imports)."""
    die_with_parent(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    torch.set_num_threads(threads)
    load_plugins()


_CATALOGS: dict[Path, Catalog] = {}
"""The dataset a worker scanned, by path: scanned once per worker, not once per run."""

_Caught = tuple[type[Warning], str, str, int, str | None]
"""A warning a worker's run raised: its category, message, file, line and module."""


def _run_in_worker(job: _Job, data: Path, n_boot: int) -> tuple[dict[str, Any], list[_Caught]]:
    """`_run_one` in a worker process; with the warnings it raised that this process's
    filters let through (each once), for the parent to raise again (`_relay`): a spawned
    worker shows them in Python's own form, with the file, line and source line, which the
    parent's ``lookfeel: warning: ...`` does not reach."""
    caught: dict[tuple[type[Warning], str], tuple[str, int]] = {}

    def keep(
        message: Warning | str,
        category: type[Warning],
        filename: str,
        lineno: int,
        file: Any = None,
        line: str | None = None,
    ) -> None:
        caught.setdefault((category, str(message)), (filename, lineno))

    with warnings.catch_warnings():
        warnings.showwarning = keep
        if data not in _CATALOGS:
            _CATALOGS[data] = scan(data, require=[], strict=True)
        record = _run_one(job.exp, job.config, _CATALOGS[data], data, job.run_dir, n_boot)
    modules = {getattr(m, "__file__", None): name for name, m in list(sys.modules.items()) if m}
    return record, [
        (_sendable(category), text, filename, lineno, modules.get(filename))
        for (category, text), (filename, lineno) in caught.items()
    ]


def _sendable(category: type[Warning]) -> type[Warning]:
    """``category``, or `UserWarning` when it cannot be sent to the parent (a class pickle
    cannot name, such as one made in a function)."""
    try:
        pickle.dumps(category)
    except (pickle.PicklingError, AttributeError, TypeError):
        return UserWarning
    return category


_RELAYED: dict[Any, Any] = {}
"""The warnings registry of the warnings relayed from workers: each shown once, as Python
shows a warning of one place once."""


def _relay(caught: Sequence[_Caught]) -> None:
    """Raise again here the warnings a worker's run raised, at their own file and line (this
    process's filters and display decide what is shown, and how)."""
    for category, text, filename, lineno, module in caught:
        warnings.warn_explicit(text, category, filename, lineno, module, _RELAYED)


def split_overrides(has_paper_test: bool, pool: int) -> tuple[list[str], list[str], int]:
    """How `reproduce` splits a dataset: the overrides of the runs of Tables 1-3, those of
    Table 4's (``seen``), and how many training fabrics the first hold out to be scored on.

    With 10 or more of the paper's test fabrics (``has_paper_test``), every run scores on
    them (``paper``; Table 4's as its novel fabrics). Otherwise the runs of Tables 1-3 hold
    out a cluster-stratified share of the ``pool`` training fabrics, 18 of 118 as the paper
    and at least 10 when there are 30 or more, and Table 4's as many as novel ones."""
    n_val = min(18, max(round(0.18 * pool), min(10, pool // 3), 2))
    if has_paper_test:
        return ["train.split=paper"], ["train.split=seen", "train.val_fabrics=0"], n_val
    return (
        ["train.split=stratified", f"train.val_fabrics={n_val}"],
        ["train.split=seen", f"train.val_fabrics={n_val}"],
        n_val,
    )


def experiment_overrides(
    exp: Experiment,
    budget: str,
    split: Sequence[str],
    vision: Sequence[str],
    overrides: Sequence[str] = (),
    pretrained: str | os.PathLike[str] | None = None,
) -> list[str | Override]:
    """The overrides `reproduce` trains ``exp`` with, on its config under ``configs/paper/``:
    the budget's, the split (``split`` for the runs of Tables 1-3, ``vision`` for Table 4's:
    `split_overrides`), the weights file under the paper budget, then ``overrides``, which
    win. The weights file's path is taken as it is (not parsed as YAML), absolute."""
    run: list[str | Override] = [*BUDGETS[budget], "train.progress=false", "train.val_every=0"]
    run += vision if exp.table == "vision" else split
    if pretrained is not None and budget == "paper":
        path = os.path.abspath(pretrained)
        run.append(Override("model.pretrained", path, f"--pretrained {path}"))
    return [*run, *overrides]


def reproduce(
    data: str | Path,
    out: str | Path,
    budget: str = "small",
    seeds: Sequence[int] | int = (0,),
    pretrained: str | Path | None = None,
    only: Sequence[str] = (),
    n_boot: int = 1000,
    overrides: Sequence[str] = (),
    log: Callable[[str], None] = print,
    workers: int = 0,
) -> ReproduceResult:
    """Run the paper's experiments on ``data`` and write ``out/report.md`` and ``results.json``.

    Args:
        data: a dataset folder in the lookfeel layout.
        out: where runs, results and the report go (resumes what is there).
        budget: ``tiny``, ``small`` or ``paper`` (see the module docstring).
        seeds: the training seeds of every experiment, trained in this order, as
            ``lookfeel reproduce --seeds 0,1`` and `lookfeel.crossval.cross_validate` take
            them; numbers are means, with their spread. Seed ``s`` runs in
            ``out/runs/<name>/seed<s>``. An int ``n`` (the older form) is seeds 0 to n-1.
        pretrained: ImageNet AlexNet weights for the ``paper`` budget.
        only: experiment names to run (default: all).
        n_boot: bootstrap resamples of the test fabrics for the intervals.
        overrides: extra ``key=value`` config overrides for every run, after the budget's.
        log: where progress lines go.
        workers: runs trained at once, each in its own worker process with an equal share of
            the cores (`_run_jobs`). 0: on a CPU one per available core (up to the runs left),
            on CUDA 1. 1: one after the other in this process.

    Raises:
        ConfigError: an unknown budget or experiment, ``paper`` without weights, no seed, a
            negative or repeated one; before
            any training, runs in ``out`` trained on another dataset (`_trained_on_other_data`),
            a finished run asked for trained with other settings (`_differs`), or one scored
            with another ``n_boot`` whose checkpoint is gone.
    """
    with exclusive(out, "reproduce", "this folder"):  # a second one into ``out`` is refused
        return _reproduce(
            data, out, budget, seeds, pretrained, only, n_boot, overrides, log, workers
        )


def _reproduce(
    data: str | Path,
    out: str | Path,
    budget: str,
    seeds: Sequence[int] | int,
    pretrained: str | Path | None,
    only: Sequence[str],
    n_boot: int,
    overrides: Sequence[str],
    log: Callable[[str], None],
    workers: int,
) -> ReproduceResult:
    """`reproduce`'s work, while it holds ``out``'s lock."""
    if budget not in BUDGETS:
        raise ConfigError(f"budget {budget!r} is not one of {', '.join(BUDGETS)}")
    if budget == "paper" and pretrained is None:
        raise ConfigError(
            "budget 'paper' trains the paper's AlexNets with fc6 frozen, which needs the ImageNet "
            "weights: pass --pretrained PATH (pretrained=PATH; torchvision's "
            "alexnet-owt-7be5be79.pth); without them use --budget small (budget='small')"
        )
    seed_list = _seed_list(seeds)
    if workers < 0:
        raise ConfigError(f"workers must be >= 0 (0: one per core on a CPU), got {workers}")
    unknown = [n for n in only if n not in EXPERIMENT_NAMES]
    if unknown:
        raise ConfigError(
            f"unknown experiment(s) {', '.join(unknown)}; have: {', '.join(EXPERIMENT_NAMES)}"
        )
    data, out = Path(data), Path(out)
    catalog = scan(data, require=[], strict=True)
    fingerprint = catalog.fingerprint()
    saved = _saved_records(out)
    # Runs in ``out`` trained on another dataset are refused before anything is trained.
    other = _trained_on_other_data(out, catalog, saved)
    if other:
        names = ", ".join(str(p.relative_to(out)) for p in other[:3])
        more = f" and {len(other) - 3} more" if len(other) > 3 else ""
        raise ConfigError(
            f"{out} holds runs trained on another dataset ({names}{more}), or on {data} before "
            "its files or labels changed; use another --out"
        )
    # The paper's split is used when the data has at least 10 of its test fabrics (pick 1 of 10
    # needs 10); otherwise a cluster-stratified share of the training fabrics is held out
    # (the paper's test fabrics are never trained on either way): 18 of 118 as the paper, and
    # at least 10 when there are 30 or more.
    paper = paper_split(catalog)
    has_paper_test = len(paper.test) >= 10
    split, vision, n_val = split_overrides(has_paper_test, len(paper.train) or len(catalog.ids))
    result = ReproduceResult(out=out, report=out / "report.md")
    started = time.perf_counter()
    jobs: list[_Job] = []  # the runs asked for
    earlier: list[_Job] = []  # the finished runs of the experiments not asked for
    for exp in EXPERIMENTS:
        asked = not only or exp.name in only
        if not asked and not (out / "runs" / exp.name).is_dir():
            continue
        run_overrides = experiment_overrides(exp, budget, split, vision, overrides, pretrained)
        base = load_config(RunConfig, config_dir() / f"{exp.name}.yaml", run_overrides)
        reason = _needs(base, catalog)
        if not asked:
            if reason is None:
                earlier += _finished_runs(exp, run_overrides, out, log, saved)
            continue
        if reason is not None:
            result.skipped[exp.name] = reason
            log(f"skip {exp.name}: {reason}")
            continue
        for seed in seed_list:
            config = load_config(
                RunConfig, config_dir() / f"{exp.name}.yaml", [*run_overrides, f"train.seed={seed}"]
            )
            run_dir = out / "runs" / exp.name / f"seed{seed}"
            job = _Job(exp, config, run_dir, saved.get(run_dir))
            # Refused before any training, as a resume with another config is (an earlier
            # lookfeel's run without its config.yaml cannot be checked: read as it is).
            if job.finished and (job.run_dir / "config.yaml").exists():
                why = _differs(job.run_dir, config)
                if why is not None:
                    raise ConfigError(
                        f"{job.run_dir} is a finished run {why}: reproduce into another --out, "
                        "or delete the run to train it anew"
                    )
            jobs.append(job)
    others = _other_seeds(out, [job.exp.name for job in jobs], seed_list)
    if others:
        log(others)
    # Finished runs scored with another --n-boot, and Table 4's scored without raw pixels and
    # the background control or without the top-3 interval, are scored again from their
    # checkpoints (`_run_one`). One of the first whose checkpoint is gone is refused, before
    # any training; one of the others is reported with those numbers n/a.
    rescore: list[str] = []  # scored with another --n-boot
    add: list[str] = []  # scored without the controls of Table 4
    add_interval: list[str] = []  # with them, but without the top-3 interval
    gone: list[str] = []  # without the controls, and without a checkpoint
    gone_interval: list[str] = []  # without the top-3 interval, and without a checkpoint
    for job in [*jobs, *earlier]:
        if not job.finished:
            continue
        record = job.saved
        if record is None:  # it could not be read: say why
            record = json.loads((job.run_dir / "eval.json").read_text(encoding="utf-8"))
        otherwise, lacking = _scored_otherwise(record, n_boot), _missing_controls(record)
        no_interval = _missing_top3_interval(record)
        name = f"{job.exp.name} seed {job.config.train.seed}"
        if not (otherwise or lacking or no_interval):
            continue
        if (job.run_dir / "checkpoints" / "last.pt").is_file():
            (rescore if otherwise else add if lacking else add_interval).append(name)
        elif otherwise and record.get("n_boot") is not None:
            raise ConfigError(_cannot_rescore(job.run_dir, record["n_boot"], n_boot))
        else:
            if lacking:
                gone.append(name)
            if no_interval:
                gone_interval.append(name)
    if rescore:
        log(
            f"scoring again with --n-boot {n_boot}, from their checkpoints, the finished runs "
            f"scored otherwise: {', '.join(rescore)}"
        )
    if add:
        log(
            "scoring again from their checkpoints, to add raw pixels and the background control "
            f"beside Table 4's numbers, the finished runs scored without them: {', '.join(add)}"
        )
    if add_interval:
        log(
            "scoring again from their checkpoints, to add the top-3 interval to Table 4's "
            f"numbers, the finished runs scored without it: {', '.join(add_interval)}"
        )
    if gone:
        log(
            f"no raw pixels or background control for {', '.join(gone)}: scored without them "
            "by an earlier lookfeel, and the checkpoint is gone (the report says n/a)"
        )
    if gone_interval:
        log(
            f"no top-3 interval for {', '.join(gone_interval)}: scored without it by an earlier "
            "lookfeel, and the checkpoint is gone (the report says n/a)"
        )
    if earlier:
        found: dict[str, list[str]] = {}
        for job in earlier:
            found.setdefault(job.exp.name, []).append(str(job.config.train.seed))
        log(
            f"also reported, from finished runs in {out}: "
            + ", ".join(f"{name} (seed {', '.join(s)})" for name, s in found.items())
        )
    resolved = _workers_for(jobs, workers)
    records = _run_jobs(jobs, catalog, data, n_boot, workers, log)
    records += [
        _run_one(j.exp, j.config, catalog, data, j.run_dir, n_boot, j.saved) for j in earlier
    ]
    every = [*jobs, *earlier]
    for exp in EXPERIMENTS:
        mine = [r for job, r in zip(every, records, strict=True) if job.exp == exp]
        if mine:
            result.results[exp.name] = _aggregate(mine)
    result.findings = findings(result.results, only=list(only) or None)
    meta = {
        # The dataset folder, named as index info, embed and cv name it (``data`` before).
        "data_root": str(data),
        "budget": budget,
        # How many seeds each experiment trained (the report's "seeds: N"), and which, in order.
        "seeds": len(seed_list),
        "seed_list": seed_list,
        "overrides": list(overrides),
        # The bootstrap resamples of every interval (runs scored with another are scored again).
        "n_boot": n_boot,
        # --workers as given (0: the default) and how many runs trained at once here (none
        # left to train: 1).
        "workers": workers,
        "workers_resolved": resolved,
        "split": "paper" if has_paper_test else f"stratified, {n_val} held-out fabrics",
        "paper_test_fabrics": len(paper.test),
        # What this reproduction was asked to run (--only; None: every experiment), and the
        # experiments it was not asked for whose finished runs in ``out``, trained with the
        # same settings, it reports too: the results hold both.
        "only": list(only) or None,
        "earlier": list(dict.fromkeys(j.exp.name for j in earlier)),
        "minutes": round((time.perf_counter() - started) / 60, 1),
        # The runs behind the results and their own time (training and scoring, summed over
        # runs side by side; with the runs an earlier reproduction trained, which a resumed
        # one only reads).
        "runs": len(records),
        "run_minutes": round(sum(float(r.get("seconds") or 0.0) for r in records) / 60, 1),
        # The dataset (`Catalog.fingerprint`: its files, sizes and labels) and the software
        # behind the numbers.
        "data_fingerprint": fingerprint,
        "software": software_versions(),
    }
    result.meta = meta
    everything = {
        "meta": meta,
        "results": result.results,
        "skipped": result.skipped,
        "findings": result.findings,
    }
    # A number that could not be measured (NaN) is null: JSON has no NaN.
    atomic_write_json(out / "results.json", everything, indent=1)
    write_reproduction_report(result, meta)
    return result


def _seed_list(seeds: Sequence[int] | int) -> list[int]:
    """`reproduce`'s ``seeds`` as the list it trains: a sequence as given, an int ``n`` seeds 0
    to n-1 (the older form; the folders ``seed0`` to ``seed{n-1}`` either way).

    Raises:
        ConfigError: no seed, one that is not an integer >= 0, or one given twice.
    """
    if isinstance(seeds, int):
        if seeds < 1:
            raise ConfigError(f"seeds must be >= 1, got {seeds}")
        return list(range(seeds))
    listed = list(seeds)
    if not listed:
        raise ConfigError("seeds: at least one training seed is needed")
    bad = [s for s in listed if not isinstance(s, int) or isinstance(s, bool) or s < 0]
    if bad:
        raise ConfigError(f"seeds: each must be an integer >= 0, got {', '.join(map(repr, bad))}")
    repeated = sorted({s for s in listed if listed.count(s) > 1})
    if repeated:
        raise ConfigError(f"seeds: {', '.join(map(str, repeated))} given more than once")
    return listed


_FREE = (
    "model.pretrained",
    "train.progress",
    "train.threads",
    "train.log_every",
    "train.checkpoint_every",
    "data.cache_dir",
    "data.decode",
    "data.workers",
)
"""Config keys that change no number of a finished run: where the weights file was named from
(a run has its weights), the progress bar, logging and checkpoint intervals, the threads (the
run's ``eval.json`` records its count) and how images are decoded and cached."""


def _differs(run_dir: Path, config: RunConfig) -> str | None:
    """None when the finished run at ``run_dir`` is the one ``config`` asks for (`_FREE` keys
    aside, and what training resolves from the labels: `as_trained`); else how it is not, to
    follow "a finished run": "trained with other settings than this reproduction's (up to 4
    keys, ``key: trained A, asked B``)" or "whose config.yaml cannot be read (why)"."""
    path = run_dir / "config.yaml"
    try:
        trained = load_config(RunConfig, path)
    except (ConfigError, OSError, ValueError) as e:
        return f"whose {path.name} cannot be read ({e})"
    changed = config_changes(trained, config, _FREE)
    if not changed:
        return None
    keys = "; ".join(f"{k}: trained {was!r}, asked {now!r}" for k, was, now in changed[:4])
    more = f" and {len(changed) - 4} more" if len(changed) > 4 else ""
    return f"trained with other settings than this reproduction's ({keys}{more})"


_SEED_DIR = re.compile(r"seed(\d+)")


def _other_seeds(out: Path, names: Sequence[str], seeds: Sequence[int]) -> str | None:
    """The line saying that ``out`` holds finished runs of the experiments asked for
    (``names``) under seeds not asked for, which the report leaves out; None when it holds
    none. (Before ``--seeds`` took a list, ``--seeds 2`` asked for seeds 0 and 1: a folder of
    those, reproduced with ``--seeds 2``, trains seed 2 alone.)"""
    found: set[int] = set()
    for name in dict.fromkeys(names):
        folder = out / "runs" / name
        if not folder.is_dir():
            continue
        for path in folder.iterdir():
            match = _SEED_DIR.fullmatch(path.name)
            if match and (path / "eval.json").exists() and int(match.group(1)) not in seeds:
                found.add(int(match.group(1)))
    if not found:
        return None
    every = ",".join(str(s) for s in sorted({*seeds, *found}))
    held = ", ".join(str(s) for s in sorted(found))
    return (
        f"{out} also holds finished runs of seed{'s' if len(found) > 1 else ''} {held}, which "
        f"--seeds leaves out of the report (--seeds {every} reports them with these; --seeds "
        "lists the seeds themselves, as in cv: before session 56, --seeds N meant seeds 0 to "
        "N-1)"
    )


def _finished_runs(
    exp: Experiment,
    run_overrides: Sequence[str | Override],
    out: Path,
    log: Callable[[str], None],
    saved: Mapping[Path, dict[str, Any]],
) -> list[_Job]:
    """The finished runs of ``exp`` under ``out/runs`` (every seed's) trained with the settings
    this reproduction would train it with (``run_overrides``), by seed, each with its record
    from ``saved`` (`_saved_records`); each finished run trained otherwise is left out, with a
    line saying how it differs."""
    seeds = []
    for path in (out / "runs" / exp.name).iterdir():
        match = _SEED_DIR.fullmatch(path.name)
        if match and (path / "eval.json").exists():
            seeds.append(int(match.group(1)))
    found = []
    for seed in sorted(seeds):
        config = load_config(
            RunConfig, config_dir() / f"{exp.name}.yaml", [*run_overrides, f"train.seed={seed}"]
        )
        run_dir = out / "runs" / exp.name / f"seed{seed}"
        job = _Job(exp, config, run_dir, saved.get(run_dir))
        why = _differs(job.run_dir, config)
        if why is None:
            found.append(job)
        else:
            log(f"not reported: {job.run_dir}, a finished run {why}")
    return found


def _run_dirs(out: Path) -> list[Path]:
    """The run folders under ``out/runs`` (``<experiment>/seed<k>``), finished or started."""
    runs = out / "runs"
    if not runs.is_dir():
        return []
    found = sorted(runs.glob("*/seed*"))
    return [d for d in found if _SEED_DIR.fullmatch(d.name) and d.is_dir()]


def _saved_records(out: Path) -> dict[Path, dict[str, Any]]:
    """The ``eval.json`` record of every finished run under ``out/runs``, by run folder: each
    file read once for the whole reproduction (`_trained_on_other_data`, the runs to score
    again, `_run_one`). One that cannot be read as a JSON object is left out."""
    records: dict[Path, dict[str, Any]] = {}
    for run_dir in _run_dirs(out):
        try:
            saved = json.loads((run_dir / "eval.json").read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        if isinstance(saved, dict):
            records[run_dir] = saved
    return records


def _trained_on_other_data(
    out: Path, catalog: Catalog, saved: Mapping[Path, Mapping[str, Any]]
) -> list[Path]:
    """The runs under ``out/runs`` (``<experiment>/seed<k>``, finished or started) trained on
    another dataset than ``catalog``, or on it before its files or labels changed
    (`Catalog.matches_fingerprint`). ``saved``: the finished runs' records (`_saved_records`).
    A run that records no dataset (trained before lookfeel recorded it, or with no checkpoint
    yet) is taken as trained on it."""
    matches: dict[str, bool] = {}
    other = []
    for run_dir in _run_dirs(out):
        recorded = _recorded_fingerprint(run_dir, saved.get(run_dir))
        if recorded is None:
            continue
        if recorded not in matches:
            matches[recorded] = catalog.matches_fingerprint(recorded)
        if not matches[recorded]:
            other.append(run_dir)
    return other


def _recorded_fingerprint(run_dir: Path, saved: Mapping[str, Any] | None) -> str | None:
    """The dataset the run at ``run_dir`` was trained on (`Catalog.fingerprint`), or None when
    it records none: from ``saved``, its ``eval.json``'s record, when finished (since it
    records it), else from the checkpoint it resumes from (`resume_checkpoint`; an ensemble's:
    its members'). Only the checkpoint's small entries are read: its tensors are mapped, not
    loaded."""
    if saved is not None and isinstance(saved.get("data_fingerprint"), str):
        return str(saved["data_fingerprint"])
    members = sorted((run_dir / MEMBERS).glob("*")) if (run_dir / MEMBERS).is_dir() else []
    for folder in [run_dir, *members]:
        path = resume_checkpoint(folder)
        if path is None:
            continue
        try:
            state = torch.load(path, map_location="cpu", weights_only=True, mmap=True)
        except Exception:  # damaged or foreign: resuming or scoring it says so
            continue
        recorded = state.get("data_fingerprint") if isinstance(state, dict) else None
        if isinstance(recorded, str):
            return recorded
    return None


def headline(results: Mapping[str, Any]) -> list[str]:
    """A few lines of the most telling numbers, for the terminal: each with its 95% interval
    over the test fabrics, where scored, and its chance. Each Table 4 model's line is followed,
    where recorded, by an indented line of its controls on the same queries: the model with
    the backgrounds swapped, raw pixels, and raw pixels with the backgrounds swapped:

        snn_depth    depth->depth top-1 on novel fabrics 0.467 [0.415, 0.518] (chance 0.100)
            background swapped 0.449 [0.398, 0.500]; raw pixels 0.327 [0.281, 0.372],
            swapped 0.320 [0.275, 0.366]

    (the second line is one line, under 110 characters). A number not measured is ``n/a``,
    with no interval."""
    lines = []

    def number(v: Any) -> str:  # a cell that could not be scored is n/a, never "nan"
        return f"{v:.3f}" if isinstance(v, (int, float)) and math.isfinite(v) else "n/a"

    def shown(r: Mapping[str, Any], key: str) -> str:
        low, high = r.get(f"{key}_ci_low"), r.get(f"{key}_ci_high")
        if number(r.get(key)) == "n/a" or number(low) == "n/a" or number(high) == "n/a":
            return number(r.get(key))
        return f"{number(r.get(key))} [{number(low)}, {number(high)}]"

    def cell(r: Mapping[str, Any], key: str, chance: str) -> str:
        return f"{shown(r, key)} (chance {number(r.get(chance))})"

    for name in ("multi_input", "cross_modal", "flat"):
        r = results.get(name, {}).get("metrics")
        if r and "touch_to_depth_top1" in r:
            lines.append(
                f"{name:<12} touch->depth top-1 "
                f"{cell(r, 'touch_to_depth_top1', 'touch_to_depth_top1_chance')}"
            )
    for name in ("snn_depth", "cross_modal_depth_touch"):
        r = results.get(name, {}).get("novel")
        if r:
            lines.append(
                f"{name:<12} depth->depth top-1 on novel fabrics {cell(r, 'top1', 'chance')}"
            )
            if "raw_pixels_top1" in r:
                lines.append(
                    f"    background swapped {shown(r, 'top1_swapped')}; raw pixels "
                    f"{shown(r, 'raw_pixels_top1')}, swapped {shown(r, 'raw_pixels_top1_swapped')}"
                )
    return lines
