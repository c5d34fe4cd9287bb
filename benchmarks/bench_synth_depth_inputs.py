"""What the depth network is shown, synthetic beside real: registered drapes compared pixel-free.

`bench_synth_fidelity` asks whether an encoder trained on synthetic depth transfers to real
depth; when it does not, this benchmark says where the two worlds' *inputs* differ. Both are
registered by the recipe's own settings (`configs/real_depth.yaml`: the cloth's height, the
drape moved so that its top lies at one place, heights from the drape's top) at the
network's size, and summarised the same way:

- ``cloth_share``: share of the image that is cloth, and its spread between and within fabrics;
- ``width_by_row``: mean cloth width (pixels) in each eighth of the image's rows, top first;
- ``height_by_row``: median cloth height (mm) in each eighth of the rows;
- ``top_mm``: where the drape's top is read (`lookfeel.data.register.drape_top`), by each rule,
  with its spread within one fabric's drapes;
- ``cap``: the rows of the sensor's wall-and-cloth mix above the drape that
  `lookfeel.data.register.without_cap` drops (``depth_top_from: cloth_top``), at the image's
  own size, and how far the drape's top moves when it is read below them (`drape_post`);
- ``profile_gap``: the mean absolute difference of the two worlds' width profiles, as a share
  of the real one's mean width (0: the same silhouettes on average).

Real: every third GelFabric depth image. Synthetic: a fresh world of ``FABRICS`` fabrics and
``DRAPES`` drapes each (seed 1, generator as shipped). A montage of both worlds' inputs is
written to ``docs/images/registered_real_vs_synth.png``. Needs --data.

    python -m benchmarks --data ../shared/data/gelfabric --only synth_depth_inputs
"""

from __future__ import annotations

import dataclasses
import re
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from PIL import Image

from lookfeel.config import RunConfig, load_config
from lookfeel.data.images import decode_depth, registered_to_unit
from lookfeel.data.register import (
    drape_mask,
    drape_post,
    drape_top,
    placed_heights,
    register_configured,
    without_cap,
)
from lookfeel.modality import Modality
from lookfeel.synth import SynthConfig, generate

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "real_depth.yaml"
FIGURE = Path(__file__).resolve().parents[1] / "docs" / "images" / "registered_real_vs_synth.png"
FABRICS = 60
DRAPES = 5
EVERY = 3
BANDS = 8


def _inputs(files: list[Path], overrides: list[str]) -> dict[str, Any]:
    """Registered network inputs (mm) of ``files``, each one's drape top by both rules, the
    rows of its cap and how far its top moves without them."""
    data = load_config(RunConfig, CONFIG, overrides).data
    capless = dataclasses.replace(
        data, depth_top_from="cloth_top", depth_top_mm=data.depth_top_mm or 300.0
    )
    heights, fabrics, tops, caps, shifts = [], [], [], [], []
    for f in files:
        d = decode_depth(f)
        reg = register_configured(d, data)
        drape = np.where(drape_mask(reg.cloth), reg.height, np.float32(0.0))
        tops.append((drape_top(drape, "first_rows"), drape_top(drape, "highest_row")))
        kept = without_cap(drape)
        caps.append(int(((drape > 0).any(axis=1) & ~(kept > 0).any(axis=1)).sum()))
        a, b = reg.post_uv, drape_post(reg, kept, capless)
        shifts.append((b[0] - a[0], b[1] - a[1]) if a is not None and b is not None else (0, 0))
        h = placed_heights(reg, data)
        heights.append(registered_to_unit(h, data) * data.depth_range_mm)
        m = re.match(r"F(\d+)", f.name)
        fabrics.append(int(m.group(1)) if m else -1)
    return {
        "x": np.stack(heights),
        "fabric": np.array(fabrics),
        "tops": np.array(tops, float),
        "cap_rows": np.array(caps, float),
        "top_shift": np.array(shifts, float),
    }


def _spread(values: NDArray[np.float64], fabric: NDArray[np.int64]) -> dict[str, float]:
    ids = np.unique(fabric)
    means = np.array([values[fabric == i].mean() for i in ids])
    within = np.sqrt(np.mean([values[fabric == i].var() for i in ids]))
    return {
        "median": round(float(np.median(values)), 3),
        "between_fabrics_sd": round(float(means.std()), 3),
        "within_fabric_sd": round(float(within), 3),
    }


def summarise(world: dict[str, Any]) -> dict[str, Any]:
    """The summary of one world's registered inputs (module doc)."""
    x, fabric, tops = world["x"], world["fabric"], world["tops"]
    cloth = x > 0
    bands = np.array_split(np.arange(x.shape[1]), BANDS)
    width = [float(cloth[:, b].sum(axis=2).mean()) for b in bands]
    height = [float(np.median(x[:, b][cloth[:, b]])) if cloth[:, b].any() else 0.0 for b in bands]
    return {
        "images": len(x),
        "fabrics": len(np.unique(fabric)),
        "cloth_share": _spread(cloth.mean(axis=(1, 2)), fabric),
        "width_by_row": [round(w, 1) for w in width],
        "height_by_row": [round(h, 1) for h in height],
        "top_mm": {
            "first_rows": _spread(tops[:, 0], fabric),
            "highest_row": _spread(tops[:, 1], fabric),
        },
        "cap": _cap(world["cap_rows"], world["top_shift"]),
    }


def _cap(rows: NDArray[np.float64], shift: NDArray[np.float64]) -> dict[str, Any]:
    """The cap's rows per image and the drape top's move (px) when it is dropped."""
    return {
        "images_with_cap": round(float((rows > 0).mean()), 3),
        "rows_median_p10_p90": [float(np.percentile(rows, q)) for q in (50, 10, 90)],
        "top_down_px_median_p10_p90": [
            round(float(np.percentile(shift[:, 1], q)), 2) for q in (50, 10, 90)
        ],
        "top_sideways_px_abs_p90": round(float(np.percentile(np.abs(shift[:, 0]), 90)), 2),
    }


def _montage(real: NDArray[np.float32], synth: NDArray[np.float32], out: Path) -> None:
    """Eight real inputs over eight synthetic ones, 0-300 mm as black to white."""

    def row(x: NDArray[np.float32]) -> NDArray[np.float32]:
        idx = np.linspace(0, len(x) - 1, 8).round().astype(int)
        return np.concatenate([np.pad(x[i], 1, constant_values=300.0) for i in idx], axis=1)

    im = np.clip(np.concatenate([row(real), row(synth)], axis=0) / 300.0, 0.0, 1.0)
    img = Image.fromarray((im * 255).astype(np.uint8))
    img = img.resize((img.width * 3, img.height * 3), Image.Resampling.NEAREST)
    out.parent.mkdir(parents=True, exist_ok=True)
    img.save(out)


def run(data: Path | None, overrides: list[str] | None = None) -> dict[str, Any]:
    if data is None:
        return {"skipped": "needs the real GelFabric depth (--data)"}
    ov = list(overrides or [])
    real_files = sorted((data / "depth").glob("*.png"))[::EVERY]
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "world"
        generate(
            SynthConfig(fabrics=FABRICS, drapes=DRAPES, modalities=(Modality.DEPTH,), seed=1),
            root,
            progress=False,
        )
        synth = _inputs(sorted((root / "depth").glob("*.png")), ov)
    real = _inputs(real_files, ov)
    _montage(real["x"], synth["x"], FIGURE)
    r, s = summarise(real), summarise(synth)
    wr, ws = np.array(r["width_by_row"]), np.array(s["width_by_row"])
    return {
        "what": "registered depth inputs of the recipe, real GelFabric beside a synthetic world",
        "config": CONFIG.name,
        "overrides": ov,
        "real": r,
        "synthetic": s,
        "profile_gap": round(float(np.abs(wr - ws).mean() / wr.mean()), 3),
        "cloth_share_ratio": round(
            s["cloth_share"]["median"] / max(r["cloth_share"]["median"], 1e-9), 3
        ),
        "figure": str(FIGURE.relative_to(FIGURE.parents[2])),
    }
