"""The command line as a script sees it: each flag's values and their refusals, the same flag
meaning the same in every command, usage errors on stderr with exit 2, and help that states
each default. A QA pass scripting lookfeel in a pipeline found ``--batch-size 0`` a traceback,
``--seeds 2`` one seed in ``cv`` but two in ``reproduce``, ``index build --folds 1`` silently
without an 'unknown' threshold, and errors naming Python parameters (``seeds must be >= 1``)
instead of flags. Most tests here parse arguments alone: nothing is trained or embedded.
"""

from __future__ import annotations

import argparse
import re
import shlex
import shutil
from pathlib import Path

import pytest

from lookfeel.cli import build_parser, main
from lookfeel.config import RunConfig, load_config
from lookfeel.config._core import parse_pairs
from lookfeel.modality import Modality, PressKind


def _usage_error(capsys: pytest.CaptureFixture[str], argv: list[str], said: str) -> list[str]:
    """Run the CLI: argparse's usage error (exit 2), its last line ending with ``said``; the
    lines of stderr."""
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert captured.out == "" and "Traceback" not in captured.err, captured
    assert err[0].startswith("usage: lookfeel "), err
    assert err[-1].startswith("lookfeel ") and err[-1].endswith(said), err
    return err


def _help(capsys: pytest.CaptureFixture[str], *words: str) -> str:
    """``lookfeel WORDS --help``, unwrapped into one line."""
    with pytest.raises(SystemExit) as e:
        main([*words, "--help"])
    assert e.value.code == 0
    return " ".join(capsys.readouterr().out.split())


# ---- 1. --batch-size: a positive integer wherever it is taken ---------------------------------


EMBEDDING = {
    "embed": ["embed", "--checkpoint", "c.pt", "--data", "d", "--out", "e.npz"],
    "evaluate": ["evaluate", "--checkpoint", "c.pt", "--data", "d", "--out", "ev"],
    "index build": ["index", "build", "--checkpoint", "c.pt", "--data", "d", "--out", "lib"],
}


@pytest.mark.parametrize("command", EMBEDDING)
@pytest.mark.parametrize("value", ["0", "-3"])
def test_batch_size_must_be_a_positive_integer_in_every_command(
    command: str, value: str, capsys: pytest.CaptureFixture[str]
):
    """QA: ``embed`` and ``evaluate --batch-size 0`` ended in a traceback
    (``range() arg 3 must not be zero``); ``index build`` in a line naming ``batch_size``."""
    argv = [*EMBEDDING[command], "--batch-size", value]
    _usage_error(capsys, argv, f"argument --batch-size: must be >= 1, got {value}")


# ---- 2. --seeds: a comma list of seeds in cv and reproduce alike ------------------------------


def _parsed(*argv: str) -> argparse.Namespace:
    return build_parser().parse_args(list(argv))


@pytest.mark.parametrize("command", ["cv", "reproduce"])
def test_seeds_are_the_same_comma_list_in_cv_and_reproduce(command: str, tmp_path: Path):
    """QA: ``--seeds 2`` trained seed 2 in ``cv`` but seeds 0 and 1 in ``reproduce``, and
    ``reproduce --seeds 0,1`` was a usage error: a pipeline passing one value to both ran
    different experiments. Both now take the seeds themselves, in the order given."""
    base = [command, "--data", "d", "--out", str(tmp_path / "o")]
    assert _parsed(*base).seeds == [0]
    assert _parsed(*base, "--seeds", "2").seeds == [2]
    assert _parsed(*base, "--seeds", "0,1").seeds == [0, 1]
    assert _parsed(*base, "--seeds", "3,1").seeds == [3, 1]


@pytest.mark.parametrize(
    ("value", "said"),
    [
        ("-1", "a seed must be an integer >= 0, got -1"),
        ("0,0", "seed 0 given more than once"),
        ("two", "'two' is not a comma-separated list of integers"),
        (",", "an empty list"),
    ],
)
@pytest.mark.parametrize("command", ["cv", "reproduce"])
def test_bad_seeds_are_usage_errors_in_cv_and_reproduce(
    command: str, value: str, said: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    argv = [command, "--data", "d", "--out", str(tmp_path / "o"), f"--seeds={value}"]
    _usage_error(capsys, argv, f"argument --seeds: {said}")
    assert not (tmp_path / "o").exists()


def test_reproduce_passes_the_seeds_it_was_given_and_says_so_in_its_help(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
):
    seen: dict[str, object] = {}

    def fake(data: Path, out: Path, **kwargs: object) -> None:
        seen.update(kwargs)
        raise KeyboardInterrupt  # stop before the report: what it was asked is all we need

    monkeypatch.setattr("lookfeel.reproduce.reproduce", fake)
    argv = ["reproduce", "--data", str(tmp_path / "d"), "--out", str(tmp_path / "o")]
    assert main([*argv, "--seeds", "2,0", "--only", "flat"]) == 130
    assert seen["seeds"] == [2, 0] and seen["only"] == ["flat"]
    capsys.readouterr()
    text = _help(capsys, "reproduce")
    assert "--seeds S,S training seeds of every experiment, integers >= 0, trained in this " in text
    assert "e.g. 0,1 (default 0), as cv --seeds" in text
    assert "DIR/runs/NAME/seed{S}" in text


# ---- 3. index build --folds below 2 is refused, as cv's ---------------------------------------


@pytest.mark.parametrize("folds", ["0", "1", "-1"])
def test_index_build_refuses_fewer_than_two_folds_as_cv_does(
    folds: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    """QA: ``index build --folds 0`` or ``1`` built a library without calibration's 'unknown'
    threshold (0, false accept nan), silently, while ``cv --folds 1`` is refused."""
    lib = tmp_path / "lib"
    argv = ["index", "build", "--checkpoint", "c.pt", "--data", "d", "--out", str(lib)]
    assert main([*argv, "--folds", folds]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"lookfeel: --folds {folds}: calibration needs at least 2 folds")
    assert err.count("\n") == 1 and not lib.exists()
    cv = ["cv", "--data", "d", "--out", str(tmp_path / "cv"), "--folds", folds]
    assert main(cv) == 1
    err = capsys.readouterr().err
    assert (
        err == f"lookfeel: --folds {folds} (train.folds): cross-validation needs at least 2 folds\n"
    )


# ---- 4. reproduce --only: names comma- or space-separated, at least one -----------------------


@pytest.mark.parametrize(
    ("given", "names"),
    [
        (["flat,auxiliary"], ["flat", "auxiliary"]),
        (["flat", "auxiliary"], ["flat", "auxiliary"]),
        (["flat,auxiliary", "multi_input"], ["flat", "auxiliary", "multi_input"]),
        (["flat,", "flat"], ["flat"]),
    ],
)
def test_reproduce_only_takes_names_comma_or_space_separated(
    given: list[str], names: list[str], tmp_path: Path
):
    """QA: ``--only`` was the one list flag taking space-separated names alone: ``--only
    flat,auxiliary`` was refused."""
    argv = ["reproduce", "--data", "d", "--out", str(tmp_path / "o"), "--only", *given]
    assert _parsed(*argv).only == names
    assert _parsed("reproduce", "--data", "d", "--out", str(tmp_path / "o")).only is None


@pytest.mark.parametrize(
    ("given", "said"),
    [
        ([], "argument --only: expected at least one argument"),
        (["flat,tables"], "argument --only: invalid choice: 'tables' (choose from 'flat', "),
    ],
)
def test_reproduce_only_refuses_no_name_and_an_unknown_one(
    given: list[str], said: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    """A bare ``--only`` meant every experiment, silently."""
    argv = ["reproduce", "--data", "d", "--out", str(tmp_path / "o"), "--only", *given]
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    assert said in capsys.readouterr().err.strip().splitlines()[-1]


# ---- 5. usage errors: on stderr, exit 2, a usage line and ``error:`` ---------------------------


def test_bare_lookfeel_is_a_usage_error_on_stderr_like_a_bare_group(
    capsys: pytest.CaptureFixture[str],
):
    """QA: a bare ``lookfeel`` printed its whole help to stdout (exit 2), where ``lookfeel
    data`` gives argparse's usage error on stderr."""
    with pytest.raises(SystemExit) as e:
        main(["data"])
    assert e.value.code == 2
    group = capsys.readouterr()
    assert group.out == "" and group.err.startswith("usage: lookfeel data ")
    assert main([]) == 2
    bare = capsys.readouterr()
    assert bare.out == ""
    err = bare.err.strip().splitlines()
    assert err[0] == "usage: lookfeel [-h] [--version] [--plugin MODULE] COMMAND ..."
    assert err[-1] == "lookfeel: error: the following arguments are required: COMMAND"
    assert any(re.match(r"  index build +embed a dataset", line) for line in err), err


def test_evaluate_options_that_go_together_are_usage_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    """QA: ``evaluate --checkpoint X`` without ``--data`` exited 2 with a line that had no
    usage and no ``error:``. Both such mistakes are argparse's usage errors now, before the
    report folder is made."""
    out = tmp_path / "ev"
    argv = ["evaluate", "--checkpoint", "c.pt", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0].startswith("usage: lookfeel evaluate ")
    assert err[-1] == "lookfeel evaluate: error: --checkpoint needs --data (the dataset it scores)"
    argv = ["evaluate", "--embeddings", "e.npz", "--split", "val", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0].startswith("usage: lookfeel evaluate ")
    assert err[-1].startswith("lookfeel evaluate: error: --split applies to --checkpoint")
    assert not out.exists()


# ---- 7. help: every default stated as "(default N)", the same words for the same meaning ------


def test_synth_and_reproduce_help_state_their_defaults(capsys: pytest.CaptureFixture[str]):
    synth = _help(capsys, "synth")
    seed = synth.partition("--seed SEED ")[2].partition(" --workers")[0]
    assert seed.startswith("world seed, an integer >= 0") and seed.endswith("(default 0)"), seed
    assert "--size SIZE image sizes (default net): net (depth 224" in synth
    reproduce = _help(capsys, "reproduce")
    assert "--n-boot N_BOOT bootstrap resamples (default 1000)" in reproduce
    # --workers 0 means the same in both, in the same words.
    assert "(default 0: one per core; 1: one after the other in this process)" in synth
    assert "(default 0: one per core on a CPU, 1 on CUDA; 1: one after the other in this " in (
        reproduce
    )


BARE_DEFAULT = re.compile(r"\((?:[0-9][0-9.,]*(?: MB)?)\)")
"""A default written bare, "(2048)" or "(8 MB)", not "(default 2048)"."""


@pytest.mark.parametrize(
    "words", [("index", "build"), ("serve",), ("synth",), ("reproduce",), ("cv",)], ids=" ".join
)
def test_defaults_are_written_default_n(words: tuple[str, ...], capsys: pytest.CaptureFixture[str]):
    """QA: ``(default 64)`` in some commands' help, a bare ``(2048)``, ``(5)``, ``(8000)`` in
    ``index build`` and ``serve``."""
    text = _help(capsys, *words)
    assert not BARE_DEFAULT.findall(text), BARE_DEFAULT.findall(text)


def test_index_build_and_serve_state_each_default(capsys: pytest.CaptureFixture[str]):
    build = _help(capsys, "index", "build")
    for said in (
        "items per shard (default 2048)",
        "leave-fabrics-out folds, at least 2 (default 5)",
        "calibration seed (default 0)",
        "held-out queries per modality pair (default 1000)",
        "accepted as a known fabric (default 0.05)",
    ):
        assert said in build, said
    serve = _help(capsys, "serve")
    for said in ("port (default 8000)", "largest upload in MB (default 8)", "(default 25)"):
        assert said in serve, said


def test_index_info_help_describes_it(capsys: pytest.CaptureFixture[str]):
    text = _help(capsys, "index", "info")
    assert "Say what the library folder LIBRARY holds: its checkpoint and model" in text


# ---- 8. a bad number is refused by its flag's name, before any work --------------------------


FLAGS = [
    (["synth", "{out}"], "--workers", "-1", ">= 0"),
    (["synth", "{out}"], "--fabrics", "0", ">= 1"),
    (["synth", "{out}"], "--seed", "-1", ">= 0"),
    (["synth", "{out}"], "--frames", "0", ">= 1"),
    (["synth", "{out}"], "--drapes", "-1", ">= 0"),
    (["synth", "{out}"], "--presses-flat", "-1", ">= 0"),
    (["synth", "{out}"], "--presses-fold", "-1", ">= 0"),
    (["synth", "{out}"], "--reprints", "-1", ">= 0"),
    (["synth", "{out}"], "--test-fabrics", "-1", ">= 0"),
    (["reproduce", "--data", "d", "--out", "{out}"], "--workers", "-1", ">= 0"),
    (["reproduce", "--data", "d", "--out", "{out}"], "--n-boot", "-1", ">= 0"),
    (["cv", "--data", "d", "--out", "{out}"], "--n-boot", "-1", ">= 0"),
    (["cv", "--data", "d", "--out", "{out}"], "--presses", "0", ">= 1"),
    (["cv", "--data", "d", "--out", "{out}"], "--fold-size", "0", ">= 1"),
    ([*EMBEDDING["index build"][:-1], "{out}"], "--shard-size", "0", ">= 1"),
    ([*EMBEDDING["index build"][:-1], "{out}"], "--seed", "-1", ">= 0"),
]


@pytest.mark.parametrize(("argv", "flag", "value", "bound"), FLAGS, ids=lambda v: str(v))
def test_a_bad_number_is_refused_by_its_flag(
    argv: list[str],
    flag: str,
    value: str,
    bound: str,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
):
    """QA: ``synth.workers: must be in [0, 256]``, ``workers must be >= 0``, ``shard_size and
    batch_size must be >= 1 (0, 64)``, ``presses: a touch query pools at least 1 press``,
    ``--set train.fold_size=0`` (no --set given), numpy's traceback for ``index build --seed
    -1`` and ``reproduce --n-boot -1``, and ``cv --n-boot -1`` after a whole fold of
    training: each is now argparse's usage line naming the flag, before any work."""
    out = tmp_path / "o"
    args = [a.replace("{out}", str(out)) for a in argv]
    _usage_error(capsys, [*args, flag, value], f"argument {flag}: must be {bound}, got {value}")
    assert not out.exists()


def test_only_folds_refuses_a_negative_fold(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    argv = ["cv", "--data", "d", "--out", str(tmp_path / "o"), "--only-folds=0,-1"]
    _usage_error(capsys, argv, "argument --only-folds: a fold must be an integer >= 0, got -1")


# ---- 9. a suggested --set works as printed, in any shell --------------------------------------


def _suggested_sets(message: str) -> list[str]:
    """Every ``--set`` a message suggests, split as a POSIX shell splits what is typed."""
    return [
        word
        for flag in re.findall(r'--set (?:"[^"]*"|\S+)', message)
        for word in shlex.split(flag.rstrip(","))
    ]


def _messages(tmp_path: Path) -> list[str]:
    """One message of each kind that suggests a ``--set``: data's leave-out, the catalog's
    press kinds, train's views and class heads (two label columns YAML reads as a boolean and
    a number), and the recipe chooser's kinds left out."""
    from lookfeel.config.recipes import _fit_touch_kinds
    from lookfeel.data import scan
    from lookfeel.data.problems import leave_out
    from lookfeel.modality import Modality, PressKind
    from lookfeel.train.loop import _heads_fix, views_problem

    from ._tiny import write_tiny_dataset

    both = write_tiny_dataset(tmp_path / "both", 4, drapes=1, fold_presses=2, flat_presses=1)
    (both / "labels.csv").write_text(
        "fabric_id,yes,1e3\n1,0,foam\n2,1,wood\n3,0,foam\n4,1,wood\n", encoding="utf-8"
    )
    catalog = scan(both)
    for p in (both / "touch").glob("F0001_flat_*"):
        p.unlink()
    flat_less = scan(both)
    touch = write_tiny_dataset(tmp_path / "touch", 4, drapes=1, fold_presses=2, flat_presses=0)
    for sense in ("depth", "color"):
        shutil.rmtree(touch / sense)
    pairs = "train.val_pairs=[depth_to_touch,touch_to_touch]"
    views = views_problem(scan(touch), load_config(RunConfig, "tiny", [pairs]))
    assert views is not None
    return [
        leave_out("color", ["depth", "touch"], "fabric", False),
        leave_out("depth", ["touch"], "fabric", True),
        *(p.message for p in flat_less.lacking([Modality.TOUCH], (PressKind.FLAT,))),
        views.message,
        _heads_fix(catalog, ["yes", "roughness", "1e3"]),
        *_fit_touch_kinds(catalog, ["fold"])[1],
    ]


def test_every_suggested_set_parses_back_as_printed(tmp_path: Path):
    """QA (portability): messages suggested ``--set 'train.views=[touch,touch]'``, which
    Windows' cmd.exe passes with the quotes (the key read is ``'train.views``). Each is now in
    double quotes, which bash, zsh, cmd.exe and PowerShell all take off; split as a POSIX shell
    splits it, the CLI's own ``--set`` reads it back to the setting the message means."""
    messages = _messages(tmp_path)
    assert not [m for m in messages if "--set '" in m], messages  # cmd.exe keeps single quotes
    sets = [_suggested_sets(m) for m in messages]
    assert all(s and len(s) % 2 == 0 and s[::2] == ["--set"] * (len(s) // 2) for s in sets), sets
    argv = ["train", "--data", str(tmp_path), "--out", str(tmp_path / "r")]
    parsed = [build_parser().parse_args([*argv, *s]).set for s in sets]
    assert parsed == [
        ["train.views=[depth,touch]"],
        ["train.views=[touch,touch]"],
        ["data.touch_kinds=[flat,fold]"],  # a fabric has fold presses alone: every kind
        ["train.views=[touch,touch]", "train.val_pairs=[touch_to_touch]"],
        ["model.class_heads=['yes','1e3']", "model.class_heads=[]"],
        ["data.touch_kinds=[flat,fold]"],
    ]
    configs = [load_config(RunConfig, "tiny", [o]) for p in parsed for o in p]
    assert configs[0].train.views == (Modality.DEPTH, Modality.TOUCH)
    assert configs[4].train.val_pairs == parse_pairs(["touch_to_touch"], "train.val_pairs")
    assert configs[5].model.class_heads == ("yes", "1e3")  # strings, not True and 1000.0
    assert configs[6].model.class_heads == ()
    assert configs[7].data.touch_kinds == (PressKind.FLAT, PressKind.FOLD)


def test_a_suggested_set_is_the_same_on_every_system(monkeypatch: pytest.MonkeyPatch):
    """The words of a suggestion do not depend on the system that prints them: double quotes
    where a setting needs quotes, none where it needs none; only text that double quotes
    cannot carry in every shell (``$``, ``"``, a backslash) is quoted for this system's."""
    from lookfeel import shell

    for windows in (False, True):
        monkeypatch.setattr(shell, "WINDOWS", windows)
        assert shell.set_flag("train.steps=3") == "--set train.steps=3"
        assert shell.set_flag("train.views=[touch,touch]") == '--set "train.views=[touch,touch]"'
        assert shell.set_flag("loss.pair_weights={}") == '--set "loss.pair_weights={}"'
        assert shell.set_flag("model.class_heads=['a b']") == "--set \"model.class_heads=['a b']\""
    monkeypatch.setattr(shell, "WINDOWS", False)
    assert shell.portable_quote("a=$HOME x") == "'a=$HOME x'"  # bash reads $ in double quotes
    assert shell.portable_quote(r"C:\My Weights") == r"'C:\My Weights'"
    monkeypatch.setattr(shell, "WINDOWS", True)
    assert shell.portable_quote(r"C:\My Weights") == r'"C:\My Weights"'
