"""Devices: a device torch does not know, or that this PyTorch or machine lacks, is refused in
one line naming it (`lookfeel.devices.resolve_device`), by the library and the CLI alike."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from lookfeel.checkpoint import load_model
from lookfeel.cli import main
from lookfeel.devices import DeviceError, resolve_device


@pytest.fixture
def cpu_build(monkeypatch: pytest.MonkeyPatch) -> None:
    """This PyTorch as a CPU build, whatever the machine's."""
    monkeypatch.setattr(torch.version, "cuda", None)
    monkeypatch.setattr(torch.version, "hip", None)


@pytest.fixture
def cuda_build(monkeypatch: pytest.MonkeyPatch) -> None:
    """This PyTorch as a CUDA 12.4 build on a machine with one GPU (nothing runs on it)."""
    monkeypatch.setattr(torch.version, "cuda", "12.4")
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 1)


def test_the_cpu_and_auto_resolve():
    assert resolve_device("cpu") == resolve_device(torch.device("cpu")) == torch.device("cpu")
    assert resolve_device("auto").type == ("cuda" if torch.cuda.is_available() else "cpu")


def test_cuda_on_a_cpu_build_is_one_line(cpu_build: None):
    """QA: `load_model(p, device="cuda")` raised torch's `AssertionError: Torch not compiled
    with CUDA enabled`."""
    for name in ("cuda", torch.device("cuda", 1)):
        with pytest.raises(DeviceError) as e:
            resolve_device(name)
        assert str(e.value) == (
            f"device {str(name)!r}: this PyTorch has no CUDA (torch {torch.__version__}, CPU "
            "build); use cpu, or install a CUDA build of PyTorch"
        )
    with pytest.raises(DeviceError, match=r"^train\.device 'cuda': this PyTorch has no CUDA"):
        resolve_device("cuda", "train.device")


def test_a_name_torch_does_not_know_is_one_line():
    """QA: ``device="tpu"`` raised torch's RuntimeError from deep in loading."""
    with pytest.raises(DeviceError, match=r"^device 'tpu': not a device torch knows: Expected "):
        resolve_device("tpu")
    for bad in ("cuda:x", "", "CPU"):
        with pytest.raises(DeviceError, match=rf"^device {bad!r}: not a device torch knows"):
            resolve_device(bad)


def test_cuda_the_machine_lacks(cuda_build: None, monkeypatch: pytest.MonkeyPatch):
    assert resolve_device("cuda:0") == torch.device("cuda:0")
    with pytest.raises(DeviceError, match=r"^device 'cuda:2': this machine has 1 CUDA device "
                       r"\(cuda:0\)$"):  # fmt: skip
        resolve_device("cuda:2")
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    with pytest.raises(DeviceError, match=r"^device 'cuda': no CUDA device is visible \(torch "
                       r".+, built for CUDA 12\.4\); check the driver"):  # fmt: skip
        resolve_device("cuda")


def test_another_accelerator_this_pytorch_lacks(monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setattr(torch.backends.mps, "is_available", lambda: False)
    with pytest.raises(DeviceError, match=r"^device 'mps': this PyTorch or machine has no MPS"):
        resolve_device("mps")
    if not torch.xpu.is_available():
        with pytest.raises(DeviceError, match=r"^device 'xpu': this PyTorch cannot use it"):
            resolve_device("xpu")


def test_apples_gpu_is_refused_even_where_the_machine_has_it(
    run: tuple[Path, Path],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture,
):
    """QA (portability): ``--device mps`` was accepted on a Mac, then training and embedding
    ended in torch's traceback (float64 sums, which MPS lacks)."""
    monkeypatch.setattr(torch.backends.mps, "is_available", lambda: True)
    for name in ("mps", "mps:0", torch.device("mps")):
        with pytest.raises(DeviceError) as e:
            resolve_device(name)
        assert str(e.value) == (
            f"device {str(name)!r}: Apple's GPU (MPS) is not supported yet (training and "
            "embedding sum in float64, which MPS lacks); use cpu"
        )
    with pytest.raises(DeviceError, match=r"^train\.device 'mps': Apple's GPU \(MPS\) is not"):
        resolve_device("mps", "train.device")
    data, checkpoint = run
    with pytest.raises(DeviceError, match="^device 'mps': Apple's GPU"):
        load_model(checkpoint, device="mps")
    args = ["--checkpoint", str(checkpoint), "--data", str(data), "--out", str(tmp_path / "e.npz")]
    assert main(["embed", *args, "--device", "mps"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("lookfeel: device 'mps': Apple's GPU") and err.count("\n") == 1
    assert not (tmp_path / "e.npz").exists()


def test_loading_and_evaluating_on_a_missing_device_is_one_line(
    run: tuple[Path, Path], tmp_path: Path, cpu_build: None, capsys: pytest.CaptureFixture
):
    """`load_model` (which `Matcher` and `evaluate_checkpoint` load through) checks the device
    first; ``lookfeel evaluate --device cuda`` ended in a traceback (QA)."""
    data, checkpoint = run
    with pytest.raises(DeviceError, match="^device 'cuda': this PyTorch has no CUDA"):
        load_model(checkpoint, device="cuda")
    with pytest.raises(DeviceError, match="^device 'tpu': not a device torch knows"):
        load_model(checkpoint, device="tpu")
    assert load_model(checkpoint, device="auto").model.embed_dim > 0  # the CPU here
    for device in ("cuda", "tpu"):
        args = ["--checkpoint", str(checkpoint), "--data", str(data), "--out", str(tmp_path)]
        assert main(["evaluate", *args, "--device", device]) == 1
        err = capsys.readouterr().err
        assert err.startswith(f"lookfeel: device '{device}': ") and err.count("\n") == 1
