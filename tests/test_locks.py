"""One lookfeel process at a time per output (`lookfeel.locks`): QA ran two `train`, `synth` and
`reproduce` processes into one --out at once; both "succeeded" and left outputs made of both."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from lookfeel.cli import main
from lookfeel.locks import BusyError, exclusive, lock_path

from ._tiny import write_tiny_dataset

TINY = Path(__file__).resolve().parents[1] / "configs" / "tiny.yaml"


def _held_message(out: Path, command: str, what: str) -> str:
    return (
        f"lookfeel: {out}: another `lookfeel {command}` is writing {what} (PID {os.getpid()}, "
        f"lock {lock_path(out)}); wait for it to end, or stop it"
    )


def test_a_lock_refuses_a_second_holder_takes_over_a_dead_ones_and_keeps_a_users_file(
    tmp_path: Path,
):
    out = tmp_path / "runs" / "a"  # its folder need not exist yet
    with exclusive(out, "train", "this run"):
        assert lock_path(out).read_text(encoding="utf-8") == f"{os.getpid()}\n"
        busy = pytest.raises(BusyError, match=r"another `lookfeel train` is writing this run")
        with busy, exclusive(out, "train", "this run"):
            pass
    assert not lock_path(out).exists()  # gone with its holder
    lock_path(out).write_text(
        "99999\n", encoding="utf-8"
    )  # left by a killed process: not held, taken over
    with exclusive(out, "train", "this run"):
        pass
    assert not lock_path(out).exists()
    lock_path(out).write_text("my notes\n", encoding="utf-8")  # the user's own file of that name
    in_the_way = pytest.raises(BusyError, match=r"a.lock is in the way of the train's lock")
    with in_the_way, exclusive(out, "train", "this run"):
        pass
    assert lock_path(out).read_text(encoding="utf-8") == "my notes\n"
    assert lock_path(tmp_path / ".") == tmp_path.with_name(tmp_path.name + ".lock")


def test_train_synth_and_reproduce_refuse_an_output_another_process_is_writing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    data = write_tiny_dataset(tmp_path / "data", fabrics=6, drapes=3)
    cases = [
        (
            ["train", "--config", str(TINY), "--data", str(data), "--set", "train.steps=2"],
            "train",
            "this run",
        ),
        (["synth", "--fabrics", "3", "--size", "tiny", "--quiet"], "synth", "this world"),
        (["reproduce", "--data", str(data), "--budget", "tiny"], "reproduce", "this folder"),
    ]
    for argv, command, what in cases:
        out = tmp_path / f"out-{command}"
        full = [*argv, "--out", str(out)] if command != "synth" else [*argv, str(out)]
        with exclusive(out, command, what):  # as another process would hold it
            assert main(full) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert err == [_held_message(out, command, what)], command
        assert not out.exists() or not any(out.iterdir()), command  # nothing was written
    train_argv = [*cases[0][0], "--out", str(tmp_path / "out-train")]
    assert main(train_argv) == 0  # free again: it trains, and leaves no lock behind
    assert not lock_path(tmp_path / "out-train").exists()
