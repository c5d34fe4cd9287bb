"""What a command's ``--out`` may name: never a path inside the ``--data`` dataset, never a file
the command did not write, never a folder holding something other than the command's own output
(a QA pass found ``embed --out rig/labels.csv`` replacing the user's labels with an ``.npz``, and
``train --out rig`` writing a run into the dataset). Each refusal is one line, exit 1, said
before any work: the tests replace the work itself with `_Worked`, so a command that got past
its checks fails the test at once instead of training or embedding.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from lookfeel.cli import main

from ._tiny import write_rgb
from .conftest import tree_digest


class _Worked(Exception):
    """Raised by the stand-in for a command's work: the command got past its ``--out`` checks."""


WORK = [
    ("lookfeel.evaluate", "embed_checkpoint"),
    ("lookfeel.evaluate", "evaluate_checkpoint"),
    ("lookfeel.evaluate", "evaluate_embedding_file"),
    ("lookfeel.train", "train"),
    ("lookfeel.crossval", "cross_validate"),
    ("lookfeel.reproduce", "reproduce"),
    ("lookfeel.export", "export_onnx"),
    ("lookfeel.index", "build_library"),
]
"""The functions that do each command's work (embed, evaluate, train, cv, reproduce, export)."""


@pytest.fixture
def no_work(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every command's work raises `_Worked` (the commands import it when they run).

    Every lookfeel module is imported first: one imported for the first time while the work
    is replaced (``lookfeel.crossval.run``'s ``from lookfeel.train import train``) would keep
    the stand-in after the test, and a later test in the process would run it."""
    import importlib
    import pkgutil

    import lookfeel

    for info in pkgutil.walk_packages(lookfeel.__path__, "lookfeel."):
        if not info.name.endswith(".__main__"):  # that one runs the CLI
            importlib.import_module(info.name)

    def worked(*args: object, **kwargs: object) -> None:
        raise _Worked

    for module, name in WORK:
        monkeypatch.setattr(importlib.import_module(module), name, worked)


def _refused(capsys: pytest.CaptureFixture[str], argv: list[object], *said: str) -> str:
    """Run the CLI: exit 1 with one ``lookfeel: `` line on stderr holding ``said``."""
    assert main([str(a) for a in argv]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("lookfeel: --out "), err
    for text in said:
        assert text in err, err
    return err


def _commands(data: Path, out: Path) -> dict[str, list[object]]:
    """Each command that writes ``--out``, reading ``data`` where it takes a dataset."""
    return {
        "embed": ["embed", "--checkpoint", "c.pt", "--data", data, "--out", out],
        "train": ["train", "--data", data, "--out", out],
        "train --resume": ["train", "--data", data, "--out", out, "--resume"],
        "cv": ["cv", "--data", data, "--out", out],
        "reproduce": ["reproduce", "--data", data, "--out", out],
        "evaluate": ["evaluate", "--checkpoint", "c.pt", "--data", data, "--out", out],
        "evaluate --embeddings": [
            "evaluate",
            "--embeddings",
            "e.npz",
            "--data",
            data,
            "--out",
            out,
        ],
        "export": ["export", "--checkpoint", "c.pt", "--out", out],
        "index build": ["index", "build", "--checkpoint", "c.pt", "--data", data, "--out", out],
    }


INSIDE = [
    ("embed", "labels.csv"),
    ("embed", "color/F0001_1.png"),
    ("embed", "e.npz"),
    ("embed", "color/e.npz"),
    ("train", "."),
    ("train", "run"),
    ("train --resume", "."),
    ("cv", "cv"),
    ("reproduce", "."),
    ("evaluate", "."),
    ("evaluate", "eval"),
    ("evaluate --embeddings", "color"),
    ("index build", "lib"),
]


@pytest.mark.parametrize(("command", "inside"), INSIDE, ids=lambda v: str(v))
def test_an_out_inside_the_dataset_is_refused_before_any_work(
    command: str, inside: str, tiny_dataset: Path, no_work: None, capsys
):
    before = tree_digest(tiny_dataset)
    out = tiny_dataset / inside
    existed = out.exists()
    argv = _commands(tiny_dataset, out)[command]
    _refused(capsys, argv, f"--out {out} lies inside the dataset folder {tiny_dataset} (--data)")
    assert tree_digest(tiny_dataset) == before
    assert out.exists() == existed


def test_an_out_inside_the_dataset_through_a_link_is_refused(
    tiny_dataset: Path, tmp_path: Path, no_work: None, capsys
):
    link = tmp_path / "link"
    link.symlink_to(tiny_dataset / "color")
    argv = _commands(tiny_dataset, link / "run")["train"]
    _refused(capsys, argv, "lies inside the dataset folder")


def _photo(path: Path) -> Path:
    write_rgb(path, 1, 0)
    return path


@pytest.mark.parametrize("name", ["labels.csv", "photo.jpg", "mine.npz", "e"])
def test_embed_keeps_a_file_it_did_not_write(
    name: str, tiny_dataset: Path, tmp_path: Path, no_work: None, capsys
):
    """Outside the dataset too: a user's CSV, photo or own archive (a zip without lookfeel's
    keys) is kept, with another name suggested."""
    mine = tmp_path / "mine" / name
    mine.parent.mkdir()
    if name == "photo.jpg":
        _photo(mine)
    elif name == "mine.npz":
        np.savez(mine, x=np.arange(3))
    else:
        mine.write_text("fabric_id,thickness_mm\n1,0.5\n", encoding="utf-8")
    before = mine.read_bytes()
    argv = _commands(tiny_dataset, mine)["embed"]
    other = (
        mine.with_name("mine-embeddings.npz") if name == "mine.npz" else mine.with_suffix(".npz")
    )
    _refused(
        capsys,
        argv,
        f"--out {mine}: the file exists and is not an embeddings file lookfeel wrote",
        f"it is kept: choose another --out, e.g. {other}",
    )
    assert mine.read_bytes() == before


def test_embed_out_must_end_in_npz(tiny_dataset: Path, tmp_path: Path, no_work: None, capsys):
    out = tmp_path / "e.csv"
    argv = _commands(tiny_dataset, out)["embed"]
    _refused(capsys, argv, f"an embeddings file is an .npz archive; name it so, e.g. {tmp_path}")
    assert not out.exists()


def test_embed_replaces_the_embeddings_file_it_wrote(run: tuple[Path, Path], tmp_path: Path):
    """A rerun over lookfeel's own output works: the file is replaced, not refused."""
    data, ckpt = run
    out = tmp_path / "e.npz"
    argv = ["embed", "--checkpoint", str(ckpt), "--data", str(data), "--out", str(out)]
    for split in ("train", "all"):
        assert main([*argv, "--split", split]) == 0
        with np.load(out) as z:
            assert json.loads(str(z["meta"]))["split"] == split  # this run's file


OWN = {
    "train": "split.json",  # not config.yaml alone: that may be the user's own --config
    "train --resume": "checkpoints",
    "cv": "seed0-fold0",
    "reproduce": "results.json",
    "evaluate": "metrics.json",
    "evaluate --embeddings": "metrics.json",
    "export": "export.json",
}
"""A name each folder command writes in its --out: a folder holding it is its own, to rerun."""


@pytest.mark.parametrize("command", sorted(OWN))
def test_a_folder_holding_something_else_is_refused_and_its_own_kept(
    command: str, tiny_dataset: Path, tmp_path: Path, no_work: None, capsys
):
    """A non-empty --out folder must hold the command's own output (as `index build` refuses a
    folder that is not a library): a run to resume, a report to write again."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine\n", encoding="utf-8")
    (out / ".hidden").write_text("", encoding="utf-8")
    argv = _commands(tiny_dataset, out)[command]
    _refused(capsys, argv, f"--out {out}: the folder holds files and is not ", "choose a new")
    assert sorted(p.name for p in out.iterdir()) == [".hidden", "notes.txt"]
    own = out / OWN[command]
    if "." in own.name:
        own.write_text("{}\n", encoding="utf-8")
    else:
        own.mkdir()
    with pytest.raises(_Worked):
        main([str(a) for a in argv])
    (out / "notes.txt").unlink()
    own.unlink() if own.is_file() else own.rmdir()
    with pytest.raises(_Worked):  # a folder holding only a temp file of an atomic write
        main([str(a) for a in argv])


FOLDER_COMMANDS = [c for c in _commands(Path("d"), Path("o")) if c != "embed"]
"""The commands whose --out is a folder (every one but embed's, a file)."""


@pytest.mark.parametrize("command", [*FOLDER_COMMANDS, "demo"])
def test_an_out_a_folder_command_cannot_write_is_exit_1_in_one_line(
    command: str, tiny_dataset: Path, tmp_path: Path, no_work: None, capsys
):
    """QA: ``train --out notes.txt`` (an existing file) and an --out below a file exited 2
    with argparse's usage, where README says an --out a command cannot write in is one line,
    exit 1, as every other path problem is."""
    notes = tmp_path / "notes.txt"
    notes.write_text("mine\n", encoding="utf-8")
    for out, said in (
        (notes, f"--out {notes} exists and is not a folder; this command writes a folder"),
        (notes / "run", f"--out {notes / 'run'}: {notes} is a file, not a folder to write in"),
    ):
        argv = (
            ["demo", "--out", out] if command == "demo" else _commands(tiny_dataset, out)[command]
        )
        _refused(capsys, argv, said)
    assert notes.read_text(encoding="utf-8") == "mine\n"


def test_an_embed_out_that_is_a_folder_is_exit_1_in_one_line(
    tiny_dataset: Path, tmp_path: Path, no_work: None, capsys
):
    argv = _commands(tiny_dataset, tmp_path)["embed"]
    _refused(capsys, argv, f"--out {tmp_path} is a folder; name the file to write (e.g. ")
