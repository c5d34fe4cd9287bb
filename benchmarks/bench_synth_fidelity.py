"""Fidelity of the synthetic drapes: a depth encoder trained only on synthetic depth, scored on
real GelFabric depth (issue #3's target: it beats the raw-pixel nearest neighbour).

Generates a synthetic depth-only world, trains `configs/real_depth.yaml`'s recipe on all of it
(no real image is seen), and scores pick 1 of 10 among the 100 real training fabrics, beside
raw pixels and chance, with 95% intervals that resample the real fabrics, and the background
control (each real image's background swapped with another fabric's, cloth kept). Since issue
#12 the recipe trains on registered depth (`data.depth_input: registered`): the synthetic
world's room registers as the real one does (floor, wall, side panel), so both worlds are
seen as the cloth's height above the fitted floor. One network (`model.members=1`): the recipe
has trained three used as one since session 32, which triples the training and is a gain on
real depth; this benchmark asks what synthetic drapes teach, so it keeps the single network
every stored result was measured with; ``python -m benchmarks.bench_synth_fidelity --data
DIR --members 3 --out FILE`` trains the recipe's three (``--keep DIR`` keeps the world and the
run, to score again; ``--set KEY=VALUE`` changes the recipe). Needs --data.

Since session 47 it also asks what the world's *labels* teach (`zero_shot_properties`): the
run's property head, trained on the synthetic fabrics' labels only, predicts each real fabric's
labels from its registered drapes, scored by Spearman's rank correlation with the real labels
(95% interval resampling real fabrics), beside a ridge fitted on the synthetic fabrics' mean
embeddings and the same ridge on their mean raw pixels (the baseline). Ranks, because the
world's label scales need not be reality's: what carries is the order.

One network's top-1 moves with the number of threads it trained on, as it does with its seed
(float sums in another order: the run diverges within the first 50 steps). Session 45's 0.326
was one thread; the same command on two threads read 0.267 in session 47.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy.stats import spearmanr

from benchmarks.__main__ import add_set_option, write_standalone
from lookfeel.config import ConfigError, RunConfig, load_config
from lookfeel.crossval import score_checkpoint
from lookfeel.data import Catalog, Item
from lookfeel.modality import Modality
from lookfeel.synth import SynthConfig, generate
from lookfeel.train import train

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "real_depth.yaml"
N_BOOT = 1000
"""Bootstrap resamples of the real fabrics for the rank correlations' intervals."""
FABRICS = 300
DRAPES = 10
MEMBERS = 1


def spearman_with_ci(
    pred: np.ndarray, truth: np.ndarray, n_boot: int = N_BOOT, seed: int = 0
) -> dict[str, Any]:
    """Spearman's rank correlation of (F,) ``pred`` with ``truth`` (one row per fabric; NaN
    rows left out) and its 95% percentile interval over ``n_boot`` resamples of the fabrics."""
    ok = ~(np.isnan(pred) | np.isnan(truth))
    p, t = pred[ok], truth[ok]
    if len(p) < 3 or np.ptp(t) == 0 or np.ptp(p) == 0:
        return {"spearman": math.nan, "ci95": [math.nan, math.nan], "fabrics": len(p)}
    rng = np.random.default_rng(seed)
    boots = []
    for _ in range(n_boot):
        i = rng.integers(0, len(p), len(p))
        if np.ptp(t[i]) > 0 and np.ptp(p[i]) > 0:
            boots.append(spearmanr(p[i], t[i]).statistic)
    low, high = np.percentile(boots, [2.5, 97.5])
    return {
        "spearman": round(float(spearmanr(p, t).statistic), 4),
        "ci95": [round(float(low), 4), round(float(high), 4)],
        "fabrics": len(p),
    }


def ridge_transfer(x_src: np.ndarray, y_src: np.ndarray, x_tgt: np.ndarray) -> np.ndarray:
    """A ridge fitted on the source rows whose label is known (`lookfeel.metrics.fit_ridge`),
    applied to every target row: (F_src, D), (F_src,), (F_tgt, D) -> (F_tgt,)."""
    from lookfeel.metrics.properties import fit_ridge

    known = ~np.isnan(y_src)
    coef, intercept = fit_ridge(x_src[known], y_src[known])
    return np.asarray(x_tgt @ coef + intercept, dtype=np.float64)


def _fabric_means(
    x: np.ndarray, catalog: Catalog, items: Sequence[Item], columns: Sequence[str]
) -> tuple[np.ndarray, np.ndarray]:
    """Each fabric's mean row of ``x`` (one row per item) and its labels (NaN: unknown)."""
    from lookfeel.metrics.properties import per_fabric_means

    fabric = np.array([it.fabric_id for it in items])
    labels = {f.id: f.labels for f in catalog.fabrics}
    y = np.array([[labels[int(i)].get(c, math.nan) for c in columns] for i in fabric], float)
    means, lab, _ = per_fabric_means(np.asarray(x, np.float64), y, fabric)
    return means, lab


def zero_shot_properties(checkpoint: Path, world: Path, data: Path) -> dict[str, Any]:
    """What the synthetic world's labels teach about real drapes (module doc): per label both
    worlds have, `spearman_with_ci` over the real fabrics of the run's property head, of a
    ridge on the synthetic fabrics' mean embeddings and of one on their mean raw pixels."""
    import torch

    from lookfeel.checkpoint import load_model
    from lookfeel.data import ImageLoader, scan
    from lookfeel.embedding import embed_items, raw_pixels
    from lookfeel.models import PROPERTY

    lm = load_model(checkpoint)
    depth = Modality.DEPTH
    loader = ImageLoader(lm.config.data)
    real, synth = scan(data, require=[depth]), scan(world, require=[depth])
    columns = [c for c in lm.label_columns if c in real.label_columns]
    if not columns:
        return {"skipped": "the real and synthetic labels share no column"}
    real_items, synth_items = real.items(depth), synth.items(depth)
    feats = {}
    for name, cat, items in (("real", real, real_items), ("synth", synth, synth_items)):
        emb = embed_items(lm.model, items, loader)
        pix = raw_pixels(items, loader)
        feats[name] = {
            "embedding": _fabric_means(emb, cat, items, columns),
            "raw_pixels": _fabric_means(pix, cat, items, columns),
        }
        if name != "real":
            continue
        with torch.inference_mode():
            out = lm.model.branch(depth.value).heads(torch.from_numpy(emb).float())
        if PROPERTY in out:  # the run's own head, on the real drapes
            head = out[PROPERTY].float().numpy().astype(np.float64)
            for j, col in enumerate(lm.label_columns):  # back to the label's units
                mean, std = lm.label_stats.get(col, (0.0, 1.0))
                head[:, j] = mean + std * head[:, j]
            keep = [lm.label_columns.index(c) for c in columns]
            feats[name]["head"] = _fabric_means(head[:, keep], cat, items, columns)
    labels: dict[str, Any] = {}
    for j, col in enumerate(columns):
        truth = feats["real"]["embedding"][1][:, j]
        entry: dict[str, Any] = {}
        if "head" in feats["real"]:
            entry["head"] = spearman_with_ci(feats["real"]["head"][0][:, j], truth)
        for kind in ("embedding", "raw_pixels"):
            x_src, y_src = feats["synth"][kind][0], feats["synth"][kind][1][:, j]
            pred = ridge_transfer(x_src, y_src, feats["real"][kind][0])
            entry[f"{kind}_ridge"] = spearman_with_ci(pred, truth)
        labels[col] = entry
    return {
        "what": "Spearman of each real fabric's predicted label (mean over its drapes) with its "
        "real label; every predictor fitted on the synthetic world's labels only",
        "real_fabrics": len(real.fabrics),
        "synthetic_fabrics": len(synth.fabrics),
        "n_boot": N_BOOT,
        "labels": labels,
    }


def run(
    data: Path | None,
    members: int = MEMBERS,
    keep: Path | None = None,
    overrides: Sequence[str] = (),
) -> dict[str, Any]:
    """Render the world, train on it, score on ``data``; ``members`` networks used as one
    (the recipe's own is 3); ``keep``: a folder to keep the world and the run in (new or
    empty), else a temporary one; ``overrides``: ``key=value`` changes of the recipe, after
    the benchmark's own."""
    if data is None:
        return {"skipped": "needs the real GelFabric depth (--data)"}
    with tempfile.TemporaryDirectory() as tmp:
        work = keep if keep is not None else Path(tmp)
        world = work / "world"
        started = time.perf_counter()
        generate(
            SynthConfig(fabrics=FABRICS, drapes=DRAPES, modalities=(Modality.DEPTH,), seed=1),
            world,
            progress=False,
        )
        synth_s = time.perf_counter() - started
        # One cache of registered images for training, scoring and the label transfer (an
        # override's value is YAML: the folder is quoted).
        cache = f"data.cache_dir={json.dumps(str(work / 'cache'))}"
        own = ["train.split=none", "train.progress=false", f"model.members={members}", cache]
        config = load_config(RunConfig, CONFIG, [*own, *overrides])
        started = time.perf_counter()
        result = train(config, world, work / "run")
        train_s = time.perf_counter() - started
        scored = score_checkpoint(result.last_checkpoint, data, pairs=["depth_to_depth"])
        properties = zero_shot_properties(result.last_checkpoint, world, data)
    pair = scored["pairs"]["depth_to_depth"]
    model, raw = pair["model_top1"], pair["raw_pixels_top1"]
    return {
        "what": "pick 1 of 10 on real depth (100 fabrics) by an encoder trained on synthetic "
        "depth only",
        "world": {"fabrics": FABRICS, "drapes": DRAPES, "seconds": round(synth_s, 1)},
        "config": str(CONFIG.name),
        "members": members,
        "overrides": list(overrides),
        "train_seconds": round(train_s, 1),
        "model_top1": model["mean"],
        "model_top1_ci95": model["ci95"],
        "model_top3": pair["model_top3"]["mean"],
        "raw_pixels_top1": raw["mean"],
        "raw_pixels_top1_ci95": raw["ci95"],
        "raw_pixels_top3": pair["raw_pixels_top3"]["mean"],
        "depth_input": config.data.depth_input,
        "model_top1_background_swapped": pair.get("model_swapped_top1", {}).get("mean"),
        "raw_pixels_top1_background_swapped": pair.get("raw_pixels_swapped_top1", {}).get("mean"),
        "chance_top1": pair["chance_top1"],
        "target": "model top-1 > raw-pixel top-1",
        "met": model["mean"] > raw["mean"],
        "zero_shot_properties": properties,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.bench_synth_fidelity", description=__doc__.splitlines()[0]
    )
    ap.add_argument("--data", type=Path, required=True, help="the real GelFabric root")
    ap.add_argument(
        "--members", type=int, default=MEMBERS, help=f"networks used as one (default {MEMBERS})"
    )
    ap.add_argument("--keep", type=Path, default=None, help="keep the world and the run here")
    add_set_option(ap, "train.steps=1200")
    ap.add_argument("--out", type=Path, default=None, help="write the JSON here")
    args = ap.parse_args(argv)
    if not args.data.is_dir():
        ap.error(f"--data: {args.data} is not a folder")
    if args.members < 1:
        ap.error(f"--members: at least 1, got {args.members}")
    if args.keep is not None and args.keep.exists() and any(args.keep.iterdir()):
        ap.error(f"--keep: {args.keep} is not empty")
    try:
        load_config(RunConfig, CONFIG, args.overrides)
    except ConfigError as e:
        ap.error(f"--set: {e}")
    started = time.time()
    result = run(args.data, args.members, args.keep, args.overrides)
    return write_standalone("synth_fidelity", started, result, args.out)


if __name__ == "__main__":
    sys.exit(main())
