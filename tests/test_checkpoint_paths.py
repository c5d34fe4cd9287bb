"""A training run's folder given where a checkpoint is asked for stands for its
``checkpoints/last.pt`` (`lookfeel.checkpoint.checkpoint_file`): in the Python API and every
command's ``--checkpoint``; a folder without one is one line saying what to give.

QA: ``lookfeel embed --checkpoint runs/a`` (and export, predict, evaluate) said "runs/a:
checkpoint not found" of a run folder that exists.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import torch

from lookfeel.checkpoint import CheckpointError, init_from_checkpoint, load_model, read_checkpoint
from lookfeel.cli import main
from lookfeel.config import RunConfig, load_config
from lookfeel.models import create_model
from lookfeel.train import train

from ._library import TINY

pytestmark = pytest.mark.filterwarnings("ignore:.*probabilities are as trained, not calibrated")

NO_LAST = (
    ": a folder with no checkpoints/last.pt: give a checkpoint file (a run's "
    "checkpoints/last.pt or best.pt)"
)


@pytest.fixture(autouse=True)
def _threads() -> Iterator[None]:
    n = torch.get_num_threads()
    yield
    torch.set_num_threads(n)


@pytest.fixture(scope="module")
def ensemble(run, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run folder of `run`'s dataset: a merged ensemble of two tiny members with a class head
    (what ``lookfeel predict`` reads), a few steps each."""
    data, _ = run
    sets = ["model.members=2", "model.class_heads=[stretchiness]", "train.steps=2"]
    sets += ["train.split=none", "train.val_every=0", "train.checkpoint_every=0"]
    config = load_config(RunConfig, TINY, sets)
    torch.set_num_threads(1)  # as `tests._library.tiny_run`: faster on a shared CPU
    out = tmp_path_factory.mktemp("ensemble") / "run"
    train(config, data, out)
    return out


def test_a_run_folder_stands_for_its_last_checkpoint_in_the_python_api(run):
    from lookfeel.checkpoint import checkpoint_file

    _, last = run
    folder = last.parent.parent
    assert checkpoint_file(folder) == last
    assert checkpoint_file(last) == last  # a file is itself
    assert read_checkpoint(folder)["step"] == read_checkpoint(last)["step"]
    loaded = load_model(folder)
    assert loaded.path == last  # the file, as evaluate and embed record it
    config = loaded.config
    fresh = create_model(config.model, list(loaded.model.modalities), load_weights=False)
    assert init_from_checkpoint(fresh, folder) == []  # model.init_from: another run's folder


def test_a_merged_ensemble_run_folder_loads_its_merged_model(ensemble: Path):
    loaded = load_model(ensemble)
    assert loaded.path == ensemble / "checkpoints" / "last.pt"
    assert loaded.config.model.members == 2  # the merged model, not member 0's


@pytest.mark.parametrize("inside", ["nothing", "checkpoints/best.pt only", "last.pt at its top"])
def test_a_folder_without_checkpoints_last_pt_is_one_line(run, tmp_path: Path, inside: str):
    from lookfeel.checkpoint import checkpoint_file

    _, last = run
    folder = tmp_path / "runs" / "a"
    folder.mkdir(parents=True)
    if inside == "checkpoints/best.pt only":
        (folder / "checkpoints").mkdir()
        (folder / "checkpoints" / "best.pt").write_bytes(last.read_bytes())
    elif inside == "last.pt at its top":
        (folder / "last.pt").write_bytes(last.read_bytes())
    for read in (checkpoint_file, read_checkpoint, load_model):
        with pytest.raises(CheckpointError) as e:
            read(folder)
        assert str(e.value) == f"{folder}{NO_LAST}"


def test_every_command_takes_a_run_folder_and_records_the_file(
    run, ensemble: Path, tmp_path: Path, capsys
):
    data, last = run
    folder = last.parent.parent
    out = tmp_path / "out"
    code = main(["embed", "--checkpoint", str(folder), "--data", str(data), "--out", f"{out}.npz"])
    assert code == 0, capsys.readouterr().err
    with np.load(f"{out}.npz") as z:
        assert json.loads(str(z["meta"]))["checkpoint"] == str(last)
    code = main(["evaluate", "--checkpoint", str(folder), "--data", str(data), "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    assert f"| checkpoint | `{last}` (step 20) |" in (out / "report.md").read_text(encoding="utf-8")
    query = sorted((data / "color").glob("*.png"))[0]
    capsys.readouterr()
    assert main(["predict", "--checkpoint", str(ensemble), str(query), "--json"]) == 0
    answer = json.loads(capsys.readouterr().out)
    assert "stretchiness" in json.dumps(answer)
    assert main(["export", "--checkpoint", str(folder), "--out", str(tmp_path / "onnx")]) == 0
    assert (tmp_path / "onnx" / "color.onnx").is_file()


@pytest.mark.parametrize("command", ["embed", "evaluate", "predict", "export", "index build"])
def test_a_folder_without_a_checkpoint_is_one_line_in_every_command(
    run, tmp_path: Path, command: str, capsys
):
    data, _ = run
    folder = tmp_path / "runs" / "a"
    folder.mkdir(parents=True)
    out = str(tmp_path / "out")
    argv = {
        "embed": ["embed", "--data", str(data), "--out", f"{out}.npz"],
        "evaluate": ["evaluate", "--data", str(data), "--out", out],
        "predict": ["predict", str(sorted((data / "color").glob("*.png"))[0])],
        "export": ["export", "--out", out],
        "index build": ["index", "build", "--data", str(data), "--out", out],
    }[command]
    assert main([*argv, "--checkpoint", str(folder)]) == 1
    captured = capsys.readouterr()
    assert captured.err == f"lookfeel: {folder}{NO_LAST}\n"


def test_a_library_and_an_export_record_the_file_a_run_folder_stands_for(
    run, tmp_path: Path, capsys
):
    data, last = run
    folder = last.parent.parent
    lib = tmp_path / "lib"
    argv = ["index", "build", "--checkpoint", str(folder), "--data", str(data), "--out", str(lib)]
    code = main(argv)
    assert code == 0, capsys.readouterr().err
    manifest = json.loads((lib / "manifest.json").read_text(encoding="utf-8"))
    assert manifest["checkpoint"]["path"] == str(last.resolve())
    query = sorted((data / "color").glob("*.png"))[0]
    argv = ["match", "--index", str(lib), "--checkpoint", str(folder), "--modality", "color"]
    assert main([*argv, str(query)]) == 0, capsys.readouterr().err
    assert main(["export", "--checkpoint", str(folder), "--out", str(tmp_path / "onnx")]) == 0
    recorded = json.loads((tmp_path / "onnx" / "export.json").read_text(encoding="utf-8"))[
        "checkpoint"
    ]
    assert recorded == str(last.resolve())


def test_a_library_built_from_a_runs_best_checkpoint_opens_with_the_run_folder(
    run, tmp_path: Path, capsys
):
    """QA (upgrading): a library built from ``RUN/checkpoints/best.pt``, opened with
    ``--checkpoint RUN``, was refused as built from another checkpoint (the folder stood for
    ``last.pt``), and the message sent the user to rebuild it."""
    import shutil

    data, last = run
    folder = tmp_path / "run"
    shutil.copytree(last.parent.parent, folder)
    # best.pt and last.pt: two checkpoints of the run (last.pt re-saved, so other bytes)
    shutil.copy(last, folder / "checkpoints" / "best.pt")
    torch.save(
        {**torch.load(last, weights_only=False), "step": 1}, folder / "checkpoints" / "last.pt"
    )
    best = folder / "checkpoints" / "best.pt"
    lib = tmp_path / "lib"
    argv = ["index", "build", "--checkpoint", str(best), "--data", str(data), "--out", str(lib)]
    assert main(argv) == 0, capsys.readouterr().err
    query = sorted((data / "color").glob("*.png"))[0]
    argv = ["match", "--index", str(lib), "--checkpoint", str(folder), "--modality", "color"]
    assert main([*argv, str(query)]) == 0, capsys.readouterr().err
    # the last checkpoint, named, is another model: refused as before
    argv[argv.index(str(folder))] = str(folder / "checkpoints" / "last.pt")
    assert main([*argv, str(query)]) == 1
    assert "differs from the one the library was built with" in capsys.readouterr().err
