"""The synthetic world's information table (issue #17 point 3): how much each modality's pixels
reveal about each latent (log thickness, log density, stiffness, stretchiness, log bending
length; material and weave), by fabric-disjoint probes on fixed pixel features, and how well
fabrics match across modalities from those probes alone (`lookfeel.synth.information`).

It is the world's honest ceiling: run it on a world before and after a generator change.

Generates a paper-size world (118 fabrics, 10 drapes, 10 flat + 15 fold presses x 3 frames,
2 worker processes) into a temporary folder, unless given one; target: the table of that world
(about 11,000 images) in <= 5 minutes on 2 cores.

    python -m benchmarks --only synth_information          # generates a world
    python -m benchmarks.bench_synth_information [WORLD]   # an existing world (or none)

Run on its own it writes ``benchmarks/results/synth_information.json`` and prints the tables.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from lookfeel.synth import MANIFEST, SynthConfig, generate
from lookfeel.synth.information import WorldError, format_information_table, information_table

FABRICS = 118
WORKERS = 2
TARGET_S = 300.0
RESULTS = Path(__file__).resolve().parent / "results" / "synth_information.json"


def _table(world: Path, max_images: int | None) -> dict[str, Any]:
    started = time.perf_counter()
    result = information_table(world, max_images_per_fabric=max_images, workers=WORKERS)
    seconds = time.perf_counter() - started
    n_images = sum(result["images"].get(m, 0) for m in ("depth", "color", "touch"))
    return {
        "what": "fabric-disjoint 5-fold probes of each latent from each modality's pixels, and "
        "pick 1 of 10 matching from the probes' predictions",
        "table_seconds": round(seconds, 1),
        "table_markdown": format_information_table(result),
        "information": result,
        "target": f"table of a {FABRICS}-fabric world ({n_images} images here) in <= "
        f"{TARGET_S:.0f} s with {WORKERS} workers",
        "target_s": TARGET_S,
        "met": seconds <= TARGET_S,
    }


def run(
    data: Path | None, world: Path | None = None, max_images: int | None = None
) -> dict[str, Any]:
    """The table of ``world`` (or of ``data`` when it is a synthetic world), else of a freshly
    generated paper-size world. ``data`` is the benchmark runner's real-data root: the real
    GelFabric has no truth, so it is used only when it holds a ``synth.json``."""
    if world is None and data is not None and (data / MANIFEST).is_file():
        world = data
    if world is not None:
        return {"world": str(world), "generated": False, **_table(world, max_images)}
    with tempfile.TemporaryDirectory(prefix="bench_synth_information_") as tmp:
        out = Path(tmp) / "world"
        started = time.perf_counter()
        generate(SynthConfig(fabrics=FABRICS, workers=WORKERS), out, progress=False)
        synth_s = time.perf_counter() - started
        result = _table(out, max_images)
    return {
        "world": f"generated: {FABRICS} fabrics, seed 0",
        "generated": True,
        "synth_seconds": round(synth_s, 1),
        **result,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_synth_information")
    parser.add_argument(
        "world", type=Path, nargs="?", default=None, help="a synthetic world (else generate one)"
    )
    parser.add_argument("--max-images-per-fabric", type=int, default=None)
    parser.add_argument("--out", type=Path, default=RESULTS, help="write the JSON here")
    args = parser.parse_args(argv)
    from benchmarks.__main__ import write_standalone

    started = time.time()
    try:
        result = run(None, args.world, args.max_images_per_fabric)
    except WorldError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    status = write_standalone("synth_information", started, result, args.out)
    print(result["table_markdown"])
    return status


if __name__ == "__main__":
    sys.exit(main())
