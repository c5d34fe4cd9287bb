"""Running a cross-validation: the folds each run holds out (checked before anything is trained),
each run's config and the key that says whether a kept result still stands, and
`cross_validate`, which trains every fold and seed, scores each run (`lookfeel.crossval.score`),
pools the runs (`lookfeel.crossval.summary`) and writes ``cv.json`` and ``cv.md``
(`lookfeel.crossval.report`). What cv measures and writes: the package docstring
(`lookfeel.crossval`).
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
import time
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from lookfeel.atomic import atomic_write_json, atomic_write_text, finite_or_null
from lookfeel.checkpoint import load_model
from lookfeel.config import RunConfig
from lookfeel.config._core import ConfigError, to_dict
from lookfeel.crossval.report import _count, format_cv_summary
from lookfeel.crossval.score import RoomProbe, _evaluate_run, _modalities, _pairs, _with_room
from lookfeel.crossval.summary import CONTROL_SEED, _check_n_boot, _scored_mean, _summarise
from lookfeel.data import (
    Catalog,
    ImageLoader,
    SplitError,
    paper_split,
    scan,
    stratified_fabric_folds,
)
from lookfeel.data.background_swap import BackgroundControl
from lookfeel.data.recordings import drop_unpressed
from lookfeel.data.touch_control import UntouchedControl
from lookfeel.evaluate.core import no_query_scored
from lookfeel.metrics import mean_and_spread
from lookfeel.metrics.cross_map import HUB_NEIGHBOURS
from lookfeel.modality import Modality, Pair
from lookfeel.provenance import software_versions
from lookfeel.train import run_started, select_split, train
from lookfeel.train.loop import as_trained

__all__ = ["MIN_HELD_OUT", "REPORT", "RESULT", "SUMMARY", "cross_validate"]

RESULT = "result.json"
SUMMARY = "cv.json"
REPORT = "cv.md"


def _run_config(config: RunConfig, fold: int, seed: int) -> RunConfig:
    t = dataclasses.replace(config.train, split="fold", fold=fold, seed=seed)
    return dataclasses.replace(config, train=t)


def _write_json(path: Path, data: Any, indent: int | None = None) -> None:
    """``data`` as strict JSON (`lookfeel.atomic.finite_or_null`), written atomically."""
    atomic_write_json(path, data, indent)


def _noun(catalog: Catalog) -> str:
    """What the data's items are called: ``object`` where the data names them (videos/
    sponge_0.mov), else ``fabric`` (as `lookfeel data info` says)."""
    return "object" if any(f.name is not None for f in catalog.fabrics) else "fabric"


MIN_HELD_OUT = 2
"""Fabrics (objects) a fold must hold out: among one, pick 1 of 10 and every probe is moot."""


def _fold_plan(catalog: Catalog, config: RunConfig, fold_list: Sequence[int]) -> dict[str, Any]:
    """Which fabrics (or objects) the folds hold out, checked before anything is trained: the
    same folds `lookfeel.train.select_split` makes, of the fabrics not kept for the paper's
    test (`paper_split`). Returns what ``cv.md``'s first line reports (``coverage`` in
    ``cv.json``): the held-out items of the folds run, the folds not run, the fabrics that no
    fold holds out (a ``train.fold_size``) and those never used, with why.

    Raises:
        SplitError: fewer than 2 folds, or a fold holding out fewer than `MIN_HELD_OUT` (one
            line naming ``--folds`` / ``--fold-size`` and how many there are), or folds too
            big for the fabrics (`stratified_fabric_folds`).
    """
    t = config.train
    noun = _noun(catalog)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # select_split says it, once, right after
        paper = paper_split(catalog)
    pool = list(paper.train) or catalog.ids
    never = [i for i in catalog.ids if i not in set(pool)]
    n = len(pool)
    kept = (
        ""
        if not never
        else f" ({_count(len(never), noun)} more, kept for the paper's test, never used)"
    )
    if t.folds < 2:
        raise SplitError(
            f"--folds {t.folds} (train.folds): cross-validation needs at least 2 folds"
        )
    if n < 2 * MIN_HELD_OUT:
        raise SplitError(
            f"{catalog.root} has {_count(n, noun)} to hold out{kept}; cross-validation needs at "
            f"least {2 * MIN_HELD_OUT}: 2 folds of {MIN_HELD_OUT} (a fold holding out one "
            f"{noun} finds it among itself alone, always right)"
        )
    if t.fold_size is not None and t.fold_size < MIN_HELD_OUT:
        raise SplitError(
            f"--fold-size {t.fold_size} (train.fold_size): a fold must hold out at least "
            f"{MIN_HELD_OUT} {noun}s to be scored (among one, pick 1 of 10 is always right); "
            f"use --fold-size {MIN_HELD_OUT} or more (at most {n // t.folds} for {t.folds} folds "
            f"of the {n} {noun}s)"
        )
    if t.fold_size is not None and t.folds * t.fold_size > n and n // t.folds < MIN_HELD_OUT:
        raise SplitError(  # `stratified_fabric_folds` would suggest a size of 1 or 0
            f"--folds {t.folds} of --fold-size {t.fold_size} (train.folds, train.fold_size) hold "
            f"out {t.folds * t.fold_size} {noun}s; {catalog.root} has {n}{kept}: use --folds "
            f"{n // MIN_HELD_OUT} or fewer with --fold-size {MIN_HELD_OUT}"
        )
    if t.fold_size is None and n // t.folds < MIN_HELD_OUT:
        raise SplitError(
            f"--folds {t.folds} (train.folds) of the {n} {noun}s of {catalog.root}{kept} "
            f"leaves {n // t.folds} held out in some fold; a fold must hold out at least "
            f"{MIN_HELD_OUT} to be scored (among one, pick 1 of 10 is always right): use "
            f"--folds {n // MIN_HELD_OUT} or fewer"
        )
    folds = stratified_fabric_folds(
        pool,
        catalog.clusters(),
        t.folds,
        seed=t.split_seed,
        fold_size=t.fold_size,
        excluded=len(paper.test),
        excluded_by=paper.source or "labels",
    )
    names = {f.id: f.display_name for f in catalog.fabrics}
    tested = [sorted(folds[f].test) for f in fold_list]
    not_run = [f for f in range(t.folds) if f not in fold_list]
    if paper.source == "builtin":
        why = "GelFabric's built-in list of the paper's test fabrics (and fabric 107, excluded)"
    else:
        marks = [catalog.fabric(i).paper_split for i in never]
        why = ", ".join(
            f"{marks.count(k)} marked paper_split={k}" if k else f"{marks.count(k)} unmarked"
            for k in dict.fromkeys(marks)
        )
        why += " in labels.csv (cv holds out and trains on the paper_split=train ones only)"
    return {
        "noun": noun,
        "items": len(catalog.ids),
        "held_out": sorted({i for test in tested for i in test}),
        "fold_sizes": [len(test) for test in tested],
        "folds_total": t.folds,
        "not_run": {
            "folds": not_run,
            "items": sorted({i for f in not_run for i in folds[f].test}),
        },
        "train_only": sorted(set(pool) - {i for f in folds for i in f.test}),
        "never_used": {
            "ids": never,
            "items": [names[i] for i in never],
            "why": why if never else None,
        },
    }


_NO_EFFECT = ("checkpoint_every", "log_every", "progress")
"""Train keys that do not change a run's result: runs differing only in them are the same."""


_NO_EFFECT_MODEL = ("class_temperature",)
"""Model keys that change neither training nor the cv's scores (`predict` reads them)."""


def _result_config(config: RunConfig) -> dict[str, Any]:
    """The config as plain data, without the keys that do not change the result."""
    d = to_dict(config)
    d["train"] = {k: v for k, v in d["train"].items() if k not in _NO_EFFECT}
    d["model"] = {k: v for k, v in d["model"].items() if k not in _NO_EFFECT_MODEL}
    if not d["loss"].get("options"):  # none given: as a result kept from before options were
        d["loss"].pop("options", None)
    return d


def _same_run(trained: RunConfig, asked: RunConfig) -> bool:
    """Whether a trained run's config is ``asked`` (what training resolves from the labels,
    `as_trained`, is no difference)."""
    return _result_config(trained) == _result_config(as_trained(asked, trained))


def _result_key(
    cfg: RunConfig,
    tta: bool,
    pairs: Sequence[Pair],
    presses: int,
    control: BackgroundControl | None,
    labelled: bool = False,
) -> dict[str, Any]:
    """What a run's ``result.json`` records as its ``key``: a kept result stands only when
    its key is this one (the run's config and how it is scored). ``labelled``: the data has
    label columns, so the run has property probes."""
    key: dict[str, Any] = {"config": _result_config(cfg), "tta": tta, "pairs": list(pairs)}
    # How the maps score (session 22 added the hub correction): a result scored
    # otherwise is scored again from its checkpoint, never silently kept.
    key["cross_map_hubs"] = HUB_NEIGHBOURS
    key = finite_or_null(key)  # as result.json holds it
    if presses > 1:
        key["presses"] = presses
        key["pooled_gallery"] = True  # session 23: touch candidates pooled too
    if cfg.model.class_heads:
        key["class_logits"] = True  # session 47: the heads' calibration needs them
    if labelled:
        key["probe_predictions"] = True  # session 55: the probes' intervals pool them
    if control is not None:
        key["background_control"] = CONTROL_SEED
        if control.has_room_control:
            key["room_control"] = True
    return key


SHOWN_DIFFERENCES = 3
"""Differences of a kept result's key that the "scoring again" line names (then "and N more")."""


_ABSENT = object()
"""A key that a kept result's key, or the key of now, does not have (`_key_differences`)."""


def _key_differences(saved: Any, now: Any, name: str = "") -> list[str]:
    """Where a kept result's ``key`` (``saved``) differs from ``now``'s, each as ``NAME NOW,
    was OLD`` (JSON values; ``not recorded`` for a key the result does not have, as when a
    newer lookfeel adds a config field; ``none now`` for one no longer in the key). A config
    key is named as the config names it (``data.video_rotate``, not ``config.data...``)."""
    if isinstance(saved, dict) and isinstance(now, dict):
        found = []
        for k in [*now, *(k for k in saved if k not in now)]:
            inner = f"{name}.{k}" if name else str(k)
            found += _key_differences(saved.get(k, _ABSENT), now.get(k, _ABSENT), inner)
        return found
    if saved == now:
        return []
    label = name.removeprefix("config.")
    return [f"{label} {_short(now, 'none now')}, was {_short(saved, 'not recorded')}"]


def _short(value: Any, absent: str) -> str:
    """``value`` as JSON, cut at 40 characters; ``absent`` for `_ABSENT`."""
    if value is _ABSENT:
        return absent
    text = json.dumps(value, default=str)
    return text if len(text) <= 40 else text[:37] + "..."


def _rescore_reason(saved: dict[str, Any] | None, key: dict[str, Any]) -> str:
    """Why a finished run is scored again (its kept ``result.json`` is ``saved``, the key of
    now ``key``), as a clause in parentheses for its "scoring again" line: the keys that
    differ (`_key_differences`, the first `SHOWN_DIFFERENCES`), and whether the result was
    scored by another lookfeel where it records which."""
    if saved is None:
        return "(no result.json kept)"
    old = saved.get("key")
    if not isinstance(old, dict):
        return "(scored by an earlier lookfeel, whose result.json records no key)"
    software = saved.get("software")
    version = software.get("lookfeel") if isinstance(software, dict) else None
    now = software_versions()["lookfeel"]
    if version is None:
        who = "scored by an earlier lookfeel or with other settings"
    elif version != now:
        who = f"scored by lookfeel {version} or with other settings"
    else:
        who = "scored with other settings"
    found = _key_differences(old, key)
    if not found:  # equal as plain data: a value JSON does not keep as it was
        return f"({who})"
    shown = "; ".join(found[:SHOWN_DIFFERENCES])
    more = f"; and {len(found) - SHOWN_DIFFERENCES} more" if len(found) > SHOWN_DIFFERENCES else ""
    return f"({who}: {shown}{more})"


def _recorded_data(saved: dict[str, Any]) -> tuple[str | None, str | None]:
    """The dataset folder and fingerprint (`Catalog.fingerprint`) a kept ``result.json``
    records: ``data_root`` and ``data_fingerprint``, or an earlier lookfeel's ``data: {root,
    fingerprint}``, read alike so that its folder resumes as before. (None, None) where it
    records none (written before lookfeel recorded it): taken as this data's."""
    if "data_fingerprint" in saved:
        root, fingerprint = saved.get("data_root"), saved["data_fingerprint"]
    else:
        old = saved.get("data")
        root, fingerprint = (old.get("root"), old.get("fingerprint")) if old else (None, None)
    return (
        None if root is None else str(root),
        None if fingerprint is None else str(fingerprint),
    )


_RUN_DIR = re.compile(r"seed(\d+)-fold(\d+)")


def _other_finished_runs(
    out: Path,
    config: RunConfig,
    catalog: Catalog,
    asked: set[tuple[int, int]],
    key_of: Callable[[RunConfig], dict[str, Any]],
) -> list[tuple[int, int]]:
    """(seed, fold) of the runs in ``out`` outside ``asked`` that are finished with the same
    settings on the same data: what a cv of them too would keep, not train or score again
    (`cross_validate`'s "done before, kept"). Sorted."""
    found = []
    for run_dir in out.iterdir() if out.is_dir() else ():
        m = _RUN_DIR.fullmatch(run_dir.name)
        if m is None:
            continue
        seed, fold = int(m[1]), int(m[2])
        if run_dir.name != f"seed{seed}-fold{fold}" or fold >= config.train.folds:
            continue  # not a folder cv makes (seed01-fold1), or not a fold of this config
        if (seed, fold) in asked:
            continue
        try:
            saved = json.loads((run_dir / RESULT).read_text(encoding="utf-8"))
            _, recorded = _recorded_data(saved)  # none: kept as this data's
            same_data = recorded is None or catalog.matches_fingerprint(recorded)
            key = saved.get("key")
        except (OSError, ValueError, TypeError, KeyError, AttributeError):
            continue  # no result (a run not finished), or not one cv wrote
        if same_data and key == key_of(_run_config(config, fold, seed)):
            found.append((seed, fold))
    return sorted(found)


def _others_line(
    out: Path,
    others: list[tuple[int, int]],
    seeds: Sequence[int],
    folds: Sequence[int],
    done: set[tuple[int, int]],
) -> str:
    """The line that names finished runs outside a cv's summary and how to summarise them
    together with it: the seeds and folds of both, and the runs of those not finished with
    these settings (``done`` are), which that cv would train or score first."""
    all_seeds = sorted({*seeds, *(s for s, _ in others)})
    all_folds = sorted({*folds, *(f for _, f in others)})
    missing = [(s, f) for s in all_seeds for f in all_folds if (s, f) not in done]

    def runs(which: list[tuple[int, int]]) -> str:
        return ", ".join(f"seed {s} fold {f}" for s, f in which)

    command = (
        f"`lookfeel cv` with the same options but --seeds "
        f"{','.join(map(str, all_seeds))} --only-folds {','.join(map(str, all_folds))}"
    )
    how = (
        "summarises them together without training"
        if not missing
        else f"summarises them together, running {runs(missing)} first"
    )
    return (
        f"{out} also holds finished runs of {runs(others)}, scored with these settings (not "
        f"in this summary): {command} {how}"
    )


def cross_validate(
    config: RunConfig,
    data: str | Path,
    out: str | Path,
    *,
    seeds: Sequence[int] = (0,),
    folds: Sequence[int] | None = None,
    tta: bool = False,
    n_boot: int = 1000,
    background_control: bool = True,
    presses: int | None = None,
    log: Callable[[str], None] = print,
) -> dict[str, Any]:
    """Train and score ``config`` on every requested fold and seed; write ``cv.json`` and ``cv.md``.

    Args:
        config: the run config; its ``train.split``, ``train.fold`` and ``train.seed`` are set
            per run, ``train.folds``, ``train.fold_size`` and ``train.split_seed`` define the
            folds.
        data: the dataset folder.
        out: the cross-validation folder (created; reruns skip finished runs, and refuse a
            folder whose runs were made on another dataset: `Catalog.fingerprint`).
        seeds: training seeds.
        folds: which folds to run (default: all ``train.folds``).
        tta: embed each image and its left-right mirror and average the two (test-time pooling).
        n_boot: bootstrap resamples for the intervals; 0 draws none: the numbers without
            intervals (null in ``cv.json``; ``cv.md`` says no interval was drawn).
        background_control: for a config with depth pairs, also score every run with the
            depth images' backgrounds swapped (package doc); about 0.2 s per held-out depth
            image once per fold (registration), shared by the seeds.
        presses: presses of one fabric pooled into a touch query (the Multi-input Net's
            protocol); default the config's ``data.presses``.
        log: where progress lines go.

    Returns:
        The summary that ``cv.json`` holds.

    Raises:
        SplitError: folds that hold out fewer than 2 fabrics (objects), or more than there are
            (`_fold_plan`), before anything is written or trained.
        ConfigError: a fold out of range, no seed, more presses than a fabric has, or a
            negative ``n_boot``.
    """
    out = Path(out)
    t = config.train
    fold_list = list(range(t.folds)) if folds is None else list(folds)
    for f in fold_list:
        if not 0 <= f < t.folds:
            raise ConfigError(f"fold {f}: the config has train.folds={t.folds} (0..{t.folds - 1})")
    if not seeds:
        raise ConfigError("seeds: at least one training seed is needed")
    _check_n_boot(n_boot)
    presses = config.data.presses if presses is None else presses
    if presses < 1:
        raise ConfigError(f"presses: a touch query pools at least 1 press, got {presses}")
    pairs = _pairs(config)
    loader = ImageLoader(config.data)  # runs differ only in train keys: one decode for all
    catalog = drop_unpressed(scan(data, require=config.train.modalities, strict=True), loader)
    # The folds and the touch queries checked before anything is printed, written or trained.
    coverage = _fold_plan(catalog, config, fold_list)
    noun = coverage["noun"]
    select_split(catalog, _run_config(config, fold_list[0], seeds[0]))
    kinds = [k.value for k in config.data.touch_kinds]
    if presses > 1 and Modality.TOUCH in _modalities(pairs):
        most = catalog.most_presses(config.data.touch_kinds)
        if most < presses:
            raise ConfigError(
                f"presses: no held-out fabric has {presses} touch presses ({', '.join(kinds)}) "
                f"to pool into a query (no fabric of {catalog.root} has more than {most}); use "
                f"--presses {max(most, 1)} or fewer"
            )
    out.mkdir(parents=True, exist_ok=True)
    uses_depth = any(Modality.DEPTH in (p.query, p.gallery) for p in pairs)
    control = (
        BackgroundControl(config.data, CONTROL_SEED) if background_control and uses_depth else None
    )
    untouched = UntouchedControl(config.data)  # shared by the seeds of a fold
    room = RoomProbe(catalog, config.data.workers) if control is not None else None
    labelled = bool(catalog.label_columns)
    # The dataset's folder and fingerprint (`Catalog.fingerprint`), in cv.json and each
    # result.json, named as index info and embed name them.
    data_id = {"data_root": str(catalog.root), "data_fingerprint": catalog.fingerprint()}
    results = []
    for seed in seeds:
        for fold in fold_list:
            run_dir = out / f"seed{seed}-fold{fold}"
            cfg = _run_config(config, fold, seed)
            result_path = run_dir / RESULT
            key = _result_key(cfg, tta, pairs, presses, control, labelled)
            saved = (
                json.loads(result_path.read_text(encoding="utf-8"))
                if result_path.exists()
                else None
            )
            was_at, recorded = _recorded_data(saved) if saved is not None else (None, None)
            if recorded is not None and not catalog.matches_fingerprint(recorded):
                raise ConfigError(
                    f"{run_dir} holds a run on another dataset ({was_at}), or on "
                    f"{catalog.root} before its files or labels changed; use another --out"
                )
            if saved is not None and saved.get("key") == key:
                log(f"seed {seed} fold {fold}: done before, kept ({result_path})")
                results.append(_with_room(saved, run_dir, room))
                continue
            last = run_dir / "checkpoints" / "last.pt"
            done = load_model(last) if last.exists() else None
            if done is not None and done.step >= cfg.train.steps:
                if not _same_run(done.config, cfg):
                    raise ConfigError(
                        f"{run_dir} holds a finished run of another config; use another --out"
                    )
                # Trained before, scored differently (e.g. --tta): score again, keep the time.
                reason = _rescore_reason(saved, key)
                log(f"seed {seed} fold {fold}: trained before, scoring again {reason}")
                kept = saved.get("train_seconds") if saved else None
                seconds = math.nan if kept is None else float(kept)
            else:
                started = time.perf_counter()
                started_before = run_started(run_dir)
                verb = "resuming" if started_before else "training in"
                log(f"seed {seed} fold {fold}: {verb} {run_dir}")
                train(cfg, data, run_dir, resume=started_before)
                seconds = time.perf_counter() - started
            res = _evaluate_run(run_dir, catalog, pairs, tta, loader, control, untouched, presses)
            res |= {"key": key, "seed": seed, "fold": fold, "train_seconds": seconds}
            res |= data_id
            res["software"] = software_versions()  # which lookfeel scored it (`_rescore_reason`)
            res = _with_room(res, run_dir, room)
            _write_json(result_path, res)
            first = res["pairs"][pairs[0]]
            top1 = _scored_mean(np.asarray(first["model"], np.float64)[:, 0])
            extra = "".join(
                f", {name} {_scored_mean(np.asarray(first[method], np.float64)[:, 0]):.3f}"
                for method, name in (
                    ("model_labels", "label space"),
                    ("model_mapped", "cross-modal map"),
                    ("model_swapped", "background swapped"),
                    ("model_room", "in another's room"),
                )
                if method in first
            )
            took = "" if math.isnan(seconds) else f" (trained in {seconds:.0f} s)"
            if math.isnan(top1):  # no query had its own fabric to find: the report says why
                log(f"seed {seed} fold {fold}: {pairs[0]} not scored{took}")
            else:
                log(f"seed {seed} fold {fold}: {pairs[0]} top-1 {top1:.3f}{extra}{took}")
            results.append(res)
    names = {f.id: f.display_name for f in catalog.fabrics}

    def why(pair: Pair) -> str:
        return no_query_scored(pair, presses, fabrics="held-out", kinds=kinds, option="--presses ")

    values = catalog.label_matrix(catalog.label_columns)
    used = [v for i, v in values.items() if i not in set(coverage["never_used"]["ids"])]
    label_values = {
        col: [v[j] for v in used if not math.isnan(v[j])]
        for j, col in enumerate(catalog.label_columns)
    }
    summary = _summarise(
        results, pairs, n_boot, control is not None, names, why, label_values, noun
    ) | {
        "folds": fold_list,
        "seeds": list(seeds),
        "fold_size": t.fold_size,
        "tta": tta,
        "presses": presses,
        "train_seconds": mean_and_spread([r["train_seconds"] for r in results]),
        "config": to_dict(config),
        "coverage": coverage,
        "n_boot": n_boot,
        **data_id,
        "software": software_versions(),
    }
    _write_json(out / SUMMARY, summary, indent=1)
    atomic_write_text(out / REPORT, format_cv_summary(summary))
    asked = {(seed, fold) for seed in seeds for fold in fold_list}
    others = _other_finished_runs(
        out,
        config,
        catalog,
        asked,
        lambda cfg: _result_key(cfg, tta, pairs, presses, control, labelled),
    )
    if others:
        log(_others_line(out, others, seeds, fold_list, asked | set(others)))
    return summary
