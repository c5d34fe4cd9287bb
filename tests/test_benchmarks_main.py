"""benchmarks/__main__.py: every result names the machine it was measured on, its GPU too."""

from __future__ import annotations

import time

import pytest
import torch
from benchmarks import __main__ as benchmarks


def test_a_result_names_the_gpu_it_ran_on(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "get_device_name", lambda index=None: "NVIDIA H200")
    result = benchmarks.stamp("x", time.time(), {"met": True})
    assert result["benchmark"] == "x" and result["met"] is True
    assert result["machine"]["gpu"] == "NVIDIA H200"
    assert result["machine"]["torch"] == torch.__version__


def test_without_cuda_the_gpu_is_none(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    assert benchmarks.machine()["gpu"] is None


@pytest.mark.parametrize(
    ("flags", "vectors"),
    [
        ("fpu sse2 avx2 avx512f avx512bw", "avx512"),
        ("fpu sse2 avx avx2", "avx2"),
        ("fpu sse2", None),
    ],
)
def test_the_cpu_is_named_by_its_widest_vectors(flags: str, vectors: str | None) -> None:
    cpuinfo = f"processor\t: 0\nmodel name\t: AMD EPYC\nflags\t\t: {flags}\n"
    assert benchmarks._cpu_vectors(cpuinfo) == vectors
    assert benchmarks._cpu_vectors("model name : no flags line") is None
