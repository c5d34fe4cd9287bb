"""Every subcommand in-process through `main(argv)`."""

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import pytest
import yaml

import lookfeel.cli
from lookfeel.cli import build_parser, main, run


def test_data_info_text_and_json(tiny_dataset: Path, capsys):
    assert main(["data", "info", str(tiny_dataset)]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^  fabrics +6 \(ids 1-6\)$", out, re.M)
    assert re.search(
        r"^  touch +30 presses \(5-5 per fabric\): flat 12, fold 18; 90 frames$", out, re.M
    )
    assert main(["data", "info", str(tiny_dataset), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["data_root"] == str(tiny_dataset) and "root" not in info  # as index info says
    assert info["fabrics"] == 6
    assert info["items"] == {"depth": 18, "color": 18, "touch": 30}
    assert info["fabrics_with_physical_labels"] == 6


def test_bad_arguments_exit_2(capsys):
    with pytest.raises(SystemExit) as e:
        main(["data", "check", "x", "--require", "smell"])
    assert e.value.code == 2
    assert "unknown modality 'smell'" in capsys.readouterr().err
    assert main([]) == 2


def test_version(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.startswith("lookfeel 0.")


def test_demo_runs_end_to_end(tmp_path: Path, capsys):
    """The demo on a small world with 2-step runs (the real one: `make demo`)."""
    args = ["demo", "--out", str(tmp_path / "demo"), "--fabrics", "10", "--data", str(tmp_path)]
    assert main([*args, "--set", "train.steps=2", "--set", "data.image_size=24"]) == 0
    out = capsys.readouterr().out
    assert "Generating a synthetic world of 10 fabrics (3 held out)" in out
    assert "touch->depth top-1" in out and "Report:" in out and "Evaluation:" in out
    assert "[4/5" in out and "Training the cross-modal recipe" in out
    assert "Look and feel connected" in out and "on 3 held-out fabrics" in out
    assert re.search(r"^  touch -> depth .* through the map, .* in the embedding", out, re.M)
    assert (tmp_path / "demo" / "cross" / "checkpoints" / "last.pt").is_file()
    # The short run keeps the full recipe's dropout on depth and touch and its three frames a
    # press, at half its width, with the photo at the size of the other senses (CROSS_OVERRIDES).
    saved = yaml.safe_load(
        (tmp_path / "demo" / "cross" / "config.yaml").read_text(encoding="utf-8")
    )
    assert saved["model"]["branch_dropout"] == {"depth": 0.3, "touch": 0.3}
    assert (saved["model"]["width"], saved["train"]["steps"]) == (16, 2)
    assert (saved["data"]["image_size"], saved["data"]["color_size"]) == (24, None)
    assert (saved["data"]["touch_frames"], saved["data"]["touch_frame"]) == ([0, 1, 2], -1)
    assert saved["model"]["precision"] == "fp32"  # on CUDA too: the numbers a CPU gives
    metrics = json.loads(
        (tmp_path / "demo" / "evaluate" / "metrics.json").read_text(encoding="utf-8")
    )
    assert "touch_to_depth_top1_mapped_ci_low" in metrics
    assert (tmp_path / "demo" / "evaluate" / "figures" / "glance.png").is_file()
    assert "At a glance:" in out
    report = (tmp_path / "demo" / "reproduce" / "report.md").read_text(encoding="utf-8")
    assert "## Table 4" in report
    # One training seed, 0, as before `reproduce` took a list of seeds (session 56).
    assert "budget: **tiny**; seeds: 1; " in report
    runs = tmp_path / "demo" / "reproduce" / "runs"
    assert {p.name for p in runs.glob("*/seed*")} == {"seed0"}
    assert main([*args, "--set", "train.steps=2", "--set", "data.image_size=24"]) == 0
    assert "Reusing the synthetic world" in capsys.readouterr().out


def _commands(
    parser: argparse.ArgumentParser, prefix: tuple[str, ...] = ()
) -> list[tuple[str, ...]]:
    """Every command the parser runs, as its words: ("data", "info"), ("train",), ..."""
    [sub] = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)] or [None]
    if sub is None:
        return [prefix]
    return [c for name, p in sub.choices.items() for c in _commands(p, (*prefix, name))]


COMMANDS = _commands(build_parser())


def test_the_docstring_and_help_list_every_command(capsys):
    assert len(COMMANDS) == 16
    listed = re.findall(r"^  ([a-z]+(?: [a-z]+)?)(?: [A-Z.]+)? {2,}\S", lookfeel.cli.__doc__, re.M)
    assert sorted(listed) == sorted(" ".join(c) for c in COMMANDS)
    with pytest.raises(SystemExit) as e:
        main(["--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: lookfeel [-h] [--version] [--plugin MODULE] COMMAND ...")
    for words in COMMANDS:
        assert re.search(rf"^  {' '.join(words)} .*\w", out, re.M), words


@pytest.mark.parametrize("words", COMMANDS, ids=" ".join)
def test_every_command_has_help(words: tuple[str, ...], capsys):
    with pytest.raises(SystemExit) as e:
        main([*words, "--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith(f"usage: lookfeel {' '.join(words)} ")
    assert "%(" not in out


def test_choices_come_from_where_they_are_defined(capsys):
    from lookfeel.demo import DEMO_BUDGETS
    from lookfeel.reproduce import BUDGETS
    from lookfeel.reproduce.run import EXPERIMENT_NAMES

    with pytest.raises(SystemExit):
        main(["reproduce", "--help"])
    out = " ".join(capsys.readouterr().out.split())  # unwrapped
    assert f"--budget BUDGET {', '.join(BUDGETS)} (default small" in out
    assert f"experiments to run, of {', '.join(EXPERIMENT_NAMES)} (default all)" in out
    with pytest.raises(SystemExit) as e:
        main(["reproduce", "--data", "d", "--out", "o", "--only", "flat", "tables"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "argument --only: invalid choice: 'tables' (choose from 'flat'" in err
    with pytest.raises(SystemExit) as e:
        main(["demo", "--budget", "paper"])
    assert e.value.code == 2
    choices = ", ".join(map(repr, DEMO_BUDGETS))
    assert f"invalid choice: 'paper' (choose from {choices})" in capsys.readouterr().err


def test_building_the_parser_loads_no_torch():
    """`lookfeel --help` and argument errors stay fast: handlers import the library."""
    code = "import sys, lookfeel.cli; lookfeel.cli.build_parser(); print('torch' in sys.modules)"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "False"


def test_output_into_a_closed_pipe_ends_quietly(tiny_dataset: Path):
    """`lookfeel data info ROOT | head -1`: no traceback when the reader is gone."""
    read, write = os.pipe()
    os.close(read)  # every write now fails with EPIPE
    try:
        done = subprocess.run(
            [sys.executable, "-m", "lookfeel", "data", "info", str(tiny_dataset)],
            stdout=write,
            stderr=subprocess.PIPE,
            text=True,
            check=False,
        )
    finally:
        os.close(write)
    assert done.returncode == 141 and done.stderr == ""


@pytest.mark.parametrize(
    ("raised", "status", "line"),
    [
        (KeyboardInterrupt(), 130, "lookfeel: interrupted"),
        (PermissionError(13, "Permission denied", "/data/out/x.npz"), 1,
         "lookfeel: /data/out/x.npz: Permission denied"),
        (OSError(30, "Read-only file system", "/mnt/ro/run"), 1,
         "lookfeel: /mnt/ro/run: Read-only file system"),
    ],
)  # fmt: skip
def test_ctrl_c_and_a_refused_file_end_in_one_line(
    tiny_dataset: Path, monkeypatch, capsys, raised: BaseException, status: int, line: str
):
    import lookfeel.cli.data

    def fails(args: argparse.Namespace) -> int:
        raise raised

    monkeypatch.setattr(lookfeel.cli.data, "run_info", fails)
    assert main(["data", "info", str(tiny_dataset)]) == status
    assert capsys.readouterr().err == line + "\n"


def test_an_os_error_about_no_file_is_a_bug_and_keeps_its_traceback(
    tiny_dataset: Path, monkeypatch
):
    import lookfeel.cli.data

    def fails(args: argparse.Namespace) -> int:
        raise OSError("no file named")

    monkeypatch.setattr(lookfeel.cli.data, "run_info", fails)
    with pytest.raises(OSError, match="no file named"):
        main(["data", "info", str(tiny_dataset)])


def test_an_out_folder_this_user_cannot_write_in_is_refused_before_the_work(
    tmp_path: Path, monkeypatch, capsys
):
    ro = tmp_path / "ro"
    ro.mkdir()
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: Path(p) != ro and real_access(p, mode))
    # One line, exit 1, as README says of an --out a command cannot write in (argparse's
    # usage error, exit 2, until session 56).
    for out in (ro / "run", ro / "deeper" / "run"):
        assert main(["train", "--data", str(tmp_path), "--out", str(out)]) == 1
        assert capsys.readouterr().err == (
            f"lookfeel: --out {out}: cannot write in {ro}: it is read-only for this user\n"
        )
    e_npz = ro / "e.npz"  # a file to write over: its folder must be writable
    assert (
        main(["embed", "--checkpoint", "c.pt", "--data", str(tmp_path), "--out", str(e_npz)]) == 1
    )
    assert capsys.readouterr().err.startswith(f"lookfeel: --out {e_npz}: cannot write in {ro}")
    # What the permissions allow but the file system does not (as root, /proc looks writable).
    monkeypatch.setattr(os, "access", real_access)
    refused = tmp_path / "refused"
    refused.mkdir()
    real_file = tempfile.TemporaryFile

    def no_files_in_refused(*args, **kwargs):
        if Path(kwargs["dir"]) == refused:
            raise OSError(30, "Read-only file system")
        return real_file(*args, **kwargs)

    monkeypatch.setattr(tempfile, "TemporaryFile", no_files_in_refused)
    assert main(["evaluate", "--checkpoint", "c.pt", "--data", str(tmp_path), "--out",
                 str(refused / "eval")]) == 1  # fmt: skip
    assert f"cannot write in {refused}: Read-only file system" in capsys.readouterr().err
    assert list(refused.iterdir()) == []


def test_the_console_script_shows_each_warning_once_as_one_line(monkeypatch, capsys):
    """`lookfeel ...` (`run`): a warning is ``lookfeel: warning: <message>``, without the
    library's file and source line, and one that several runs raise alike shows once."""

    def warns_like_three_runs(argv=None) -> int:
        for _ in range(3):  # as each of a recipe's three networks does
            warnings.warn("2 of 9 touch videos hold no press: a.mov (too short)", stacklevel=1)
        warnings.warn("another thing", RuntimeWarning, stacklevel=1)
        return 0

    monkeypatch.setattr(lookfeel.cli, "main", warns_like_three_runs)
    shown_before = warnings.showwarning
    assert run(["data", "info", "x"]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err == [
        "lookfeel: warning: 2 of 9 touch videos hold no press: a.mov (too short)",
        "lookfeel: warning: another thing",
    ]
    assert warnings.showwarning is shown_before  # put back for whoever calls next


def test_python_m_lookfeel_shows_a_training_warning_as_one_line(tiny_dataset: Path, tmp_path: Path):
    """`python -m lookfeel train ...` asking for re-printed photos a dataset lacks: the run
    goes on, and says so in one line, not in Python's warning with a library source line."""
    config = Path(__file__).resolve().parents[1] / "configs" / "tiny.yaml"
    command = [
        sys.executable, "-m", "lookfeel", "train", "--config", str(config),
        "--data", str(tiny_dataset), "--out", str(tmp_path / "run"),
        "--set", "train.steps=1", "--set", "data.color_reprints=1",
    ]  # fmt: skip
    done = subprocess.run(
        command,
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    warned = [line for line in done.stderr.splitlines() if "reprints" in line]
    assert warned == [
        f"lookfeel: warning: data.color_reprints=1: {tiny_dataset} has no reprints/ folder of "
        "re-printed photos (a synthetic world's: `lookfeel synth --reprints`); training on the "
        "photos themselves"
    ]
    assert "UserWarning" not in done.stderr


def test_pretrained_is_a_path_not_yaml_saved_absolute_and_named_in_its_errors(
    tiny_dataset: Path, tmp_path: Path, monkeypatch, capsys
):
    """`train --pretrained PATH` sets model.pretrained to the path as typed, not read as YAML
    (``: `` and a leading ``*`` are a file name's characters), made absolute in the run's
    config.yaml (which then runs from any folder); an error about it names --pretrained, not a
    ``--set model.pretrained=...`` the user never typed."""
    import torch

    from lookfeel.models import create_backbone

    monkeypatch.chdir(tmp_path)
    (tmp_path / "w").mkdir()
    torch.save(create_backbone("resnet18").state_dict(), tmp_path / "w" / "a: b.pth")
    config = Path(__file__).resolve().parents[1] / "configs" / "tiny.yaml"  # compact CNNs
    args = ["train", "--config", str(config), "--data", str(tiny_dataset), "--out"]
    assert main([*args, "r0", "--pretrained", "*r18.pth"]) == 1
    err = capsys.readouterr().err
    assert "--pretrained '*r18.pth': model.pretrained: backbone 'compact' has no" in err
    assert "--set" not in err and "YAML" not in err
    resnet = ["model.backbone=resnet18", "model.width=null", "train.views=[touch,touch]"]
    resnet += ["train.steps=1", "train.batch_size=4", "train.val_every=0"]
    sets = [x for s in resnet for x in ("--set", s)]
    assert main([*args, "run", *sets, "--pretrained", "w/a: b.pth"]) == 0
    saved = yaml.safe_load((tmp_path / "run" / "config.yaml").read_text(encoding="utf-8"))
    assert saved["model"]["pretrained"] == str(Path.cwd() / "w" / "a: b.pth")


def test_reproduce_names_its_pretrained_file_by_its_absolute_path(
    tmp_path: Path, monkeypatch, capsys
):
    """Every run `reproduce` trains saves the weights file's absolute path in its config.yaml,
    as `train --pretrained` does, so a run's config runs from any folder."""
    import lookfeel.reproduce
    from lookfeel.config import ConfigError

    given: dict[str, object] = {}

    def reproduce(data: Path, out: Path, **kwargs: object) -> None:
        given.update(kwargs)
        raise ConfigError("stopped here")

    monkeypatch.setattr(lookfeel.reproduce, "reproduce", reproduce)
    monkeypatch.chdir(tmp_path)
    argv = ["reproduce", "--data", "d", "--out", "o", "--budget", "paper"]
    assert main([*argv, "--pretrained", "w/alexnet.pth"]) == 1
    assert "stopped here" in capsys.readouterr().err
    assert given["pretrained"] == str(Path.cwd() / "w" / "alexnet.pth")


def test_embed_says_which_touch_presses_the_run_leaves_out(tmp_path: Path):
    from lookfeel.cli.embed import _kinds_left_out

    from ._tiny import write_tiny_dataset

    data = write_tiny_dataset(tmp_path / "d", fabrics=2, fold_presses=2, flat_presses=3)
    # 2 fabrics x 3 flat presses of 3 frames each: the press, not the frame, is counted.
    assert _kinds_left_out(data, ["fold"]) == (
        "touch: fold presses only (the run's data.touch_kinds); 6 flat presses of the dataset "
        "left out"
    )
    assert _kinds_left_out(data, ["fold", "flat"]) is None
    assert _kinds_left_out(data, None) is None


def test_batch_size_default_is_the_one_constant_the_embedding_code_uses(
    monkeypatch: pytest.MonkeyPatch,
):
    """QA: ``--batch-size`` wrote 64 as a literal (default and help), a copy of the embedding
    code's own default. The parser now reads `lookfeel.config.model.EMBED_BATCH` (no torch),
    for every command that embeds; the functions it feeds default to the same number."""
    import inspect

    import lookfeel.cli._args
    from lookfeel.config.model import EMBED_BATCH

    def batch_sizes(parser: argparse.ArgumentParser, path: str = "") -> dict[str, argparse.Action]:
        """``--batch-size`` of every command under ``parser``, by its words (``index build``)."""
        found = {}
        for action in parser._actions:
            if "--batch-size" in action.option_strings:
                found[path] = action
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    found |= batch_sizes(sub, f"{path} {name}".strip())
        return found

    monkeypatch.setattr(lookfeel.cli._args, "EMBED_BATCH", 7)
    actions = batch_sizes(build_parser())
    assert {"embed", "evaluate", "index build"} <= set(actions)
    for action in actions.values():
        assert action.default == 7 and action.help == "images per forward pass (default 7)"
    from lookfeel.embedding import embed_catalog, embed_items
    from lookfeel.evaluate import embed_checkpoint, evaluate_checkpoint
    from lookfeel.index import build_library
    from lookfeel.index.match import EMBED_BATCH as MATCH_BATCH

    assert MATCH_BATCH == EMBED_BATCH
    for fed in (embed_checkpoint, evaluate_checkpoint, build_library, embed_items, embed_catalog):
        assert inspect.signature(fed).parameters["batch_size"].default == EMBED_BATCH, fed
