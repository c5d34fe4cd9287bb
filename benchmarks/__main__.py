"""Run benchmarks and write one JSON file per benchmark under ``benchmarks/results/``.

Each ``benchmarks/bench_<name>.py`` defines ``run(data: Path | None) -> dict``: it measures
(medians or ratios over repeated runs, never one timing), and returns JSON-able results
including its targets and whether they were met. This runner adds the machine's description
and writes ``benchmarks/results/<name>.json`` atomically. A benchmark without ``run`` scores
the runs of a ``lookfeel cv`` folder (``bench_depth_swap``, ``bench_depth_room_labels``,
``bench_touch_metric``): the runner names it and skips it; run it on its own with ``--cv``.

    python -m benchmarks [--data ../shared/data/gelfabric] [--only NAME ...]
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import platform
import sys
import time
from pathlib import Path

import torch

from lookfeel.atomic import atomic_write_text

HERE = Path(__file__).resolve().parent


def _cpuinfo() -> str:
    """``/proc/cpuinfo`` (Linux), or "" where there is none."""
    try:
        return Path("/proc/cpuinfo").read_text()
    except OSError:
        return ""


def _cpuinfo_field(cpuinfo: str, key: str) -> str | None:
    """The value of the first ``key : value`` line of ``cpuinfo``, or None."""
    for line in cpuinfo.splitlines():
        if line.startswith(key):
            return line.partition(":")[2].strip()
    return None


def _cpu_model(cpuinfo: str) -> str | None:
    """The CPU's model name, e.g. ``AMD EPYC``: float results of training differ between CPU
    families, and so may the numbers a benchmark records."""
    return _cpuinfo_field(cpuinfo, "model name")


def _cpu_vectors(cpuinfo: str) -> str | None:
    """The widest x86 vector extension the CPU has (``avx512``, ``avx2``), or None: two CPUs
    named alike (``AMD EPYC``) may differ in it, and so in speed and in how a run rounds."""
    flags = (_cpuinfo_field(cpuinfo, "flags") or "").split()
    for name, flag in (("avx512", "avx512f"), ("avx2", "avx2")):
        if flag in flags:
            return name
    return None


def machine() -> dict[str, object]:
    """What the numbers were measured on."""
    cpuinfo = _cpuinfo()
    return {
        "python": platform.python_version(),
        "torch": torch.__version__,
        "cpus": os.cpu_count(),
        "torch_threads": torch.get_num_threads(),
        "processor": platform.processor() or platform.machine(),
        "cpu_model": _cpu_model(cpuinfo),
        "cpu_vectors": _cpu_vectors(cpuinfo),
        # The GPU a benchmark may have used (None without CUDA): training, embedding and the
        # demo run on it by default (`train.device: auto`).
        "gpu": torch.cuda.get_device_name(0) if torch.cuda.is_available() else None,
    }


def stamp(name: str, started: float, result: dict[str, object]) -> dict[str, object]:
    """``result`` headed by the benchmark's name, the time, its duration and the machine."""
    return {
        "benchmark": name,
        "when": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "seconds": round(time.time() - started, 2),
        "machine": machine(),
        **result,
    }


def add_set_option(parser: argparse.ArgumentParser, example: str) -> None:
    """``--set KEY=VALUE`` (repeatable, into ``args.overrides``) for a benchmark run on its own
    that trains: a config change, e.g. ``example``."""
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help=f"change the config (repeatable), e.g. {example}",
    )


def write_standalone(name: str, started: float, result: dict[str, object], out: Path | None) -> int:
    """Stamp a benchmark run on its own, print its JSON and write it to ``out`` if given.

    Returns:
        The exit status: 1 when the benchmark says its targets were not met, else 0.
    """
    result = stamp(name, started, result)
    text = json.dumps(result, indent=2) + "\n"
    if out is not None:
        atomic_write_text(out, text)
    print(text)
    return 1 if result.get("met") is False else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__)
    parser.add_argument("--data", type=Path, default=None, help="real GelFabric root, if any")
    parser.add_argument("--only", nargs="*", default=None, help="benchmark names to run")
    parser.add_argument("--out", type=Path, default=HERE / "results")
    args = parser.parse_args(argv)
    data = args.data if args.data is not None and args.data.is_dir() else None
    names = sorted(p.stem[len("bench_") :] for p in HERE.glob("bench_*.py"))
    if args.only:
        unknown = sorted(set(args.only) - set(names))
        if unknown:
            parser.error(f"unknown benchmark(s) {', '.join(unknown)}; have: {', '.join(names)}")
        names = [n for n in names if n in args.only]
    failed = 0
    for name in names:
        module = importlib.import_module(f"benchmarks.bench_{name}")
        if not hasattr(module, "run"):  # scores the runs of a cv folder: run it on its own
            print(f"== {name}: standalone, see python -m benchmarks.bench_{name} --help")
            continue
        print(f"== {name}", flush=True)
        started = time.time()
        result = stamp(name, started, module.run(data))
        path = atomic_write_text(args.out / f"{name}.json", json.dumps(result, indent=2) + "\n")
        print(json.dumps(result, indent=2))
        print(f"-> {path}")
        if result.get("met") is False:
            failed += 1
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
