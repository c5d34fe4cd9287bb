"""What a trained model's embeddings reveal of each latent parameter of a synthetic world.

`lookfeel.synth.information` asks how much of each latent a linear probe on pixel statistics
reads: what the images hold. This asks a trained model what its embeddings kept of it, for
every latent the world knows, including the ones the labels never carry (a fabric's sheen,
gloss, fuzz and translucency, what a camera sees of its material; its compliance, relief and
yarn period, what a fingertip sensor feels). A latent the pixels show and no embedding reads
is one the training never asked for: the gap between the two tables says where a recipe, not
the world, is the limit.

    >>> result = latent_table(Path("world"), [Path("cv/seed0-fold0/checkpoints/last.pt")])
    >>> print(format_latent_table(result))

or from a shell, one checkpoint or several (a `lookfeel cv`'s folds, averaged)::

    python -m lookfeel.synth.latent_probe WORLD CV/seed0-fold*/checkpoints/last.pt --json out.json

Per checkpoint:

1. The world is embedded as `lookfeel embed` does (`lookfeel.evaluate.embed_checkpoint`): the
   run's held-out fabrics (``--split val``: a cv fold's held-out fabrics) and, as reference, its
   training fabrics. Nothing is fitted on the held-out ones.
2. Each fabric's mean embedding per modality (every press of touch, flat and fold together).
3. Per latent and modality, a ridge fitted on the training fabrics' means (one penalty chosen
   by leave-one-out over them, `lookfeel.metrics.properties.fit_ridge_multi`), scored on the
   held-out fabrics: R^2 for a number (the log of a positive, skewed one: `LOG_LATENTS`); for a
   class, a ridge on one-hot targets whose largest output is the prediction, as accuracy beside
   the training fabrics' majority class.

Several checkpoints give the mean and the standard deviation over them. With ``--pixels`` the
same probe also reads the information table's pixel statistics (`lookfeel.synth.information`'s
features, at most `PIXEL_IMAGES` images a fabric of each stream) on the same fabrics: what the
images show a linear probe, beside what the model kept. Deterministic for given checkpoints.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lookfeel.atomic import atomic_write_text
from lookfeel.errors import LookfeelError
from lookfeel.metrics.properties import fit_ridge_multi
from lookfeel.synth.information import WorldError, _subsample, extract_features, read_world

__all__ = [
    "LOG_LATENTS",
    "format_latent_table",
    "latent_table",
    "main",
    "probe_latents",
]

LOG_LATENTS = frozenset(
    {
        "thickness_mm",
        "density",
        "bending_length_mm",
        "bending_rigidity_uNm",
        "gloss",
        "yarn_period_mm",
        "relief_mm",
    }
)
"""Numeric latents probed as their log (positive and spread over orders of magnitude)."""

PIXEL_IMAGES = 6
"""``--pixels``: images a fabric of each stream (depth, colour, touch flat, touch fold) whose
statistics are probed (seeded draw)."""

_SKIP = frozenset({"fabric_id"})

Embedded = Mapping[str, tuple[NDArray[Any], NDArray[Any]]]
"""modality -> ((N, D) embeddings, (N,) fabric ids)."""


def _latent_columns(
    truth: Mapping[int, Mapping[str, Any]],
) -> tuple[dict[str, dict[int, float]], dict[str, dict[int, str]]]:
    """Every latent that all fabrics of ``truth`` give: numbers (logged where `LOG_LATENTS`
    says and all are positive) and classes (strings)."""
    rows = list(truth.values())
    keys = [k for k in rows[0] if k not in _SKIP] if rows else []
    numbers: dict[str, dict[int, float]] = {}
    classes: dict[str, dict[int, str]] = {}
    for k in keys:
        vals = [r.get(k) for r in rows]
        if all(isinstance(v, str) for v in vals):
            classes[k] = {int(f): str(r[k]) for f, r in truth.items()}
        elif all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in vals):
            v = np.asarray(vals, dtype=np.float64)
            if not np.isfinite(v).all():
                continue
            if k in LOG_LATENTS and (v > 0).all():
                numbers[f"log_{k}"] = {int(f): math.log(float(r[k])) for f, r in truth.items()}
            else:
                numbers[k] = {int(f): float(r[k]) for f, r in truth.items()}
    return numbers, classes


def _fabric_means(emb: NDArray[Any], fab: NDArray[Any]) -> tuple[list[int], NDArray[np.float64]]:
    x = np.asarray(emb, dtype=np.float64)
    f = np.asarray(fab).reshape(-1)
    ids = sorted(int(i) for i in np.unique(f))
    return ids, np.stack([x[f == i].mean(axis=0) for i in ids])


def probe_latents(
    truth: Mapping[int, Mapping[str, Any]], train: Embedded, test: Embedded
) -> dict[str, Any]:
    """Probe every latent of ``truth`` from each modality's embeddings (module doc, step 3).

    Args:
        truth: fabric id -> that fabric's parameters (``synth.json``'s entries).
        train: the training fabrics' items, per modality (the probes are fitted on them).
        test: the held-out fabrics' items, per modality (the probes are scored on them).

    Returns:
        ``{"scores": {modality: {latent: R^2 or accuracy or None}}, "majority": {class:
        accuracy of the training majority on the held-out fabrics}, "fabrics": {modality:
        [training count, held-out count]}}``; None where the held-out truth does not vary (R^2
        is undefined) or a modality lacks fabrics with known truth.
    """
    numbers, classes = _latent_columns(truth)
    scores: dict[str, dict[str, float | None]] = {}
    majority: dict[str, float] = {}
    counts: dict[str, list[int]] = {}
    for m in test:
        if m not in train:
            continue
        tr_ids, xtr = _fabric_means(*train[m])
        te_ids, xte = _fabric_means(*test[m])
        keep_tr = [i for i, f in enumerate(tr_ids) if f in truth]
        keep_te = [i for i, f in enumerate(te_ids) if f in truth]
        tr_ids = [tr_ids[i] for i in keep_tr]
        te_ids = [te_ids[i] for i in keep_te]
        xtr, xte = xtr[keep_tr], xte[keep_te]
        counts[m] = [len(tr_ids), len(te_ids)]
        out: dict[str, float | None] = {}
        if len(tr_ids) < 3 or not te_ids:
            scores[m] = dict.fromkeys([*numbers, *classes])
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # ill-conditioned folds: the ridge still answers
            for name, col in numbers.items():
                y = np.array([col[f] for f in tr_ids])
                yt = np.array([col[f] for f in te_ids])
                coef, icpt = fit_ridge_multi(xtr, y[:, None])
                pred = (xte @ coef + icpt).reshape(-1)
                sst = float(((yt - yt.mean()) ** 2).sum())
                out[name] = None if sst <= 1e-12 else 1.0 - float(((pred - yt) ** 2).sum()) / sst
            for name, kinds in classes.items():
                labels = sorted(set(kinds.values()))
                y = np.array([labels.index(kinds[f]) for f in tr_ids])
                yt = np.array([labels.index(kinds[f]) for f in te_ids])
                coef, icpt = fit_ridge_multi(xtr, np.eye(len(labels))[y])
                pred = (xte @ coef + icpt).argmax(axis=1)
                out[name] = float((pred == yt).mean())
                top = np.bincount(y, minlength=len(labels)).argmax()
                majority[name] = float((yt == top).mean())
        scores[m] = out
    return {"scores": scores, "majority": majority, "fabrics": counts}


def latent_table(
    world: Path | str,
    checkpoints: Sequence[Path | str],
    *,
    split: str = "val",
    device: str = "cpu",
    pixels: bool = False,
    workers: int = 0,
) -> dict[str, Any]:
    """Probe a world's latents from the embeddings of each checkpoint (module doc).

    Args:
        world: a complete `lookfeel synth` folder.
        checkpoints: one or more trained models (e.g. every fold of a `lookfeel cv`).
        split: the items scored (`lookfeel embed`'s ``--split``); ``val``, the run's held-out
            fabrics, by default. The probes are fitted on the split's reference fabrics.
        device: where the models run.
        pixels: also probe the images' statistics on the same fabrics (module doc).
        workers: processes extracting those statistics; 0: one per core.

    Returns:
        ``{"world", "checkpoints", "split", "runs": [probe_latents per checkpoint], "mean":
        {modality: {latent: value}}, "std": ..., "majority": {class: mean}}``, and with
        ``pixels`` the same under ``"pixels"`` for the image statistics.

    Raises:
        WorldError: ``world`` is not a complete world.
        LookfeelError: a checkpoint cannot be loaded, or its split has no reference fabrics.
    """
    from lookfeel.evaluate import embed_checkpoint  # the model stack, only when embedding

    fabrics, images = read_world(world)
    truth = {int(f["fabric_id"]): f for f in fabrics}
    if not checkpoints:
        raise LookfeelError("no checkpoint given: name one or more trained models")
    feats = None
    if pixels:
        kept = _subsample(images, PIXEL_IMAGES, seed=0)
        per_mod = extract_features(kept, workers=workers)
        feats = {
            m: (per_mod[m], np.array([im.fabric for im in kept if im.modality == m]))
            for m in per_mod
        }
    runs, pixel_runs = [], []
    for ck in checkpoints:
        emb = embed_checkpoint(ck, world, split, reference=True, device=device)
        if not emb.reference:
            raise LookfeelError(
                f"{ck}: --split {split} has no training fabrics to fit the probes on; use val"
            )
        test = {m.value: (e.embeddings, e.fabric_ids) for m, e in emb.embedded.items()}
        train = {m.value: (e.embeddings, e.fabric_ids) for m, e in emb.reference.items()}
        runs.append({"checkpoint": str(ck)} | probe_latents(truth, train, test))
        if feats is not None:
            held = {m: np.unique(f) for m, (_, f) in test.items()}
            seen = {m: np.unique(f) for m, (_, f) in train.items()}
            pix_train, pix_test = {}, {}
            for m, (raw, f) in feats.items():
                if m in held:
                    fit, score = np.isin(f, seen[m]), np.isin(f, held[m])
                    x = _standardise(raw, fit)
                    pix_train[m], pix_test[m] = (x[fit], f[fit]), (x[score], f[score])
            pixel_runs.append({"checkpoint": str(ck)} | probe_latents(truth, pix_train, pix_test))
    out: dict[str, Any] = {
        "world": str(world),
        "checkpoints": [str(c) for c in checkpoints],
        "split": split,
    }
    out |= {"runs": runs} | _summary(runs)
    if pixel_runs:
        out["pixels"] = {"runs": pixel_runs} | _summary(pixel_runs)
    return out


def _standardise(x: NDArray[Any], fit: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Each feature in units of its spread over the ``fit`` rows (the training fabrics')."""
    x = np.asarray(x, dtype=np.float64)
    mu, sd = x[fit].mean(axis=0), x[fit].std(axis=0)
    return (x - mu) / np.where(sd > 1e-9, sd, 1.0)


def _summary(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """Mean and standard deviation over runs of every score, and the majority classes."""
    mean: dict[str, dict[str, float | None]] = {}
    std: dict[str, dict[str, float | None]] = {}
    for m in runs[0]["scores"]:
        mean[m], std[m] = {}, {}
        for name in runs[0]["scores"][m]:
            vals = [r["scores"][m].get(name) for r in runs if m in r["scores"]]
            got = [v for v in vals if v is not None]
            mean[m][name] = float(np.mean(got)) if got else None
            std[m][name] = float(np.std(got)) if got else None
    majority = {
        k: float(np.mean([r["majority"][k] for r in runs if k in r["majority"]]))
        for k in runs[0]["majority"]
    }
    return {"mean": mean, "std": std, "majority": majority}


def format_latent_table(result: Mapping[str, Any]) -> str:
    """The result as a markdown table: a row per latent, a column per modality (and, with
    pixels, one per modality's image statistics), mean ± standard deviation over the
    checkpoints (R^2; accuracy for a class, its majority beside)."""
    columns = [(m, result, m) for m in result["mean"]]
    if "pixels" in result:
        columns += [(f"{m} pixels", result["pixels"], m) for m in result["pixels"]["mean"]]
    names = list(next(iter(result["mean"].values()))) if result["mean"] else []
    n = len(result["runs"])
    source = "the embeddings" + (
        " (and, as 'pixels', the images' statistics)" if "pixels" in result else ""
    )
    lines = [
        f"Latents read from {source} of {n} run(s) (ridge on the training fabrics' means, "
        f"scored on the held-out fabrics; R², accuracy for classes; mean ± std over runs)",
        "",
        "| latent | " + " | ".join(c for c, _, _ in columns) + " |",
        "|---|" + "---|" * len(columns),
    ]
    for name in names:
        cells = []
        for _, res, m in columns:
            v, s = res["mean"][m].get(name), res["std"][m].get(name)
            cells.append("-" if v is None else f"{v:.2f}" + (f" ± {s:.2f}" if n > 1 else ""))
        label = name
        if name in result["majority"]:
            label = f"{name} (accuracy; majority {result['majority'][name]:.2f})"
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """``python -m lookfeel.synth.latent_probe``: print the table (and write ``--json``)."""
    parser = argparse.ArgumentParser(
        prog="python -m lookfeel.synth.latent_probe",
        description="What a trained model's embeddings reveal of each latent of a synthetic "
        "world: a ridge per latent and modality, fitted on the run's training fabrics and "
        "scored on its held-out ones.",
    )
    parser.add_argument("world", type=Path, help="a complete `lookfeel synth` output folder")
    parser.add_argument(
        "checkpoints", type=Path, nargs="+", help="trained models (e.g. every fold of a cv)"
    )
    parser.add_argument("--json", type=Path, default=None, help="also write the result here")
    parser.add_argument("--device", default="cpu", help="where the models run (default cpu)")
    parser.add_argument(
        "--pixels",
        action="store_true",
        help="also probe the images' statistics (lookfeel.synth.information's) on the same fabrics",
    )
    parser.add_argument("--workers", type=int, default=0, help="for --pixels; 0 = one per core")
    args = parser.parse_args(argv)
    try:
        result = latent_table(
            args.world,
            args.checkpoints,
            device=args.device,
            pixels=args.pixels,
            workers=args.workers,
        )
        if args.json is not None:
            atomic_write_text(args.json, json.dumps(result, indent=1) + "\n")
    except (WorldError, LookfeelError, OSError) as e:
        print(f"latent_probe: {e}", file=sys.stderr)
        return 2
    print(format_latent_table(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
