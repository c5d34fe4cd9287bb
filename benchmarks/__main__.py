"""Run benchmarks and write one JSON file per benchmark (``benchmarks/results/`` by default).

Each ``benchmarks/bench_<name>.py`` defines ``run(data: Path | None) -> dict``: it measures
(medians or ratios over repeated runs, never one timing), and returns JSON-able results
including its targets and whether they were met. This runner adds the machine's description
and writes ``<out>/<name>.json`` atomically (``--out``, default ``benchmarks/results/``). A
benchmark skipped here (its data missing) never replaces a stored measurement: the runner
keeps that file and says so. A benchmark without ``run`` scores the runs of a ``lookfeel cv``
folder (``bench_depth_swap``, ``bench_depth_room_labels``, ``bench_touch_metric``): the runner
names it and skips it; run it on its own with ``--cv``.

    python -m benchmarks [--data ../shared/data/gelfabric] [--only NAME ...] [--out FOLDER]
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import platform
import subprocess
import sys
import time
from collections.abc import Mapping
from pathlib import Path

import torch

from lookfeel.atomic import atomic_write_text

HERE = Path(__file__).resolve().parent


def _cpuinfo() -> str:
    """``/proc/cpuinfo`` (Linux), or "" where there is none."""
    try:
        return Path("/proc/cpuinfo").read_text(encoding="utf-8")
    except OSError:
        return ""


def _cpuinfo_field(cpuinfo: str, key: str) -> str | None:
    """The value of the first ``key : value`` line of ``cpuinfo`` (the key exactly), or None."""
    for line in cpuinfo.splitlines():
        name, colon, value = line.partition(":")
        if colon and name.strip() == key:
            return value.strip()
    return None


# Where /proc/cpuinfo names the model: x86 ("model name"), 32-bit ARM ("Processor"), MIPS
# ("cpu model"), POWER ("cpu").
_CPU_MODEL_KEYS = ("model name", "Processor", "cpu model", "cpu")


def _sysctl_cpu() -> str | None:
    """macOS's name of the CPU (``sysctl machdep.cpu.brand_string``), or None."""
    try:
        done = subprocess.run(
            ["sysctl", "-n", "machdep.cpu.brand_string"],
            capture_output=True,
            text=True,
            check=False,
            timeout=5,
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout.strip() or None


def _cpu_model(cpuinfo: str) -> str | None:
    """The CPU's model name, e.g. ``AMD EPYC``: float results of training differ between CPU
    families, and so may the numbers a benchmark records. None where the system names none."""
    for key in _CPU_MODEL_KEYS:
        value = _cpuinfo_field(cpuinfo, key)
        if value:
            return value
    return _sysctl_cpu() if sys.platform == "darwin" else None


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


def now() -> str:
    """The local time with its UTC offset, as a result records when it was measured."""
    return time.strftime("%Y-%m-%dT%H:%M:%S%z")


def stamp(name: str, started: float, result: dict[str, object]) -> dict[str, object]:
    """``result`` headed by the benchmark's name, the time, its duration and the machine."""
    return {
        "benchmark": name,
        "when": now(),
        "seconds": round(time.time() - started, 2),
        "machine": machine(),
        **result,
    }


def skip_reason(result: Mapping[str, object]) -> str | None:
    """Why ``result`` measured nothing, or None where it holds a measurement.

    A result is a skip when it says ``skipped`` itself, or when it sets no ``met`` and every part
    of a table of parts says ``skipped`` (``bench_train_real``'s recipes, none of whose data is
    there).
    """
    reason = result.get("skipped")
    if reason is not None:
        return str(reason)
    if result.get("met") is not None:
        return None
    reasons = []
    for value in result.values():
        if not isinstance(value, dict) or not value:
            continue
        if not all(isinstance(part, dict) for part in value.values()):
            continue
        if not all("skipped" in part for part in value.values()):
            return None
        reasons += [f"{key}: {part['skipped']}" for key, part in value.items()]
    return "; ".join(reasons) or None


def _measured_on(stored: Mapping[str, object]) -> str:
    """``<date> <machine>`` of a stored result, e.g. ``2026-11-29 AMD EPYC (avx512)``."""
    when = stored.get("when")
    date = str(when)[:10] if when else "an unknown date"
    machine = stored.get("machine")
    if not isinstance(machine, Mapping):
        return f"{date}, machine not recorded"
    cpu = machine.get("cpu_model")
    if cpu:
        what = str(cpu)
        if machine.get("cpu_vectors"):
            what += f" ({machine['cpu_vectors']})"
    else:
        what = f"{machine.get('processor') or 'a machine'} (CPU model not recorded)"
    if machine.get("gpu"):
        what += f", {machine['gpu']}"
    return f"{date} {what}"


def kept_stored(path: Path, result: Mapping[str, object]) -> str | None:
    """Where ``result`` is a skip and ``path`` holds a measurement: a line saying the stored
    result is kept (the caller then leaves ``path`` as it is); else None (write ``result``)."""
    reason = skip_reason(result)
    if reason is None:
        return None
    try:
        stored = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):  # nothing there, or nothing readable: nothing to keep
        return None
    if not isinstance(stored, Mapping) or skip_reason(stored) is not None:
        return None
    return (
        f"kept the stored result of {_measured_on(stored)} in {path}: skipped here because {reason}"
    )


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
    """Stamp a benchmark run on its own, print its JSON and write it to ``out`` if given
    (unless it was skipped and ``out`` holds a measurement: that is kept, and a line says so).

    Returns:
        The exit status: 1 when the benchmark says its targets were not met, else 0.
    """
    result = stamp(name, started, result)
    text = json.dumps(result, indent=2) + "\n"
    kept = kept_stored(out, result) if out is not None else None
    if out is not None and kept is None:
        atomic_write_text(out, text)
    print(text)
    if kept is not None:
        print(kept)
    return 1 if result.get("met") is False else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__)
    parser.add_argument(
        "--data",
        type=Path,
        default=None,
        help="the real GelFabric root (a folder); without it the benchmarks that need it skip",
    )
    parser.add_argument("--only", nargs="*", default=None, help="benchmark names to run")
    parser.add_argument(
        "--out",
        type=Path,
        default=HERE / "results",
        metavar="FOLDER",
        help="the folder results are written to, one <name>.json each (default "
        "benchmarks/results/); write elsewhere to compare with the stored ones without "
        "replacing them",
    )
    args = parser.parse_args(argv)
    if args.data is not None and not args.data.is_dir():
        what = "is not a folder" if args.data.exists() else "no such folder"
        parser.error(
            f"--data {args.data}: {what} (the real GelFabric root; leave --data out to run "
            "without it, the benchmarks that need it then skip)"
        )
    if args.out.exists() and not args.out.is_dir():
        parser.error(f"--out {args.out}: is a file, not a folder")
    data = args.data
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
        kept = kept_stored(args.out / f"{name}.json", result)
        if kept is not None:
            print(f"== {name}: {kept}")
            continue
        path = atomic_write_text(args.out / f"{name}.json", json.dumps(result, indent=2) + "\n")
        print(json.dumps(result, indent=2))
        print(f"-> {path}")
        if result.get("met") is False:
            failed += 1
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
