"""How much of a fabric's labels the capture session alone predicts: the room as a probe.

Every GelFabric fabric was captured in one session, and the room (wall, floor, side panel) sits
a few millimetres differently in each. If fabrics of one kind were captured in the same
sessions, the room predicts the labels of fabrics it never saw, and a property probe on an
embedding that carries the room reads them without reading the cloth. This is the control for
`lookfeel cv`'s property probes (thickness, density, stiffness R^2; issue #12).

The room is the background of raw depth (`lookfeel data leakage`'s rule: pixels within 20 mm of
their median in 95% of images, after 4x4 mean pooling; no cloth reaches them). For each run of
a ``lookfeel cv`` folder, the probe `lookfeel cv` fits on the embedding (ridge on per-fabric
means, `lookfeel.metrics.property_probe`) is fitted on the room pixels of the run's training
fabrics and scored on its held-out ones, beside the run's own model probe. Means over runs.
Since session 39 `lookfeel cv` reports the same probe (`lookfeel.crossval.RoomProbe`) in its
property table; this reads it for a cv folder scored before that.

    python -m benchmarks.bench_depth_room_labels --cv CV [--data ../shared/data/gelfabric]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from benchmarks.bench_depth_position import DEFAULT_DATA, write_result


def measure(cv: Path, data: Path) -> dict[str, object]:
    from lookfeel.crossval import RoomProbe
    from lookfeel.data import scan
    from lookfeel.modality import Modality

    t0 = time.perf_counter()
    catalog = scan(data, require=[Modality.DEPTH], strict=True)
    room = RoomProbe(catalog, workers=2)
    runs = sorted(p.parent for p in cv.glob("seed*-fold*/result.json"))
    if not runs:
        raise SystemExit(f"{cv}: no finished runs (seed*-fold*/result.json)")
    columns = list(catalog.label_columns)
    per_run: dict[str, dict[str, dict[str, float]]] = {}
    for r in runs:
        split = json.loads((r / "split.json").read_text(encoding="utf-8"))
        alone = room(split["train"], split["val"]) or {}
        model = json.loads((r / "result.json").read_text(encoding="utf-8"))["properties"]["depth"][
            "model"
        ]
        per_run[r.name] = {
            c: {"room": alone[c]["r2"], "model": model[c]["r2"]}
            for c in columns
            if c in model and c in alone
        }
    mean = {
        c: {k: float(np.nanmean([v[c][k] for v in per_run.values()])) for k in ("room", "model")}
        for c in columns
        if all(c in v for v in per_run.values())
    }
    return {
        "what": "R^2 of ridge probes on held-out fabrics: the room's pixels alone vs the model",
        "cv": str(cv),
        "background_pixels": room.background_pixels,
        "runs": len(runs),
        "mean_r2": mean,
        "per_run": per_run,
        "seconds": round(time.perf_counter() - t0, 1),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--cv", type=Path, required=True, help="a lookfeel cv folder (depth)")
    ap.add_argument("--out", type=Path, default=None, help="write the JSON here")
    args = ap.parse_args(argv)
    if not args.data.exists():
        print(f"{args.data}: no such dataset", file=sys.stderr)
        return 1
    result = measure(args.cv, args.data)
    print(json.dumps(result["mean_r2"], indent=1), flush=True)
    if args.out is not None:
        write_result(result, args.out, "bench_depth_room_labels", argv)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
