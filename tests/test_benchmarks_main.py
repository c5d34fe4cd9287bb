"""benchmarks/__main__.py: every result names the date and machine it was measured on, its GPU
too; a bad --data is one error; a skipped benchmark never replaces a stored measurement."""

from __future__ import annotations

import json
import re
import time
from pathlib import Path

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


X86 = "processor\t: 0\ncpu family\t: 25\nmodel name\t: AMD EPYC 7B13\nflags\t\t: fpu avx2 avx512f\n"


@pytest.mark.parametrize(
    ("cpuinfo", "model"),
    [
        (X86, "AMD EPYC 7B13"),
        (
            "processor\t: 0\nProcessor\t: ARMv7 Processor rev 4 (v7l)\n",
            "ARMv7 Processor rev 4 (v7l)",
        ),
        (
            "processor\t: 0\ncpu\t\t: POWER9 (raw), altivec supported\n",
            "POWER9 (raw), altivec supported",
        ),
        ("processor\t: 0\ncpu family\t: 6\ncpu MHz\t\t: 2000\n", None),
    ],
)
def test_the_cpu_model_is_read_by_its_exact_key(cpuinfo: str, model: str | None) -> None:
    assert benchmarks._cpu_model(cpuinfo) == model


def test_every_new_result_names_its_date_and_cpu(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(benchmarks, "_cpuinfo", lambda: X86)
    result = benchmarks.stamp("x", time.time(), {"met": True})
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d[+-]\d{4}", str(result["when"]))
    assert result["machine"]["cpu_model"] == "AMD EPYC 7B13"
    assert result["machine"]["cpu_vectors"] == "avx512"


def test_a_cv_scored_result_names_its_date_and_cpu(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    from benchmarks.bench_depth_position import write_result

    monkeypatch.setattr(benchmarks, "_cpuinfo", lambda: X86)
    out = tmp_path / "swap.json"
    write_result({"runs": []}, out, "bench_depth_swap", ["--cv", "x"])
    stored = json.loads(out.read_text(encoding="utf-8"))
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT.*", stored["when"])
    assert stored["machine"]["cpu_model"] == "AMD EPYC 7B13"
    assert stored["command"] == "python -m benchmarks.bench_depth_swap --cv x"


def _stored(folder: Path) -> Path:
    """A stored decode_depth measurement in ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "decode_depth.json"
    stored = {
        "benchmark": "decode_depth",
        "when": "2026-12-07T12:40:49+0000",
        "machine": {"processor": "x86_64", "cpu_model": "AMD EPYC", "cpu_vectors": "avx512"},
        "median_s": 1.872,
        "met": True,
    }
    path.write_text(json.dumps(stored, indent=2) + "\n", encoding="utf-8")
    return path


def test_a_missing_data_folder_is_one_error_before_anything_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _stored(tmp_path / "out")
    before = path.read_text(encoding="utf-8")
    missing = tmp_path / "nonexistent"
    argv = ["--data", str(missing), "--only", "decode_depth", "--out", str(tmp_path / "out")]
    with pytest.raises(SystemExit) as exit_:
        benchmarks.main(argv)
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert f"--data {missing}: no such folder" in err
    assert "Traceback" not in err
    assert path.read_text(encoding="utf-8") == before
    a_file = tmp_path / "file"
    a_file.write_text("", encoding="utf-8")
    with pytest.raises(SystemExit) as exit_:
        benchmarks.main(["--data", str(a_file), "--only", "decode_depth", "--out", str(tmp_path)])
    assert exit_.value.code == 2
    assert "is not a folder" in capsys.readouterr().err


def test_a_skip_keeps_the_stored_measurement(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _stored(tmp_path)
    before = path.read_text(encoding="utf-8")
    assert benchmarks.main(["--only", "decode_depth", "--out", str(tmp_path)]) == 0
    assert path.read_text(encoding="utf-8") == before
    out = capsys.readouterr().out
    assert (
        f"kept the stored result of 2026-12-07 AMD EPYC (avx512) in {path}: skipped here "
        "because real GelFabric data not found (pass --data)"
    ) in out


def test_a_skip_is_written_where_no_measurement_is_stored(tmp_path: Path) -> None:
    assert benchmarks.main(["--only", "decode_depth", "--out", str(tmp_path)]) == 0
    written = json.loads((tmp_path / "decode_depth.json").read_text(encoding="utf-8"))
    assert written["skipped"].startswith("real GelFabric data not found")
    assert written["when"] and "cpu_model" in written["machine"]
    # a later skip replaces an earlier skip: there is no measurement to keep
    assert benchmarks.kept_stored(tmp_path / "decode_depth.json", written) is None


def test_a_standalone_skip_keeps_the_stored_measurement(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _stored(tmp_path)
    before = path.read_text(encoding="utf-8")
    skipped = {"skipped": "needs the real GelFabric depth (--data)"}
    assert benchmarks.write_standalone("decode_depth", time.time(), skipped, path) == 0
    assert path.read_text(encoding="utf-8") == before
    assert "kept the stored result of 2026-12-07" in capsys.readouterr().out
    measured = {"median_s": 2.0, "met": True}
    assert benchmarks.write_standalone("decode_depth", time.time(), measured, path) == 0
    assert json.loads(path.read_text(encoding="utf-8"))["median_s"] == 2.0


def test_a_result_whose_every_part_skipped_is_a_skip() -> None:
    none = {
        "recipes": {"real_depth": {"skipped": "no data at a"}, "physiclear": {"skipped": "b"}},
        "met": None,
    }
    assert benchmarks.skip_reason(none) == "real_depth: no data at a; physiclear: b"
    some = {
        "recipes": {"real_depth": {"skipped": "no data at a"}, "physiclear": {"median_s": 71}},
        "met": True,
    }
    assert benchmarks.skip_reason(some) is None
    assert benchmarks.skip_reason({"median_s": 1.0, "met": None, "machine": {"cpus": 2}}) is None


def test_out_is_described_in_the_help(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        benchmarks.main(["--help"])
    help_ = " ".join(capsys.readouterr().out.split())
    assert "the folder results are written to" in help_
    assert "default benchmarks/results/" in help_
