"""The web app under load: 20 concurrent clients for 30 s on loopback, no failed request.

``lookfeel serve`` runs in its own process on 127.0.0.1 (a free port; defaults: one PyTorch
thread per query, two queries at a time) over a library of 100 fabrics (4 depth, 4 colour,
2 touch presses each; the compact CNN at 64 px, random weights). Twenty client threads, each
with its own keep-alive connection, post queries back to back, in turn a depth map, a colour
photo and a two-press touch query, until 30 s have passed or 20,000 requests were sent. Every
answer must be a 200 with results; p50/p99 latency and throughput are reported. The clients
share the 2 cores with the server, so the latency includes theirs.

Before the load, one client alone posts `ONE_CLIENT_REQUESTS` queries back to back over one
keep-alive connection, as a browser does (``one_client_ms``): what one user waits. Until
session 55 each such answer waited about 40 ms for the client's delayed ACK (Nagle's delay was
left on: `lookfeel.serve.server._bind`).
"""

from __future__ import annotations

import contextlib
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import torch

from benchmarks.bench_index import COMPACT, SIZE, write_checkpoint, write_dataset

CLIENTS = 20
SECONDS = 30.0
MAX_REQUESTS = 20_000
TARGET_FAILED = 0


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _wait_ready(url: str, proc: subprocess.Popen[bytes], timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise RuntimeError(f"lookfeel serve exited with {proc.returncode}")
        try:
            if httpx.get(url + "/api/library", timeout=2.0).status_code == 200:
                return
        except httpx.HTTPError:
            pass
        time.sleep(0.2)
    raise RuntimeError(f"lookfeel serve did not answer at {url} in {timeout} s")


@contextlib.contextmanager
def serving(library: Path) -> Iterator[tuple[str, subprocess.Popen[bytes]]]:
    """Run ``lookfeel serve`` on ``library`` at a free loopback port until the block ends.

    Yields:
        The server's base URL (once it answers) and its process.
    """
    port = _free_port()
    url = f"http://127.0.0.1:{port}"
    cmd = [
        *(sys.executable, "-m", "lookfeel", "serve", "--index", str(library)),
        *("--host", "127.0.0.1", "--port", str(port)),
    ]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        _wait_ready(url, proc)
        yield url, proc
    finally:
        proc.send_signal(signal.SIGINT)  # uvicorn shuts down gracefully on SIGINT
        try:
            proc.wait(15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)


ONE_CLIENT_REQUESTS = 60
"""Queries one client alone posts, back to back over one connection (`_one_client`)."""


def _post(http: httpx.Client, modality: str, files: list[tuple[str, bytes]]) -> httpx.Response:
    return http.post(
        "/api/match",
        data={"modality": modality},
        files=[("files", (n, b, "image/png")) for n, b in files],
    )


def _one_client(url: str, queries: list[tuple[str, list[tuple[str, bytes]]]]) -> dict[str, Any]:
    """One client's latency over one keep-alive connection, in turn each query (after one
    of each to warm up): its p50 and p90 in ms, and whether every answer was a 200."""
    latencies: list[float] = []
    ok = True
    with httpx.Client(base_url=url, timeout=60.0) as http:
        for modality, files in queries:
            _post(http, modality, files)
        for i in range(ONE_CLIENT_REQUESTS):
            modality, files = queries[i % len(queries)]
            t = time.perf_counter()
            r = _post(http, modality, files)
            latencies.append(1e3 * (time.perf_counter() - t))
            ok = ok and r.status_code == 200
    lat = np.array(latencies)
    return {
        "requests": ONE_CLIENT_REQUESTS,
        "all_ok": ok,
        "p50": round(float(np.percentile(lat, 50)), 1),
        "p90": round(float(np.percentile(lat, 90)), 1),
    }


def _load(url: str, queries: list[tuple[str, list[tuple[str, bytes]]]]) -> dict[str, Any]:
    latencies: list[float] = []
    failures: list[str] = []
    lock = threading.Lock()
    sent = [0]
    deadline = time.monotonic() + SECONDS

    def client(k: int) -> None:
        with httpx.Client(base_url=url, timeout=60.0) as http:
            i = k
            while time.monotonic() < deadline:
                with lock:
                    if sent[0] >= MAX_REQUESTS:
                        return
                    sent[0] += 1
                modality, files = queries[i % len(queries)]
                i += 1
                t = time.perf_counter()
                try:
                    r = _post(http, modality, files)
                    ok = r.status_code == 200 and bool(r.json()["results"][0]["fabrics"])
                    why = f"{r.status_code}: {r.text[:200]}"
                except httpx.HTTPError as e:
                    ok, why = False, f"{type(e).__name__}: {e}"
                dt = 1e3 * (time.perf_counter() - t)
                with lock:
                    latencies.append(dt)
                    if not ok:
                        failures.append(why)

    started = time.monotonic()
    threads = [threading.Thread(target=client, args=(k,)) for k in range(CLIENTS)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    elapsed = time.monotonic() - started
    lat = np.array(latencies)
    return {
        "requests": len(latencies),
        "failed": len(failures),
        "failures": failures[:5],
        "load_seconds": round(elapsed, 1),
        "requests_per_s": round(len(latencies) / elapsed, 1),
        "latency_ms": {
            "p50": round(float(np.percentile(lat, 50)), 1),
            "p99": round(float(np.percentile(lat, 99)), 1),
            "mean": round(statistics.fmean(latencies), 1),
            "max": round(float(lat.max()), 1),
        },
    }


def run(data: Path | None) -> dict[str, object]:
    torch.set_num_threads(2)
    from lookfeel.index import build_library

    with tempfile.TemporaryDirectory() as tmp:
        root = write_dataset(Path(tmp) / "data", fabrics=100, depth=4, color=4, touch=2)
        ckpt = write_checkpoint(Path(tmp) / "compact.pt", COMPACT, SIZE)
        build_library(ckpt, root, Path(tmp) / "lib")
        queries = [
            ("depth", [("d.png", (root / "depth/F0007_1.png").read_bytes())]),
            ("color", [("c.jpg", (root / "color/F0042_2.jpg").read_bytes())]),
            (
                "touch",
                [
                    (f"t{p}.jpg", (root / f"touch/F0077_fold_1_{p}.jpg").read_bytes())
                    for p in (0, 1)
                ],
            ),
        ]
        with serving(Path(tmp) / "lib") as (url, _):
            one = _one_client(url, queries)
            result = _load(url, queries)
    return {
        "one_client_ms": one,
        "clients": CLIENTS,
        "duration_s": SECONDS,
        "max_requests": MAX_REQUESTS,
        "library": {"fabrics": 100, "items": 1000, "model": {**COMPACT, "image_size": SIZE}},
        "server": "lookfeel serve --host 127.0.0.1 (threads 1, max concurrency 2)",
        **result,
        "targets": {"failed": TARGET_FAILED, "clients": CLIENTS, "seconds": SECONDS},
        "met": result["failed"] == TARGET_FAILED and result["requests"] > 0,
    }
