"""The progress bars of ``match``, ``data check`` and ``embed`` (QA, session 56).

On a large world the three were silent for long: ``match`` of 3,000 photos ~25 s, ``data check``
of a 300-fabric world 48 s, ``embed`` 27 s. Each now shows a progress bar on stderr (tqdm, as
``synth`` and training do), which ``--quiet`` turns off, and prints to stdout what it printed
before: ``match`` a bar of the images embedded when they are more than one batch
(`lookfeel.index.match.EMBED_BATCH`), ``data check`` one of the files decoded and one of the
modalities scored for leaks, ``embed`` one of each modality's images decoded and one of its
items embedded. The library's functions show none unless asked.

Bars are drawn only where stderr is a terminal, or with ``LOOKFEEL_PROGRESS=always``
(`lookfeel.progress`): pytest's captured stderr is not one, so the tests of what a bar shows set
it, and the last tests check the rule itself.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from lookfeel.cli import main
from lookfeel.index import match as match_module
from lookfeel.progress import ENV, bar, shown

from ._library import tiny_library


def _bars(err: str) -> dict[str, int]:
    """Each bar on stderr by name, with its total (from the line tqdm prints as it starts);
    stderr must hold nothing else."""
    said = [part for part in err.split("\r") if part.strip()]
    assert all(re.match(r"[a-z ]+: +\d+%\|", part) for part in said), said
    found = re.findall(r"\r([a-z ]+): +0%\|[^|]*\| 0/(\d+) ", err)
    return {name: int(total) for name, total in found}


@pytest.fixture(autouse=True)
def _bars_drawn(monkeypatch: pytest.MonkeyPatch) -> None:
    """As on a terminal: the tests below read what the bars show."""
    monkeypatch.setenv(ENV, "always")


@pytest.fixture(scope="module")
def library(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tiny_library(tmp_path_factory, "progress", shard_size=64)


def test_match_shows_its_progress_on_stderr_only(
    run: tuple[Path, Path],
    library: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
):
    data, _ = run
    depth = sorted(str(p) for p in (data / "depth").glob("*.png"))[:5]
    argv = ["match", "--index", str(library), "--modality", "depth", "--top", "2", *depth]
    monkeypatch.setattr(match_module, "EMBED_BATCH", 2)  # 5 images: 3 batches
    assert main([*argv, "--quiet"]) == 0
    quiet = capsys.readouterr()
    assert quiet.err == "" and quiet.out.count("Query depth (1 image") == 5
    assert main(argv) == 0
    shown = capsys.readouterr()
    assert shown.out == quiet.out  # the answers, as before
    assert _bars(shown.err) == {"match": 5}
    assert main([*argv, "--json"]) == 0
    shown = capsys.readouterr()
    assert len(json.loads(shown.out)) == 5 and _bars(shown.err) == {"match": 5}
    # One batch has no progress to show: as before, nothing on stderr.
    monkeypatch.setattr(match_module, "EMBED_BATCH", 5)
    assert main(argv) == 0
    one = capsys.readouterr()
    assert one.err == "" and one.out == quiet.out


def test_a_matcher_shows_no_bar_unless_asked(
    run: tuple[Path, Path], library: Path, monkeypatch: pytest.MonkeyPatch, capsys
):
    from lookfeel.index import Library, Matcher

    data, _ = run
    depth = sorted((data / "depth").glob("*.png"))[:3]
    monkeypatch.setattr(match_module, "EMBED_BATCH", 1)
    matcher = Matcher(Library.open(library))
    plain = matcher.match_files(depth, "depth")
    assert capsys.readouterr().err == ""
    shown = matcher.match_files(depth, "depth", progress=True)
    assert _bars(capsys.readouterr().err) == {"match": 3}
    assert [r.fabrics for r in shown] == [r.fabrics for r in plain]


def test_data_check_shows_the_files_decoded_and_the_leak_check(
    tiny_dataset: Path, capsys: pytest.CaptureFixture[str]
):
    assert main(["data", "check", str(tiny_dataset), "--quiet"]) == 0
    quiet = capsys.readouterr()
    assert quiet.err == ""
    files = int(re.findall(r"(\d+) files decoded", quiet.out)[0])
    assert main(["data", "check", str(tiny_dataset)]) == 0
    shown = capsys.readouterr()
    assert shown.out == quiet.out
    assert _bars(shown.err) == {"check": files, "leakage": 3}  # depth, colour, touch
    assert main(["data", "check", str(tiny_dataset), "--json", "--no-leakage"]) == 0
    shown = capsys.readouterr()
    assert json.loads(shown.out)["ok"] and _bars(shown.err) == {"check": files}


def test_embed_shows_each_modality_decoded_and_embedded(
    run: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    from lookfeel.evaluate import embed_checkpoint

    data, ckpt = run
    argv = ["embed", "--checkpoint", str(ckpt), "--data", str(data)]
    assert main([*argv, "--out", str(tmp_path / "quiet.npz"), "--quiet"]) == 0
    quiet = capsys.readouterr()
    assert quiet.err == ""
    assert main([*argv, "--out", str(tmp_path / "e.npz")]) == 0
    shown = capsys.readouterr()
    assert shown.out == quiet.out.replace("quiet.npz", "e.npz")
    counts = dict(re.findall(r"(depth|color|touch) (\d+)", shown.out.splitlines()[0]))
    assert len(counts) == 3
    want = {f"{step} {m}": int(n) for m, n in counts.items() for step in ("decode", "embed")}
    assert _bars(shown.err) == want
    # The library's function, outside `lookfeel embed`: no bar.
    embed_checkpoint(ckpt, data)
    assert capsys.readouterr().err == ""


class _Terminal:
    """A stderr that says it is a terminal (or not) and keeps what is written to it."""

    def __init__(self, tty: bool) -> None:
        self.tty, self.text = tty, ""

    def isatty(self) -> bool:
        return self.tty

    def write(self, s: str) -> int:
        self.text += s
        return len(s)

    def flush(self) -> None:
        pass


@pytest.mark.parametrize(
    ("tty", "env", "drawn"),
    [
        (True, None, True),  # a person watching
        (False, None, False),  # a log file or a pipe: no frame of a bar in it
        (False, "auto", False),
        (False, "always", True),
        (True, "never", False),
        (True, "0", False),
    ],
)
def test_bars_are_drawn_on_a_terminal_unless_the_environment_says_otherwise(
    monkeypatch: pytest.MonkeyPatch, tty: bool, env: str | None, drawn: bool
):
    """QA: a 60-step training run wrote 5.7 KB of bar frames into a redirected stderr (a long
    run, megabytes of a batch job's log)."""
    stderr = _Terminal(tty)
    monkeypatch.setattr("sys.stderr", stderr)
    if env is None:
        monkeypatch.delenv(ENV, raising=False)
    else:
        monkeypatch.setenv(ENV, env)
    assert shown() is drawn and shown(False) is False  # a command's --quiet: never
    with bar(total=3, desc="work", file=stderr) as b:
        for _ in range(3):
            b.update(1)
    assert ("work:" in stderr.text) is drawn


def test_an_unknown_setting_is_warned_of_and_read_as_auto(monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setattr("sys.stderr", _Terminal(False))
    monkeypatch.setenv(ENV, "sometimes")
    with pytest.warns(UserWarning, match=r"^LOOKFEEL_PROGRESS='sometimes': expected always"):
        assert shown() is False


def test_a_redirected_training_run_writes_no_bar(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
):
    """Training's own bar, from the command line, into a stderr that is not a terminal (as
    pytest's, a log file's): no frame of it; with ``LOOKFEEL_PROGRESS=always``, its frames."""
    from ._library import TINY, tiny_run

    data, _ = tiny_run()
    sets = ["--set", "train.steps=2", "--set", "train.val_every=0"]
    sets += ["--set", "train.checkpoint_every=0", "--set", "train.threads=1"]
    sets += ["--set", "train.progress=true"]  # the tiny recipe turns it off
    monkeypatch.delenv(ENV, raising=False)
    argv = ["train", "--config", str(TINY), "--data", str(data), *sets]
    assert main([*argv, "--out", str(tmp_path / "quiet")]) == 0
    assert "train:" not in capsys.readouterr().err
    monkeypatch.setenv(ENV, "always")
    assert main([*argv, "--out", str(tmp_path / "drawn")]) == 0
    assert "train: 100%" in capsys.readouterr().err


def test_train_and_cv_take_quiet_as_the_other_commands_do(tmp_path: Path):
    """QA: `synth`, `index build`, `data check`, `embed` and `match` turn their bars off with
    --quiet, `train` and `cv` only with `--set train.progress=false`: --quiet is that too."""
    from lookfeel.cli import build_parser

    parser = build_parser()
    for command in ("train", "cv"):
        base = [command, "--data", str(tmp_path), "--out", str(tmp_path / command)]
        args = parser.parse_args([*base, "--set", "train.steps=3", "--quiet"])
        assert args.set == ["train.steps=3", "train.progress=false"]
        assert parser.parse_args(base).set == []  # the default list is not changed by a parse
