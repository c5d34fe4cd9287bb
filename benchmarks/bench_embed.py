"""Embedding speed of the paper's AlexNet branch at 227 px: images/s once decoded, and end to
end from image files (decode, preprocess, embed).

``decoded`` embeds preprocessed touch images already on the device (an `ImageStore`: GPU
memory on CUDA); ``host`` embeds them from the loader's memory cache (copied over through
pinned buffers); ``from_files`` starts from PNG files on disk with a fresh loader
(`embed_catalog`: decoding in ``data.workers`` worker processes, each batch embedded as soon
as it is decoded). ``decode_images_per_s`` times the decoding alone, in 1 and ``workers``
threads and processes: threads stop scaling at the GIL, processes scale with the cores.
Medians over repeats.

    PYTHONPATH=src python -m benchmarks.bench_embed --device cuda \\
        --out benchmarks/results/embed_h100.json

Targets on one H100: >= 50,000 images/s decoded, >= 5,000 images/s from files. On 2 CPU
cores: ~190 images/s decoded (the shipped code with channels-last).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch
from PIL import Image

from benchmarks.bench_train_step import device_name

TARGETS = {
    "cuda": {"decoded_images_per_s": 50_000.0, "from_files_images_per_s": 5_000.0},
    "cpu": {"decoded_images_per_s": 190.0},
}


def _write_touch(root: Path, n: int, seed: int = 0) -> Path:
    """``n`` random single-frame touch presses (320x240 PNG) over n/10 fabrics, in the layout."""
    rng = np.random.default_rng(seed)
    (root / "touch").mkdir(parents=True, exist_ok=True)
    fabrics = max(1, n // 10)
    for i in range(n):
        t = rng.integers(0, 255, (240, 320, 3)).astype(np.uint8)
        Image.fromarray(t).save(
            root / "touch" / f"F{i % fabrics + 1:04d}_fold_1_{i // fabrics}.png"
        )
    (root / "labels.csv").write_text(
        "fabric_id\n" + "".join(f"{f}\n" for f in range(1, fabrics + 1)), encoding="utf-8"
    )
    return root


def _sync(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def run(
    data: Path | None, device: str = "cpu", images: int | None = None, repeats: int = 3
) -> dict[str, object]:
    """Measure on ``device``; the `benchmarks` runner's entry point (CPU)."""
    from lookfeel.config import DataConfig, ModelConfig
    from lookfeel.data import ImageLoader, ImageStore, scan
    from lookfeel.embedding import embed_catalog, embed_items
    from lookfeel.modality import Modality

    dev = torch.device(device)
    n = images or (10_000 if dev.type == "cuda" else 256)
    batch = 1024 if dev.type == "cuda" else 64
    warnings.simplefilter("ignore")  # random AlexNet: no ImageNet file here
    from lookfeel.models import create_model

    model = create_model(ModelConfig(backbone="alexnet"), [Modality.TOUCH]).to(dev)
    if dev.type == "cuda":
        model = model.to(memory_format=torch.channels_last)  # type: ignore[call-overload, unused-ignore]
        torch.backends.cudnn.benchmark = True
        torch.cuda.reset_peak_memory_stats()
    config = DataConfig(image_size=227, workers=16 if dev.type == "cuda" else 2)
    with tempfile.TemporaryDirectory() as tmp:
        root = _write_touch(Path(tmp) / "data", n)
        catalog = scan(root)
        items = catalog.items(Modality.TOUCH)
        warm = ImageLoader(config)
        warm.preload(items)
        embed_items(model, items[: 2 * batch], warm, batch, dev)  # warm-up (cuDNN autotune)
        store = ImageStore(warm, items, dev)
        decoded, host = [], []
        for _ in range(repeats):
            _sync(dev)
            t0 = time.perf_counter()
            embed_items(model, items, warm, batch, dev, store=store)
            decoded.append(len(items) / (time.perf_counter() - t0))
            t0 = time.perf_counter()
            embed_items(model, items, warm, batch, dev)
            host.append(len(items) / (time.perf_counter() - t0))
        files = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            embed_catalog(model, catalog, ImageLoader(config), batch_size=batch, device=dev)
            files.append(len(items) / (time.perf_counter() - t0))
        decode: dict[str, dict[str, float]] = {}
        some = items[:2000]  # one worker decodes ~300 a second
        for mode in ("threads", "processes"):
            for w in sorted({1, config.workers}):
                rates = []
                for _ in range(repeats):
                    fresh = ImageLoader(replace(config, workers=w, decode=mode))
                    t0 = time.perf_counter()
                    fresh.preload(some)
                    rates.append(len(some) / (time.perf_counter() - t0))
                decode.setdefault(mode, {})[str(w)] = round(statistics.median(rates), 1)
    result: dict[str, object] = {
        "model": "alexnet touch branch, 227 px",
        "device": dev.type,
        "device_name": device_name(dev.type),
        "images": len(items),
        "batch_size": batch,
        "decoded_images_per_s": round(statistics.median(decoded), 1),
        "host_images_per_s": round(statistics.median(host), 1),
        "from_files_images_per_s": round(statistics.median(files), 1),
        "decode_images_per_s": decode,
        "decode_workers": config.workers,
        "repeats": {
            "decoded": [round(x, 1) for x in decoded],
            "from_files": [round(x, 1) for x in files],
        },
    }
    if dev.type == "cuda":
        result["peak_gpu_gb"] = round(torch.cuda.max_memory_allocated() / 2**30, 2)
    targets = TARGETS["cuda" if dev.type == "cuda" else "cpu"]
    result["targets"] = targets
    result["met"] = all(float(result[k]) >= t for k, t in targets.items())  # type: ignore[arg-type]
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_embed")
    parser.add_argument("--device", choices=("cpu", "cuda"), default="cpu")
    parser.add_argument("--images", type=int, default=None)
    parser.add_argument("--out", type=Path, default=None, help="write the JSON here")
    args = parser.parse_args(argv)
    from benchmarks.__main__ import write_standalone

    started = time.time()
    return write_standalone("embed", started, run(None, args.device, args.images), args.out)


if __name__ == "__main__":
    sys.exit(main())
