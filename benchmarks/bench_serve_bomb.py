"""Decompression bombs against the web app: 20 concurrent clients upload 13000 x 13000 PNGs.

``lookfeel serve`` runs in its own process on 127.0.0.1 only (a free port; its defaults) over a
library of 20 fabrics (the compact CNN at 64 px, random weights). Each bomb is a real PNG of
13000 x 13000 zeros, under 1 MB on disk and 169 megapixels decoded (507 MB as RGB; before the
pixel limit one cost 2.1 GB and 20 s of CPU). Twenty client threads post bombs back to back
until 20 s have passed or 400 were sent, while one more client posts an ordinary depth query
every 0.25 s. Reported: the server's peak resident memory (``VmHWM`` from /proc, Linux) and
its idle memory, every bomb's status (each must be a 413 naming the file), and the ordinary
queries' latency (each must be a 200). Target: peak memory below 1 GB.
"""

from __future__ import annotations

import platform
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np
from tests._tiny import bomb_png

from benchmarks.bench_index import COMPACT, SIZE, write_checkpoint, write_dataset
from benchmarks.bench_serve import serving

CLIENTS = 20
SECONDS = 20.0
MAX_BOMBS = 400
SIDE = 13000
TARGET_PEAK_MB = 1024.0


def _status_kb(pid: int, key: str) -> float:
    """A ``/proc/PID/status`` field in kB (VmRSS, VmHWM); NaN where there is no /proc."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text(encoding="utf-8").splitlines():
            if line.startswith(key + ":"):
                return float(line.split()[1])
    except OSError:
        pass
    return float("nan")


def _device() -> str:
    """The CPU the numbers were measured on, in words."""
    try:
        for line in Path("/proc/cpuinfo").read_text(encoding="utf-8").splitlines():
            if line.startswith("model name"):
                return f"CPU: {line.split(':', 1)[1].strip()}"
    except OSError:
        pass
    return f"CPU: {platform.processor() or platform.machine()}"


def _attack(url: str, bomb: bytes, probe: bytes) -> dict[str, Any]:
    statuses: dict[int, int] = {}
    wrong: list[str] = []
    probe_ms: list[float] = []
    probe_failed: list[str] = []
    lock = threading.Lock()
    sent = [0]
    deadline = time.monotonic() + SECONDS
    done = threading.Event()

    def client() -> None:
        with httpx.Client(base_url=url, timeout=120.0) as http:
            while time.monotonic() < deadline:
                with lock:
                    if sent[0] >= MAX_BOMBS:
                        return
                    sent[0] += 1
                try:
                    r = http.post(
                        "/api/match",
                        data={"modality": "color"},
                        files=[("files", ("bomb.png", bomb, "image/png"))],
                    )
                    code, text = r.status_code, r.text
                except httpx.HTTPError as e:
                    code, text = 0, f"{type(e).__name__}: {e}"
                with lock:
                    statuses[code] = statuses.get(code, 0) + 1
                    if code != 413 or "bomb.png: declares 13000x13000" not in text:
                        wrong.append(f"{code}: {text[:200]}")

    def prober() -> None:
        with httpx.Client(base_url=url, timeout=120.0) as http:
            while not done.is_set():
                t = time.perf_counter()
                r = http.post(
                    "/api/match",
                    data={"modality": "depth"},
                    files=[("files", ("d.png", probe, "image/png"))],
                )
                with lock:
                    probe_ms.append(1e3 * (time.perf_counter() - t))
                    if r.status_code != 200:
                        probe_failed.append(f"{r.status_code}: {r.text[:200]}")
                done.wait(0.25)

    started = time.monotonic()
    probe_thread = threading.Thread(target=prober)
    probe_thread.start()
    threads = [threading.Thread(target=client) for _ in range(CLIENTS)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    done.set()
    probe_thread.join()
    elapsed = time.monotonic() - started
    lat = np.array(probe_ms) if probe_ms else np.array([np.nan])
    return {
        "bombs_sent": sum(statuses.values()),
        "bomb_statuses": {str(k): v for k, v in sorted(statuses.items())},
        "bombs_not_refused": len(wrong),
        "examples_not_refused": wrong[:3],
        "attack_seconds": round(elapsed, 1),
        "ordinary_queries": len(probe_ms),
        "ordinary_failed": len(probe_failed),
        "ordinary_latency_ms": {
            "p50": round(float(np.percentile(lat, 50)), 1),
            "max": round(float(lat.max()), 1),
        },
    }


def run(data: Path | None) -> dict[str, object]:
    from lookfeel.index import build_library

    bomb = bomb_png(SIDE, SIDE)
    with tempfile.TemporaryDirectory() as tmp:
        root = write_dataset(Path(tmp) / "data", fabrics=20, depth=2, color=2, touch=1)
        ckpt = write_checkpoint(Path(tmp) / "compact.pt", COMPACT, SIZE)
        build_library(ckpt, root, Path(tmp) / "lib", progress=False)
        probe = (root / "depth/F0007_1.png").read_bytes()
        with serving(Path(tmp) / "lib") as (url, proc):
            idle_kb = _status_kb(proc.pid, "VmRSS")
            result = _attack(url, bomb, probe)
            peak_kb = _status_kb(proc.pid, "VmHWM")
    peak_mb = peak_kb / 1024
    return {
        "device": _device(),
        "network": "loopback only (127.0.0.1)",
        "clients": CLIENTS,
        "duration_s": SECONDS,
        "max_bombs": MAX_BOMBS,
        "bomb": {"width": SIDE, "height": SIDE, "bytes": len(bomb), "mode": "8-bit grey PNG"},
        "server": "lookfeel serve --host 127.0.0.1 (defaults: max 25 megapixels per upload)",
        "server_idle_rss_mb": round(idle_kb / 1024, 1),
        "server_peak_rss_mb": round(peak_mb, 1),
        **result,
        "targets": {"peak_rss_mb_below": TARGET_PEAK_MB, "bombs_refused": "all, with 413"},
        "met": bool(
            peak_mb < TARGET_PEAK_MB
            and result["bombs_not_refused"] == 0
            and result["ordinary_failed"] == 0
            and result["bombs_sent"] > 0
        ),
    }
