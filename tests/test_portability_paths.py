"""Paths on macOS and Windows as well as Linux (QA, session 57): guards that compare folders by
identity, not spelling; names one folder cannot hold there; a dataset fingerprint written with
``/`` on every system; commands quoted for the shell that runs them; text read as UTF-8.

Linux shows the identity part with a bind mount (a folder under two names, as ``~/Data`` and
``~/data`` are one folder on a disk that ignores case), made in a private user and mount
namespace (``unshare -Urm``); those tests are skipped where the system allows none.
"""

from __future__ import annotations

import json
import ntpath
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path, PureWindowsPath

import pytest

from lookfeel import shell
from lookfeel.cli._args import OutError, check_out_beside_data, path_flag, shell_quote
from lookfeel.data import scan
from lookfeel.data.paths import lies_within

from ._tiny import write_rgb, write_tiny_dataset

# ---- identity, not spelling ------------------------------------------------------------------


def test_lies_within_by_path(tmp_path: Path):
    data = tmp_path / "data"
    (data / "color").mkdir(parents=True)
    (tmp_path / "link").symlink_to(data)
    assert lies_within(data, data)
    assert lies_within(data / "color", data)
    assert lies_within(data / "run" / "not-yet", data)  # need not exist
    assert lies_within(tmp_path / "link" / "run", data)  # through a symbolic link
    assert not lies_within(tmp_path / "data-run", data)  # a name that begins the same
    assert not lies_within(tmp_path, data)
    assert not lies_within(tmp_path / "elsewhere", tmp_path / "missing")


_ALIASED = textwrap.dedent(
    """
    import os, sys
    from pathlib import Path

    data, alias = Path(sys.argv[1]), Path(sys.argv[2])

    from lookfeel.cli._args import OutError, check_out_beside_data
    try:
        check_out_beside_data(alias / "run", data)
        print("out: written into the dataset")
    except OutError as e:
        print("out: refused:", e)

    from lookfeel.data import scan
    problems = [str(p) for p in scan(data, check_headers=False).problems]
    print("scan:", "outside" if any("outside the dataset" in p for p in problems) else "inside")

    from lookfeel.index.build import LibraryError, _check_not_here
    os.chdir(alias / "color")
    try:
        _check_not_here(data)
        print("cwd: swapped away")
    except LibraryError as e:
        print("cwd: refused:", e)
    """
)


@pytest.fixture(scope="module")
def aliased(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    """What the guards say of a dataset folder reached under another name (a bind mount):
    ``out`` (an ``--out`` inside it), ``scan`` (a link in it to one of its files by the other
    name) and ``cwd`` (``index build --out`` the folder the shell is in)."""
    unshare = shutil.which("unshare")
    if unshare is None or subprocess.run([unshare, "-Urm", "true"], check=False).returncode:
        pytest.skip("no private mount namespace here (unshare -Urm)")
    root = tmp_path_factory.mktemp("aliased")
    data, alias = root / "data", root / "alias"
    write_rgb(data / "color" / "F0001_1.png", 1, 1)
    write_rgb(data / "extra" / "F2.png", 2, 1)
    alias.mkdir()
    (data / "color" / "F0002_1.png").symlink_to(alias / "extra" / "F2.png")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    mount = 'mount --bind "$1" "$2" && shift 2 && exec "$@"'
    python = [sys.executable, "-c", _ALIASED, str(data), str(alias)]
    done = subprocess.run(
        [unshare, "-Urm", "sh", "-c", mount, "sh", str(data), str(alias), *python],
        capture_output=True,
        text=True,
        env=env,
        check=False,
        timeout=120,
    )
    if "mount" in done.stderr and done.returncode:
        pytest.skip(f"no bind mount here: {done.stderr.strip()}")
    assert done.returncode == 0, done.stderr
    return dict(line.split(": ", 1) for line in done.stdout.splitlines())


def test_an_out_inside_the_data_under_another_name_is_refused(aliased: dict[str, str]):
    """QA: ``--data ~/Data --out ~/data/run`` on a disk that ignores case passed the guard (it
    compared the real paths as text) and lookfeel wrote into the dataset."""
    assert aliased["out"].startswith("refused: ")
    assert "lies inside the dataset folder" in aliased["out"]


def test_a_link_to_the_data_under_another_name_is_inside_it(aliased: dict[str, str]):
    """A symbolic link to a file of the dataset, spelt another way, is not "outside"."""
    assert aliased["scan"] == "inside"


def test_index_build_refuses_the_current_folder_under_another_name(aliased: dict[str, str]):
    """``cd ~/Lib`` then ``--out ~/lib``: the swap would take the shell's folder away."""
    assert aliased["cwd"].startswith("refused: ")
    assert "is the current folder or holds it" in aliased["cwd"]


def test_out_beside_the_data_is_still_allowed(tmp_path: Path):
    (tmp_path / "data").mkdir()
    check_out_beside_data(tmp_path / "data-run", tmp_path / "data")
    with pytest.raises(OutError, match="lies inside the dataset folder"):
        check_out_beside_data(tmp_path / "data" / "run", tmp_path / "data")


# ---- names one folder cannot hold on macOS or Windows ---------------------------------------


def test_files_differing_only_in_case_are_a_warning(tmp_path: Path):
    """QA: ``color/F0001_1.png`` beside ``color/f0001_1.png`` made two items and no warning;
    a copy on macOS or Windows keeps one of them."""
    root = write_tiny_dataset(tmp_path / "tiny", fabrics=2, drapes=1, fold_presses=1)
    write_rgb(root / "color" / "f0001_1.png", 1, 9)
    catalog = scan(root)
    clashes = [p for p in catalog.problems if "differ only in case" in p.message]
    assert [(p.path, p.severity) for p in clashes] == [(root / "color", "warning")]
    assert clashes[0].message.startswith("'F0001_1.png' and 'f0001_1.png' differ only in case")
    assert "cannot both exist on macOS or Windows" in clashes[0].message
    assert not catalog.errors


def test_names_alike_but_for_accents_encoding_are_a_warning(tmp_path: Path):
    """``crème_0.mov`` composed and decomposed: two files on Linux, one on macOS."""
    root = tmp_path / "rec"
    (root / "videos").mkdir(parents=True)
    for name in ("cr\u00e8me_0.mov", "cre\u0300me_0.mov"):
        (root / "videos" / name).write_bytes(b"\x00\x00\x00\x18ftypmp42" + bytes(64))
    problems = [p for p in scan(root).problems if "cannot both exist" in p.message]
    assert [p.path for p in problems] == [root / "videos"]
    assert "differ only in how an accented letter is written" in problems[0].message


def test_a_dataset_without_clashes_has_no_such_warning(tiny_dataset: Path):
    assert not [p for p in scan(tiny_dataset).problems if "cannot both exist" in p.message]


# ---- the fingerprint is one on every system --------------------------------------------------


def _fixed_dataset(root: Path) -> Path:
    """Files of fixed bytes (no encoder involved), read without their headers."""
    for rel, size in [
        ("depth/F0001_Depth_1.png", 40),
        ("color/F0001_1.png", 50),
        ("depth/F0002_Depth_1.png", 45),
        ("color/F0002_1.png", 60),
        ("touch/F0001_fold_01_7.png", 70),
        ("touch/F0001_fold_02_7.png", 80),
        ("touch/F0002_fold_01_3.png", 90),
    ]:
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(size))
    (root / "labels.csv").write_text("fabric_id,thickness_mm\n1,0.5\n2,0.7\n", encoding="utf-8")
    return root


HEAD_FINGERPRINT = "d0a3c11d477b02ff"
"""`Catalog.fingerprint` of `_fixed_dataset` before session 57 (measured on Linux)."""


def test_the_fingerprint_is_unchanged_on_linux_and_macos(tmp_path: Path):
    catalog = scan(_fixed_dataset(tmp_path / "d"), check_headers=False)
    assert not catalog.errors
    assert catalog.fingerprint() == HEAD_FINGERPRINT


def test_the_fingerprint_on_windows_is_the_same(tmp_path: Path, monkeypatch):
    """QA: Windows' relpath says ``depth\\F0001...``, so the same dataset had another digest
    there, and a run trained on Linux was refused as "trained on another dataset"."""
    from lookfeel.data import catalog as catalog_module

    root = _fixed_dataset(tmp_path / "d")
    linux = scan(root, check_headers=False).fingerprint()
    windows = scan(root, check_headers=False)
    monkeypatch.setattr(os.path, "relpath", ntpath.relpath)  # as on Windows: "\\"
    monkeypatch.setattr(catalog_module, "PurePath", PureWindowsPath, raising=False)
    assert windows.fingerprint() == linux


# ---- commands a message suggests, quoted for the shell that runs them -----------------------


def test_shell_quote_is_posix_quoting_off_windows():
    assert shell_quote("train.steps=3") == "train.steps=3"
    assert shell_quote("w/a b.pth") == "'w/a b.pth'"
    assert path_flag("model.pretrained", "--pretrained", Path("w/a b.pth")).given == (
        "--pretrained 'w/a b.pth'"
    )


def test_shell_quote_on_windows_uses_double_quotes(monkeypatch):
    """QA: cmd.exe keeps single quotes as part of the argument."""
    monkeypatch.setattr(shell, "WINDOWS", True)
    assert shell_quote("train.steps=3") == "train.steps=3"
    assert shell_quote(r"C:\My Weights\a.pth") == r'"C:\My Weights\a.pth"'
    assert shell_quote(r"C:\My Weights" + "\\") == r'"C:\My Weights\\"'
    assert shell_quote("model.class_heads=[a&b]") == '"model.class_heads=[a&b]"'
    assert shell_quote("a&b\\") == '"a&b\\\\"'  # a backslash before the quote is doubled
    assert path_flag("model.pretrained", "--pretrained", Path("w a.pth")).given == (
        '--pretrained "w a.pth"'
    )


# ---- text read as UTF-8 ----------------------------------------------------------------------


def test_a_metrics_line_that_is_not_utf8_counts_nothing(tmp_path: Path):
    """Reading metrics.jsonl as UTF-8 (not the locale's code page) must not fail on one bad
    byte: that line is skipped as an unreadable line is, and the others still count."""
    from lookfeel.reproduce.run import _logged_seconds

    path = tmp_path / "metrics.jsonl"
    lines = [
        json.dumps({"step": 10, "steps_per_s": 5.0}),
        json.dumps({"step": 20, "steps_per_s": 10.0}),
    ]
    path.write_bytes(lines[0].encode() + b'\n{"note": "\xff"}\n' + lines[1].encode() + b"\n")
    assert _logged_seconds(path) == pytest.approx(10 / 5 + 10 / 10)


def test_a_held_out_item_recorded_on_windows_is_found_on_linux():
    # split.json records each held-out item's path as the training machine wrote it; evaluate
    # finds it again by its folder and name wherever the dataset now lies.
    from lookfeel.evaluate.from_checkpoint import _item_key

    key = ("depth", "F0001_1.png")
    assert _item_key(r"C:\Users\me\gelfabric\depth\F0001_1.png") == key
    assert _item_key("/home/me/gelfabric/depth/F0001_1.png") == key
    assert _item_key(Path("gelfabric") / "depth" / "F0001_1.png") == key
