"""What the background control changes on registered depth, one part at a time.

`lookfeel cv`'s background control (`lookfeel.data.background_swap.BackgroundControl`) gives
each held-out depth image another fabric's background, keeps the cloth, and registers the
composite again. On registered depth the network never sees the room, so the swap reaches it
only through that second registration: the cloth's heights (measured from the partner's
fitted floor), its mask, and the estimate of the drape's top. For each run of a ``lookfeel
cv`` folder of a registered-depth recipe this scores the run's held-out queries (pick 1 of 10
exact, top-1; model and raw pixels of the same inputs) with one part of the swap applied at a
time, the rest as the image was:

- ``as_is``; ``swapped``: the control as ``cv`` computes it (partner drawn with seed 0);
- ``swap_partner_room``: the composite registered in the room fitted on the partner's own
  image (`register_in_room`, no fit on the composite): the swap with the composite's room fit
  made exact, so what ``swapped`` loses beyond it is the fit's error;
- ``swap_mask``: the image's own heights on the composite's cloth mask;
- ``mask_low``, ``mask_high``, ``mask_gained``: one part of that mask's change at a time, the
  drape kept where it is (its own top): only the cloth the composite loses lower than
  `LOW_MM` above the image's own floor dropped (the drape's foot on the floor), only the cloth
  it loses higher up dropped, or only the pixels it gains added (at the composite's heights
  less the fitted plane, as ``swap_mask`` adds them);
- ``swap_top``: the image's own heights and mask, moved by the composite's drape top;
- ``swap_level``: own mask, heights changed by the plane (in image coordinates) fitted to
  the composite's change of height; ``swap_shift``: that plane's mean only; ``swap_tilt``:
  that plane with its mean removed;
- ``partner_room``: own cloth, its heights measured from the partner's floor *as fitted on the
  partner's own image* (no refit on a composite);
- ``room``: ``cv``'s room control: the image registered in the partner's fitted room (its
  cloth mask, heights and drape top all taken relative to the partner's planes,
  `register_in_room`); ``room_own_top``: the same, moved by the image's own drape top.

Every variant then goes through the run's own settings (``depth_min_height_mm``,
``depth_top_mm``, ``depth_post_at``, the map to [0, 1] and the resize).

Each run's row also says where the composite's cloth differs from the image's own
(``mask``, `mask_changes`, at the registration's resolution, before the resize): the cloth
pixels the composite loses and those it gains, the lost ones counted by their height above the
image's own fitted floor and by their distance from the own cloth's edge, and the fraction of
its cloth each image loses (quantiles over the run's images).

    python -m benchmarks.bench_depth_swap --data ../shared/data/gelfabric --cv CV \
        [--runs seed0-fold0,...] [--out JSON]
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.bench_depth_position import DEFAULT_DATA, score_variants, write_result
from lookfeel.data.catalog import Catalog


def _plane(h0: np.ndarray, h1: np.ndarray) -> np.ndarray:
    """The plane a u + b v + c fitted to h1 - h0 where both have cloth (0 without any)."""
    both = (h0 > 0) & (h1 > 0)
    if both.sum() < 3:
        return np.zeros_like(h0)
    v, u = np.nonzero(both)
    a = np.c_[u, v, np.ones_like(u)].astype(np.float64)
    c, *_ = np.linalg.lstsq(a, (h1 - h0)[both], rcond=None)
    vv, uu = np.mgrid[: h0.shape[0], : h0.shape[1]]
    return (c[0] * uu + c[1] * vv + c[2]).astype(np.float32)


LOW_MM = 30.0
"""``mask_low`` / ``mask_high``: lost cloth lower / higher than this above the own floor."""
HEIGHT_BANDS_MM = (0.0, 15.0, 30.0, 60.0, float("inf"))
"""`mask_changes`: the bands of height above the own floor the lost cloth is counted in."""
EDGE_BANDS_PX = (0.0, 1.5, 3.5, 8.5, float("inf"))
"""`mask_changes`: the bands of distance from the own cloth's edge (pixels; 1 is the rim)."""


def _bands(values: np.ndarray, edges: tuple[float, ...], unit: str) -> dict[str, int]:
    return {
        f"{lo:g}-{hi:g} {unit}": int(((values > lo) & (values <= hi)).sum())
        for lo, hi in itertools.pairwise(edges)
    }


def mask_changes(
    own: list[np.ndarray], comp: list[np.ndarray], above_floor: list[np.ndarray]
) -> dict[str, Any]:
    """Where each composite's cloth (``comp[i] > 0``) differs from its image's own (``own[i] >
    0``), summed over the images; ``above_floor[i]``: the own cloth's heights above its own
    fitted floor (mm), which band the lost pixels.

    Returns ``own_cloth``, ``lost`` and ``gained`` pixel counts, ``lost_by_height`` (bands of
    `HEIGHT_BANDS_MM`), ``lost_by_edge`` (distance from the own cloth's edge, `EDGE_BANDS_PX`;
    a pixel next to the background is 1) and ``lost_fraction`` (the 50th, 75th and 90th
    percentile over the images of the fraction of its own cloth each loses).
    """
    from scipy import ndimage

    lost_h, lost_d, fractions = [], [], []
    own_px = lost_px = gained_px = 0
    for h0, h1, floor in zip(own, comp, above_floor, strict=True):
        m0, m1 = h0 > 0, h1 > 0
        lost = m0 & ~m1
        own_px += int(m0.sum())
        lost_px += int(lost.sum())
        gained_px += int((m1 & ~m0).sum())
        fractions.append(lost.sum() / max(1, int(m0.sum())))
        lost_h.append(floor[lost])
        lost_d.append(ndimage.distance_transform_edt(m0)[lost])
    return {
        "own_cloth": own_px,
        "lost": lost_px,
        "gained": gained_px,
        "lost_by_height": _bands(np.concatenate(lost_h or [np.zeros(0)]), HEIGHT_BANDS_MM, "mm"),
        "lost_by_edge": _bands(np.concatenate(lost_d or [np.zeros(0)]), EDGE_BANDS_PX, "px"),
        "lost_fraction": {
            f"p{q}": round(float(np.percentile(fractions, q)), 4) if fractions else 0.0
            for q in (50, 75, 90)
        },
    }


def one_run(run_dir: Path, catalog: Catalog) -> dict[str, Any]:
    """Every variant of the module doc for one trained run."""
    from lookfeel.checkpoint import load_model
    from lookfeel.crossval import CONTROL_SEED
    from lookfeel.data.background_swap import swap_backgrounds
    from lookfeel.data.holes import fill_holes
    from lookfeel.data.images import decode_depth, registered_to_unit
    from lookfeel.data.register import (
        Intrinsics,
        camera_points,
        drape_mask,
        drape_post,
        heights_from_top,
        kept_heights,
        move_drape,
        register_depth,
        register_in_room,
        registered_heights,
        registered_intrinsics,
    )
    from lookfeel.modality import Modality

    lm = load_model(run_dir / "checkpoints" / "last.pt")
    dc = lm.config.data
    if dc.depth_input != "registered":
        raise SystemExit(f"{run_dir}: not a registered-depth run (data.depth_input)")
    items = catalog.subset(lm.split["val"]).items(Modality.DEPTH)
    fabric = np.array([it.fabric_id for it in items])
    with ThreadPoolExecutor(2) as pool:
        depths = list(pool.map(lambda it: decode_depth(it.path), items))
    h_px, w_px = depths[0].shape
    k = registered_intrinsics((h_px, w_px), dc)
    # Each image registered once, as `registered_heights` and the background control do.
    with ThreadPoolExecutor(2) as pool:
        regs = list(pool.map(lambda d: register_depth(d, k, margin_mm=dc.depth_margin_mm), depths))
    cloth = np.stack([drape_mask(r.cloth) if dc.depth_cloth == "drape" else r.cloth for r in regs])
    filled = np.stack([fill_holes(d).astype(np.float32) for d in depths])
    rooms = np.stack([r.room for r in regs])
    sw = swap_backgrounds(filled, cloth, fabric, seed=CONTROL_SEED, rooms=rooms)
    own = [(kept := kept_heights(r, dc), drape_post(r, kept, dc)) for r in regs]
    # Heights above the image's own fitted floor, kept as the run keeps them but not yet
    # measured from the drape's top: the cloth whose floor the partner's replaces.
    plain = dataclasses.replace(dc, depth_top_mm=None)
    own_floor = [kept_heights(r, plain) for r in regs]
    with ThreadPoolExecutor(2) as pool:
        comp = list(pool.map(lambda d: registered_heights(d, dc), sw.images))

    def finish(h: np.ndarray, post: tuple[float, float] | None) -> np.ndarray:
        return registered_to_unit(move_drape(h.astype(np.float32), post, dc.depth_post_at), dc)

    intr = k if k is not None else Intrinsics.gelfabric(w_px, h_px)

    def floor_heights(i: int, j: int) -> np.ndarray:
        """Image i's cloth as the run keeps it, its heights above image j's floor as fitted
        on image j (image i's own floor when image j has none)."""
        floor = regs[j].plane("floor") or regs[i].plane("floor")
        if floor is None:  # neither image has a floor: the run's own heights
            return own_floor[i]
        height = floor.distance - camera_points(filled[i].astype(np.float64), intr) @ np.asarray(
            floor.normal
        )
        return np.where(own_floor[i] > 0, np.maximum(height, 0.1), 0.0).astype(np.float32)

    def top(h: np.ndarray) -> np.ndarray:
        return (
            heights_from_top(h, dc.depth_top_mm, dc.depth_top_from)
            if dc.depth_top_mm is not None
            else h
        )

    variants: dict[str, list[np.ndarray]] = {name: [] for name in _VARIANTS}
    for i, ((h0, p0), (h1, p1)) in enumerate(zip(own, comp, strict=True)):
        cl = h0 > 0
        plane = _plane(h0, h1)
        mean = float(plane[cl].mean()) if cl.any() else 0.0

        def level(add: np.ndarray | float, h0: np.ndarray = h0, cl: np.ndarray = cl) -> np.ndarray:
            return np.where(cl, np.maximum(h0 + add, 0.1), 0.0)

        back = np.where(h1 > 0, np.where(cl, h0, np.maximum(h1 - plane, 0.1)), 0.0)
        variants["as_is"].append(finish(h0, p0))
        variants["swapped"].append(finish(h1, p1))
        variants["swap_mask"].append(finish(back, p1))
        exact = register_in_room(
            sw.images[i], regs[int(sw.partner[i])].planes, k, margin_mm=dc.depth_margin_mm
        )
        exact_kept = kept_heights(exact, dc)
        variants["swap_partner_room"].append(finish(exact_kept, drape_post(exact, exact_kept, dc)))
        lost, low = cl & (h1 <= 0), own_floor[i] < LOW_MM
        variants["mask_low"].append(finish(np.where(lost & low, 0.0, h0), p0))
        variants["mask_high"].append(finish(np.where(lost & ~low, 0.0, h0), p0))
        variants["mask_gained"].append(finish(np.where(cl, h0, back), p0))
        variants["swap_top"].append(finish(h0, p1))
        variants["swap_level"].append(finish(level(plane), p0))
        variants["swap_shift"].append(finish(level(mean), p0))
        variants["swap_tilt"].append(finish(level(plane - mean), p0))
        variants["partner_room"].append(finish(top(floor_heights(i, int(sw.partner[i]))), p0))
        in_room = register_in_room(
            filled[i], regs[int(sw.partner[i])].planes, k, margin_mm=dc.depth_margin_mm
        )
        kept = kept_heights(in_room, dc)
        variants["room"].append(finish(kept, drape_post(in_room, kept, dc)))
        variants["room_own_top"].append(finish(kept, p0))
    row: dict[str, Any] = {"run": run_dir.name, "queries": len(items)}
    row["mask"] = mask_changes([h for h, _ in own], [h for h, _ in comp], own_floor)
    return row | score_variants(lm, items, fabric, variants)


_VARIANTS = (
    "as_is",
    "swapped",
    "swap_partner_room",
    "swap_mask",
    "mask_low",
    "mask_high",
    "mask_gained",
    "swap_top",
    "swap_level",
    "swap_shift",
    "swap_tilt",
    "partner_room",
    "room",
    "room_own_top",
)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--cv", type=Path, required=True, help="a lookfeel cv folder (registered)")
    ap.add_argument("--runs", default=None, help="comma-separated run names (default: all)")
    ap.add_argument("--out", type=Path, default=None, help="write the JSON here")
    args = ap.parse_args(argv)
    if not args.data.exists():
        print(f"{args.data}: no such dataset", file=sys.stderr)
        return 1
    from lookfeel.data.layout import scan
    from lookfeel.modality import Modality

    catalog = scan(args.data, require=[Modality.DEPTH], strict=True)
    names = (
        args.runs.split(",") if args.runs else [p.name for p in sorted(args.cv.glob("seed*-fold*"))]
    )
    started = time.perf_counter()
    rows = []
    for name in names:
        rows.append(one_run(args.cv / name, catalog))
        print(json.dumps(rows[-1]), flush=True)
    mean = {
        v: {who: float(np.mean([r[v][who] for r in rows])) for who in ("model", "raw_pixels")}
        for v in _VARIANTS
    }
    masks = [r["mask"] for r in rows]
    mask_total = {k: sum(m[k] for m in masks) for k in ("own_cloth", "lost", "gained")} | {
        k: {band: sum(m[k][band] for m in masks) for band in masks[0][k]}
        for k in ("lost_by_height", "lost_by_edge")
    }
    result = {
        "runs": rows,
        "mean": mean,
        "mask": mask_total,
        "seconds": round(time.perf_counter() - started, 1),
    }
    print(json.dumps(mean, indent=1))
    if args.out is not None:
        write_result(result, args.out, "bench_depth_swap", argv)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
