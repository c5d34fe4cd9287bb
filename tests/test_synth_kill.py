"""Killing `lookfeel synth` (even with SIGKILL) kills its workers, and the half-rendered world
it leaves fails `data check`; killing a decoding process or `lookfeel reproduce` kills theirs."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from lookfeel.data import check_dataset
from tests._processes import alive

pytestmark = pytest.mark.skipif(
    not Path("/proc/self/stat").exists(), reason="reads process parents from /proc (Linux)"
)


def _children(pid: int) -> set[int]:
    """Processes whose parent is ``pid`` (read from /proc)."""
    out = set()
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            stat = (d / "stat").read_text(encoding="utf-8")
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2 :].split()
        if int(fields[1]) == pid:
            out.add(int(d.name))
    return out


def _kill_and_wait_for(proc: subprocess.Popen[bytes], workers: set[int], what: str) -> None:
    """SIGKILL ``proc``; fail unless every one of ``workers`` ends within 10 s."""
    assert proc.poll() is None, f"{what} finished before it could be killed"
    assert len(workers) >= 2, f"expected 2 worker processes of {what}, found {workers}"
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=10)
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(alive(w) for w in workers):
        time.sleep(0.05)
    assert not any(alive(w) for w in workers), f"workers outlived the killed {what}"


def _images(root: Path) -> int:
    return sum(1 for p in root.rglob("*") if p.suffix in (".png", ".jpg"))


def _kill_lookfeel_once_busy(args: list[str], busy: Callable[[], bool], what: str) -> None:
    """Start ``lookfeel ARGS`` in a fresh interpreter; once it has 2 live child processes and
    ``busy()`` holds, SIGKILL it and fail unless every child ends within 10 s."""
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1] / "src"))
    proc = subprocess.Popen(
        [sys.executable, "-m", "lookfeel", *args],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 120
        workers: set[int] = set()
        while time.monotonic() < deadline and proc.poll() is None:
            workers = {w for w in _children(proc.pid) if alive(w)}
            if len(workers) >= 2 and busy():
                break
            time.sleep(0.05)
        _kill_and_wait_for(proc, workers, what)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_sigkill_of_synth_kills_its_workers_and_the_world_fails_check(tmp_path: Path):
    out = tmp_path / "world"
    args = ["--size", "tiny", "--fabrics", "60", "--workers", "2", "--no-contact-sheet"]
    _kill_lookfeel_once_busy(
        ["synth", str(out), *args, "--quiet"],
        lambda: out.is_dir() and _images(out) > 0,
        "synth (raise --fabrics if it finished)",
    )
    n = _images(out)
    time.sleep(1.5)
    assert _images(out) == n, "files kept appearing after synth was killed"
    catalog = check_dataset(out)
    messages = [str(p) for p in catalog.errors]
    assert any("synthetic world was not finished" in m for m in messages), messages


_SLOW_DECODER = """
import sys, time
from pathlib import Path
from lookfeel.config import DataConfig
from lookfeel.data import ImageLoader, scan
from lookfeel.data.images import ImageLoader as L
from lookfeel.modality import Modality

real = L._preprocess_file
L._preprocess_file = lambda self, p, m: (time.sleep(0.2), real(self, p, m))[1]
items = scan(Path(sys.argv[1])).items(Modality.COLOR)
ImageLoader(DataConfig(image_size=16, workers=2, decode="processes")).preload(items)
"""


def test_sigkill_of_a_decoding_process_kills_its_decode_workers(tmp_path: Path):
    from ._tiny import write_tiny_dataset

    root = write_tiny_dataset(tmp_path / "d", fabrics=10, drapes=20, fold_presses=0)
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1] / "src"))
    proc = subprocess.Popen([sys.executable, "-c", _SLOW_DECODER, str(root)], env=env)
    try:
        deadline = time.monotonic() + 60
        workers: set[int] = set()
        while time.monotonic() < deadline and proc.poll() is None and len(workers) < 2:
            workers = {w for w in _children(proc.pid) if alive(w)}
            time.sleep(0.05)
        _kill_and_wait_for(proc, workers, "decoding process")
    finally:
        if proc.poll() is None:
            proc.kill()


def test_sigkill_of_reproduce_kills_the_runs_training_side_by_side(tmp_path: Path):
    from ._tiny import write_tiny_dataset

    root = write_tiny_dataset(tmp_path / "d", fabrics=10, drapes=5, fold_presses=4)
    runs = tmp_path / "r" / "runs"
    args = ["--budget", "tiny", "--workers", "2", "--set", "train.steps=5000"]
    _kill_lookfeel_once_busy(
        ["reproduce", "--data", str(root), "--out", str(tmp_path / "r"), *args],
        lambda: len(list(runs.glob("*/seed0/config.yaml"))) >= 2,  # two runs training
        "reproduce (raise train.steps if it finished)",
    )
    assert not list(runs.glob("*/seed0/eval.json"))  # no run had finished: nothing half-scored
