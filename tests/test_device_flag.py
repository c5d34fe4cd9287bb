"""``--device``, where the network runs, is one flag with one definition on every command that
runs a trained model (embed, evaluate, predict, index build, match, serve; export runs on the
CPU: `lookfeel.export` says why), and reaches the model. A device torch does not know, or one
this machine lacks, is the one line ``predict`` gives, exit 1, before any work."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import pytest
import torch

from lookfeel.cli import build_parser, main
from lookfeel.devices import DeviceError
from lookfeel.index import Library, build_library
from lookfeel.serve import ServeConfig, background_server, create_app

from ._library import tiny_library

RUN_A_MODEL = [("embed",), ("evaluate",), ("predict",), ("index", "build"), ("match",), ("serve",)]
"""The commands (and actions) that run a trained model where ``--device`` says."""

DEPTH = "depth/F0003_Depth_New_000001.png"
"""A depth image of the tiny dataset (`tests._tiny`), of fabric 3."""


@pytest.fixture(scope="module")
def library(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tiny_library(tmp_path_factory, "device", shard_size=64)


@pytest.fixture(params=["cpu build", "no gpu"])
def no_cuda(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> None:
    """This machine without CUDA, whatever it has: a CPU build of PyTorch, or a CUDA build on a
    machine whose GPU is not visible."""
    monkeypatch.setattr(torch.version, "cuda", None if request.param == "cpu build" else "12.4")
    monkeypatch.setattr(torch.version, "hip", None)
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)


@pytest.fixture
def devices(monkeypatch: pytest.MonkeyPatch) -> list[torch.device]:
    """The device each model is loaded on, in order (index build's, and a library's)."""
    import lookfeel.index.build
    import lookfeel.index.library

    seen: list[torch.device] = []
    for module in (lookfeel.index.build, lookfeel.index.library):
        real = module.load_model

        def spy(path: Any, device: Any = "cpu", real: Callable[..., Any] = real) -> Any:
            seen.append(device)
            return real(path, device)

        monkeypatch.setattr(module, "load_model", spy)
    return seen


def _option(path: tuple[str, ...], flag: str) -> argparse.Action | None:
    """The option ``flag`` of the command ``path`` (``("index", "build")``), None if it has none."""
    parser: argparse.ArgumentParser = build_parser()
    for name in path:
        [sub] = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
        parser = sub.choices[name]
    return next((a for a in parser._actions if flag in a.option_strings), None)


def _fake_serve(monkeypatch: pytest.MonkeyPatch) -> dict[str, Any]:
    """Make `lookfeel serve` return at once with its app (the real server blocks)."""
    served: dict[str, Any] = {}

    def fake_serve(app: Any, host: str, port: int, on_bound: Callable[[str], None]) -> None:
        served.update(app=app)
        on_bound(f"http://{host}:{port}/")

    monkeypatch.setattr("lookfeel.serve.serve", fake_serve)
    return served


def test_every_command_that_runs_a_model_takes_the_same_device_flag():
    want = _option(("embed",), "--device")
    assert want is not None and want.default == "cpu"
    for path in RUN_A_MODEL:
        got = _option(path, "--device")
        assert got is not None, f"lookfeel {' '.join(path)} has no --device"
        fields = ("default", "help", "type", "nargs", "choices", "required", "metavar", "dest")
        assert {f: getattr(got, f) for f in fields} == {f: getattr(want, f) for f in fields}, path
    assert _option(("export",), "--device") is None  # on the CPU: lookfeel.export says why


def test_index_build_on_the_cpu(
    run: tuple[Path, Path], tmp_path: Path, devices: list[torch.device], capsys
):
    data, ckpt = run
    out = tmp_path / "lib"
    args = ["index", "build", "--checkpoint", str(ckpt), "--data", str(data), "--out", str(out)]
    assert main([*args, "--shard-size", "64", "--quiet", "--device", "cpu"]) == 0
    assert capsys.readouterr().out.startswith(f"Library {out}: ")
    assert devices == [torch.device("cpu")]
    assert Library.open(out).summary()["fabrics"] == 6


def test_match_on_the_cpu(run: tuple[Path, Path], library: Path, devices: list, capsys):
    data, _ = run
    args = ["match", "--index", str(library), "--modality", "depth", str(data / DEPTH)]
    assert main([*args, "--top", "2", "--device", "cpu"]) == 0
    out = capsys.readouterr().out
    assert DEPTH.rsplit("/")[-1] in out and "fabric 3" in out
    assert devices == [torch.device("cpu")]


def test_serve_on_the_cpu(
    run: tuple[Path, Path], library: Path, devices: list, monkeypatch: pytest.MonkeyPatch, capsys
):
    data, _ = run
    served = _fake_serve(monkeypatch)
    assert main(["serve", "--index", str(library), "--port", "8124", "--device", "cpu"]) == 0
    assert "Serving" in capsys.readouterr().out
    assert devices == [torch.device("cpu")]
    with background_server(served["app"]) as url:
        r = httpx.post(
            url + "/api/match",
            data={"modality": "depth", "top": "2"},
            files=[("files", ("q.png", (data / DEPTH).read_bytes(), "image/png"))],
        )
    assert r.status_code == 200, r.text
    assert r.json()["results"][0]["fabrics"][0]["fabric_id"] == 3


def test_a_rebuilt_library_served_is_matched_on_the_same_device(
    library: Path, monkeypatch: pytest.MonkeyPatch
):
    """`create_app` gives the device to the matcher of the library it opens, and of each one
    rebuilt under it (`lookfeel.serve.reload.ServedLibrary`'s ``make_matcher``)."""
    import lookfeel.serve.app

    made: dict[str, Any] = {}

    class Recorded(lookfeel.serve.app.ServedLibrary):
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            made.update(kwargs)
            super().__init__(*args, **kwargs)

    monkeypatch.setattr(lookfeel.serve.app, "ServedLibrary", Recorded)
    create_app(Library.open(library), ServeConfig(reload_every=0), device="cpu")
    assert made["make_matcher"](Library.open(library)).device == torch.device("cpu")
    with pytest.raises(DeviceError, match="^device 'tpu': not a device torch knows"):
        create_app(library.parent / "no-library", device="tpu")  # before it is opened


def test_index_build_refuses_a_device_torch_does_not_know_before_any_work(
    run: tuple[Path, Path], tmp_path: Path, capsys
):
    """Without the check first, the library's lock file and the folder above it were made
    before the model was loaded on the device."""
    data, ckpt = run
    out = tmp_path / "new" / "lib"
    args = ["index", "build", "--checkpoint", str(ckpt), "--data", str(data), "--out", str(out)]
    assert main([*args, "--device", "tpu"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("lookfeel: device 'tpu': not a device torch knows: ")
    assert err.count("\n") == 1
    with pytest.raises(DeviceError, match="^device 'tpu': not a device torch knows"):
        build_library(ckpt, data, out, device="tpu")
    assert not (tmp_path / "new").exists()


@pytest.mark.parametrize("device", ["tpu", "cuda", "mps"])
def test_a_device_this_machine_lacks_is_the_line_predict_gives(
    run: tuple[Path, Path],
    library: Path,
    tmp_path: Path,
    device: str,
    no_cuda: None,
    monkeypatch: pytest.MonkeyPatch,
    capsys,
):
    data, ckpt = run
    # An Apple GPU there: lookfeel does not support it (`lookfeel.devices`), and says so.
    monkeypatch.setattr(torch.backends.mps, "is_available", lambda: True)
    served = _fake_serve(monkeypatch)  # never blocks, should serve start
    query = str(data / DEPTH)
    assert main(["predict", query, "--checkpoint", str(ckpt), "--device", device]) == 1
    said = capsys.readouterr()
    assert said.err.startswith(f"lookfeel: device '{device}': ") and said.err.count("\n") == 1
    out = tmp_path / "lib"
    build = ["index", "build", "--checkpoint", str(ckpt), "--data", str(data), "--out", str(out)]
    missing = str(tmp_path / "no-library")  # the device is said first
    commands = {
        "index build": build,
        "match": ["match", "--index", str(library), query],
        "match (no library)": ["match", "--index", missing, query],
        "serve": ["serve", "--index", str(library)],
        "serve (no library)": ["serve", "--index", missing],
    }
    for name, args in commands.items():
        assert main([*args, "--device", device]) == 1, name
        assert capsys.readouterr() == ("", said.err), name
    assert not served and not out.exists() and not (tmp_path / "lib.lock").exists()
