"""Training speed of the paper's Multi-input Net at 227 px, batch 128: trunk cache vs full.

Issue targets (2 cores): ``cached_steps_per_s / full_steps_per_s >= 10``, the 25,000-step
schedule in <= 2.5 h with the cache, and peak memory <= 6 GB. Each mode runs in its own
process (``python -m benchmarks.bench_train_step MODE DATA OUT``) on a generated dataset of
random images in the layout (speed does not depend on the pixels), with
``configs/paper/multi_input.yaml`` (AlexNet, fc6 frozen, 3 presses per touch input, cluster
head). Steps/s is the median over logged windows after the first (warm-up) window.
"""

from __future__ import annotations

import json
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "paper" / "multi_input.yaml"
TARGET_RATIO = 10.0
TARGET_HOURS = 2.5
TARGET_PEAK_GB = 6.0
SCHEDULE = 25_000
MODES = {
    # mode: (steps, log_every, overrides)
    "cached": (60, 10, ["train.cache_trunk=true"]),
    "full": (4, 1, ["train.cache_trunk=false"]),
}


def write_dataset(root: Path, fabrics: int = 24, seed: int = 0) -> Path:
    """Random images in the layout: 3 depth, 3 colour, 6 single-frame fold presses a fabric."""
    rng = np.random.default_rng(seed)
    for f in range(1, fabrics + 1):
        for k in range(3):
            (root / "depth").mkdir(parents=True, exist_ok=True)
            d = rng.integers(700, 1500, (224, 224)).astype(np.uint16)
            Image.fromarray(d).save(root / "depth" / f"F{f:04d}_{k}.png")
            c = rng.integers(0, 255, (256, 256, 3)).astype(np.uint8)
            (root / "color").mkdir(exist_ok=True)
            Image.fromarray(c).save(root / "color" / f"F{f:04d}_{k}.png")
        for p in range(6):
            t = rng.integers(0, 255, (240, 320, 3)).astype(np.uint8)
            (root / "touch").mkdir(exist_ok=True)
            Image.fromarray(t).save(root / "touch" / f"F{f:04d}_fold_1_{p}.png")
    lines = ["fabric_id,cluster8"] + [f"{f},{f % 8}" for f in range(1, fabrics + 1)]
    (root / "labels.csv").write_text("\n".join(lines) + "\n")
    return root


def _child(mode: str, data: Path, out: Path) -> None:
    """Run one mode in this process and print its measurements as JSON."""
    import warnings

    from lookfeel.config import RunConfig, load_config
    from lookfeel.train import train

    warnings.simplefilter("ignore")  # frozen random AlexNet: no ImageNet file here
    steps, log_every, overrides = MODES[mode]
    config = load_config(
        RunConfig,
        CONFIG,
        [
            *overrides,
            f"train.steps={steps}",
            f"train.log_every={log_every}",
            "train.split=none",
            "train.val_every=0",
            "train.checkpoint_every=0",
            "train.progress=false",
        ],
    )
    train(config, data, out)
    lines = [json.loads(x) for x in (out / "metrics.jsonl").read_text().splitlines()]
    rates = [x["steps_per_s"] for x in lines if "steps_per_s" in x][1:]
    cache = next((x for x in lines if "trunk_cache_s" in x), {})
    peak_gb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
    print(
        json.dumps(
            {
                "steps_per_s": statistics.median(rates),
                "windows": [round(r, 3) for r in rates],
                "trunk_cache_s": cache.get("trunk_cache_s"),
                "peak_rss_gb": round(peak_gb, 2),
            }
        )
    )


def run(data: Path | None) -> dict[str, object]:
    with tempfile.TemporaryDirectory() as tmp:
        root = write_dataset(Path(tmp) / "data")
        results = {}
        for mode in MODES:
            proc = subprocess.run(
                [
                    sys.executable,
                    "-m",
                    "benchmarks.bench_train_step",
                    mode,
                    str(root),
                    f"{tmp}/{mode}",
                ],
                capture_output=True,
                text=True,
                check=True,
            )
            results[mode] = json.loads(proc.stdout.strip().splitlines()[-1])
    cached = results["cached"]["steps_per_s"]
    full = results["full"]["steps_per_s"]
    hours = SCHEDULE / cached / 3600
    peak = max(r["peak_rss_gb"] for r in results.values())
    ratio = cached / full
    return {
        "config": "configs/paper/multi_input.yaml",
        "image_size": 227,
        "batch_size": 128,
        "cached_steps_per_s": round(cached, 3),
        "full_steps_per_s": round(full, 4),
        "ratio": round(ratio, 1),
        "schedule_steps": SCHEDULE,
        "schedule_hours_cached": round(hours, 2),
        "trunk_cache_s": results["cached"]["trunk_cache_s"],
        "peak_memory_gb": peak,
        "details": results,
        "targets": {
            "ratio": TARGET_RATIO,
            "schedule_hours": TARGET_HOURS,
            "peak_gb": TARGET_PEAK_GB,
        },
        "met": ratio >= TARGET_RATIO and hours <= TARGET_HOURS and peak <= TARGET_PEAK_GB,
    }


if __name__ == "__main__":
    _child(sys.argv[1], Path(sys.argv[2]), Path(sys.argv[3]))
