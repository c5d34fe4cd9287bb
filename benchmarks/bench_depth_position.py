"""Where the drape lies in the image: a capture-session cue that the background swap keeps.

Registered depth (``data.depth_input: registered``) masks the room and measures the cloth's
height above the fitted floor, but keeps the camera's pixel grid: the drape stays where the
camera saw it. Every GelFabric fabric was captured in one session and the camera moved a little
between sessions, so where the drape (hanging from a fixed post) lies in the image is a session
cue. The background control (`lookfeel.data.background_swap`) keeps each cloth pixel where it
is, so it cannot see this cue.

Two measurements:

1. **Position alone** (`run`, no model): register every depth image (`register_depth`) and
   identify its fabric, pick 1 of 10 exact among all fabrics, from two numbers only (by their
   distance in pixels): the image position of the drape's top, where the post holds it
   (``post_uv``); beside the same from the drape's centroid and chance. 95% interval
   resampling fabrics. The library's `position_leakage` does this (``lookfeel data leakage
   --position``).
2. **Moved drapes** (``--cv CV``, a ``lookfeel cv`` folder of a registered-depth recipe such as
   ``configs/real_depth.yaml``): each run's held-out images are scored as they are and with the
   registered drape translated (bilinear, at the registration's resolution, before the resize
   to the network's input) by the offset between its post and another image's post: an image
   of another fabric (drawn as the background control draws its partner, seed 0), or another
   image of its own fabric. The second is the post estimate's own jitter within one session,
   a move of the same kind that carries no session change. A run that moves every drape to one
   place (``data.depth_post_at``) moves these too. Model and raw pixels of the same inputs,
   top-1 pick 1 of 10 exact.

    python -m benchmarks.bench_depth_position [--data ../shared/data/gelfabric] [--cv CV]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage

from lookfeel.config import DataConfig

DEFAULT_DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "gelfabric"


def _register(
    path: Path, config: DataConfig | None = None
) -> tuple[np.ndarray, tuple[float, float]]:
    """(registered heights in mm as ``config`` keeps them, where the camera saw them, at the
    file's resolution; the drape's top (u, v) in pixels, NaN without one). Default: the
    registered recipe's settings."""
    from lookfeel.data.images import decode_depth
    from lookfeel.data.register import registered_heights

    cfg = config if config is not None else DataConfig(depth_input="registered")
    height, post = registered_heights(decode_depth(path), cfg)
    return height, post if post is not None else (np.nan, np.nan)


def _pick(features: np.ndarray, fabric: np.ndarray) -> tuple[float, list[float]]:
    """Top-1 pick 1 of 10 exact (Euclidean, as `lookfeel cv` scores embeddings and raw
    pixels) and its 95% interval."""
    from lookfeel.metrics import EXACT_PICK, bootstrap_ci, score_pairs
    from lookfeel.modality import Modality, Pair

    x = features
    pair = Pair.parse("depth_to_depth")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        s = score_pairs({Modality.DEPTH: x}, {Modality.DEPTH: fabric}, EXACT_PICK, [pair])
    top1 = s[pair].pick.per_query[:, 0]
    lo, hi = bootstrap_ci(top1, fabric)
    return float(top1.mean()), [float(lo), float(hi)]


def run(data: Path | None) -> dict[str, object]:
    """Measurement 1: the fabric from the drape's position alone
    (`lookfeel.data.leakage.position_leakage`, as ``lookfeel data leakage --position``)."""
    from lookfeel.data.layout import scan
    from lookfeel.data.leakage import position_leakage
    from lookfeel.modality import Modality

    root = Path(data) if data is not None else DEFAULT_DATA
    if not root.is_dir():
        return {"skipped": f"real GelFabric depth not found at {root}", "met": None}
    catalog = scan(root, require=[Modality.DEPTH], strict=True)
    started = time.perf_counter()
    got = position_leakage(catalog)
    if isinstance(got, str):
        return {"skipped": got, "met": None}
    rows = {
        name: {
            "top1": s.top1,
            "ci95": list(s.ci95),
            "within_fabric_std_px": s.within_fabric_px,
            "overall_std_px": s.overall_px,
        }
        for name, s in (("post_uv", got.post_uv), ("drape_centroid", got.drape_centroid))
    }
    return {
        "data": str(root),
        "images": got.n_items,
        "fabrics": got.n_fabrics,
        "image_px": list(got.image_px),
        "chance_top1": got.chance,
        "position_alone": rows,
        "seconds": round(time.perf_counter() - started, 1),
    }


def moved_drapes(cv: Path, data: Path) -> list[dict[str, object]]:
    """Measurement 2: every seed-and-fold run in ``cv``, its held-out drapes moved."""
    from lookfeel.checkpoint import load_model
    from lookfeel.data.background_swap import pair_other_fabric
    from lookfeel.data.images import registered_to_unit
    from lookfeel.data.layout import scan
    from lookfeel.data.register import move_drape
    from lookfeel.modality import Modality

    catalog = scan(data, require=[Modality.DEPTH], strict=True)
    out = []
    registered: dict[Path, tuple[np.ndarray, tuple[float, float]]] = {}
    for run_dir in sorted(cv.glob("seed*-fold*")):
        lm = load_model(run_dir / "checkpoints" / "last.pt")
        dc = lm.config.data
        if dc.depth_input != "registered":
            raise SystemExit(f"{run_dir}: not a registered-depth run (data.depth_input)")
        items = catalog.subset(lm.split["val"]).items(Modality.DEPTH)
        todo = [it.path for it in items if it.path not in registered]
        configs = [dc] * len(todo)
        with ThreadPoolExecutor(2) as pool:
            registered |= dict(zip(todo, pool.map(_register, todo, configs), strict=True))
        regs = [registered[it.path] for it in items]
        fabric = np.array([it.fabric_id for it in items])

        def to_input(h: np.ndarray, post: tuple[float, float], dc: DataConfig = dc) -> np.ndarray:
            """The network's input of registered heights ``h`` whose drape top is ``post``,
            as `registered_input` and `preprocess_depth` make it."""
            known = None if np.isnan(post).any() else post
            return registered_to_unit(move_drape(h, known, dc.depth_post_at), dc)

        def moved(partner: np.ndarray, regs: list[Any] = regs) -> list[np.ndarray]:
            arrays = []
            for i, j in enumerate(partner):
                (h, own), other = regs[i], regs[int(j)][1]
                d = np.nan_to_num(np.subtract(other, own))
                shifted = ndimage.shift(h, (d[1], d[0]), order=1, cval=0.0)
                arrays.append(to_input(shifted, other))
            return arrays

        rng = np.random.default_rng(0)
        same = np.array(
            [
                rng.choice(np.flatnonzero((fabric == f) & (np.arange(len(fabric)) != i)))
                for i, f in enumerate(fabric)
            ]
        )
        variants = {
            "as_is": [to_input(h, post) for h, post in regs],
            "moved_to_other_fabric_post": moved(pair_other_fabric(fabric, 0)),
            "moved_to_own_fabric_post": moved(same),
        }
        row = {"run": run_dir.name, "queries": len(items)}
        row |= score_variants(lm, items, fabric, variants)
        out.append(row)
        print(json.dumps(row), flush=True)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--cv", type=Path, default=None, help="a lookfeel cv folder (registered)")
    ap.add_argument("--out", type=Path, default=None, help="write the JSON here")
    args = ap.parse_args(argv)
    if not args.data.exists():
        print(f"{args.data}: no such dataset", file=sys.stderr)
        return 1
    result = run(args.data)
    print(json.dumps(result["position_alone"], indent=1), flush=True)
    if args.cv is not None:
        result["moved_drapes"] = moved_drapes(args.cv, args.data)
    if args.out is not None:
        write_result(result, args.out, "bench_depth_position", argv)
    return 0


def score_variants(
    lm: Any, items: list[Any], fabric: np.ndarray, variants: dict[str, list[np.ndarray]]
) -> dict[str, object]:
    """Per variant (one network input per item), the run's model and raw pixels of the same
    inputs: top-1 pick 1 of 10 exact."""
    from lookfeel.data.images import ArrayLoader
    from lookfeel.embedding import embed_items
    from lookfeel.modality import Modality

    scores: dict[str, object] = {}
    for name, arrays in variants.items():
        loader = ArrayLoader(
            lm.config.data,
            dict(zip((it.path for it in items), arrays, strict=True)),
            Modality.DEPTH,
        )
        emb = embed_items(lm.model, items, loader)
        pixels = np.stack([a.reshape(-1) for a in arrays])
        scores[name] = {"model": _pick(emb, fabric)[0], "raw_pixels": _pick(pixels, fabric)[0]}
    return scores


def write_result(result: dict[str, object], out: Path, module: str, argv: list[str] | None) -> None:
    """Write ``result`` to ``out`` (atomically) with the time, the machine and the command line."""
    from benchmarks.__main__ import machine, now
    from lookfeel.atomic import atomic_write_text

    result["when"] = now()
    result["machine"] = machine()
    result["command"] = " ".join([f"python -m benchmarks.{module}", *(argv or sys.argv[1:])])
    atomic_write_text(out, json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    raise SystemExit(main())
