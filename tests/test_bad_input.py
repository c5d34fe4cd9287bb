"""Bad input, as a new user or an attacker gives it: every case exits 1 or 2 with one line on
stderr naming the file or option and what is wrong, no traceback, and the dataset unchanged.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml

from lookfeel.cli import main
from lookfeel.config import ConfigError
from lookfeel.data import ImageError, check_dataset, decode_depth, decode_rgb, scan
from lookfeel.data.splits import SplitError, stratified_fabric_folds, stratified_fabric_split
from lookfeel.index import Library, LibraryError
from lookfeel.serve import ServeConfig, ServeOptionError, ServeOptions

from ._library import TINY, evaluate_cli, tiny_library
from ._tiny import bomb_png, write_tiny_dataset
from .conftest import tree_digest

ROOT = Path(__file__).resolve().parents[1]


# ---- helpers -------------------------------------------------------------------------------


def _fails(
    capsys: pytest.CaptureFixture[str], argv: list[str], *expected: str, codes=(1, 2)
) -> str:
    """Run the CLI; it must fail with ``codes`` and one ``lookfeel`` line holding ``expected``."""
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert "Traceback" not in err, err
    assert code in codes, f"exit {code}; stderr: {err}"
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert lines, "nothing on stderr"
    last = lines[-1]
    assert last.startswith("lookfeel"), f"the error is not one line: {err!r}"
    assert sum(ln.startswith("lookfeel") for ln in lines) == 1, err
    for text in expected:
        assert text in last, f"{text!r} not in {last!r}"
    return last


@pytest.fixture(scope="module")
def library(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tiny_library(tmp_path_factory, "bad", shard_size=64)


@pytest.fixture
def copy(run: tuple[Path, Path], tmp_path: Path) -> Iterator[Path]:
    """A copy of the tiny dataset; the test checks nothing under it was modified."""
    data = tmp_path / "data"
    shutil.copytree(run[0], data)
    yield data


@pytest.fixture(autouse=True)
def _threads() -> Iterator[None]:
    n = torch.get_num_threads()
    yield
    torch.set_num_threads(n)


def _truncate(path: Path) -> None:
    b = path.read_bytes()
    path.write_bytes(b[: len(b) // 2])


def _jpeg_dataset(data: Path) -> Path:
    """Turn the copy's colour PNGs into JPEGs (the same fabric names)."""
    from PIL import Image

    for p in sorted((data / "color").glob("*.png")):
        Image.open(p).convert("RGB").save(p.with_suffix(".jpg"), quality=90)
        p.unlink()
    return data


# ---- truncated images: one line in every command that decodes ------------------------------


@pytest.mark.parametrize("kind", ["png", "jpeg"])
@pytest.mark.parametrize("command", ["embed", "evaluate", "index", "train"])
def test_truncated_image_is_one_line(
    kind: str, command: str, run, copy: Path, tmp_path: Path, capsys
):
    _, ckpt = run
    if kind == "jpeg":
        _jpeg_dataset(copy)
        bad = sorted((copy / "color").glob("*.jpg"))[0]
    else:
        bad = sorted((copy / "depth").glob("*.png"))[0]
    _truncate(bad)
    before = tree_digest(copy)
    out = tmp_path / "out"
    argv = {
        "embed": ["embed", "--checkpoint", ckpt, "--data", copy, "--out", out / "e.npz"],
        "evaluate": ["evaluate", "--checkpoint", ckpt, "--data", copy, "--out", out],
        "index": ["index", "build", "--checkpoint", ckpt, "--data", copy, "--out", out],
        "train": ["train", "--config", TINY, "--data", copy, "--out", out],
    }[command]
    if command == "train":
        argv += ["--set", "train.steps=2", "--set", "train.val_every=0"]
    _fails(capsys, argv, bad.name, "truncated")
    assert tree_digest(copy) == before


def test_decoders_refuse_truncated_and_special_files(tmp_path: Path):
    good = tmp_path / "F1_1.png"
    from PIL import Image

    Image.fromarray(np.zeros((8, 8, 3), np.uint8)).save(good)
    cut = tmp_path / "F1_2.png"
    cut.write_bytes(good.read_bytes()[:40])
    with pytest.raises(ImageError, match="F1_2.png: file is truncated"):
        decode_rgb(cut)
    fifo = tmp_path / "F1_3.png"
    os.mkfifo(fifo)
    with pytest.raises(ImageError, match=r"F1_3.png: is a FIFO \(named pipe\), not a regular"):
        decode_rgb(fifo)  # at once: a FIFO with no writer must not be waited on
    with pytest.raises(ImageError, match="F1_4.png: is a folder"):
        (tmp_path / "F1_4.png").mkdir()
        decode_depth(tmp_path / "F1_4.png")


# ---- pixel limit: from the header, before decoding ------------------------------------------


def test_decompression_bomb_is_refused_from_its_header(tmp_path: Path):
    bomb = tmp_path / "bomb.png"
    bomb.write_bytes(bomb_png(13000, 13000))
    assert bomb.stat().st_size < 1_000_000
    with pytest.raises(ImageError, match=r"bomb.png: image declares 13000x13000 = 169.0 mega"):
        decode_rgb(bomb)
    with pytest.raises(ImageError, match="at most 0.01 are decoded"):
        decode_rgb(bomb, max_pixels=10_000)
    small = bomb_png(64, 64)
    assert decode_rgb("upload.png", small, max_pixels=64 * 64).shape == (64, 64, 3)
    with pytest.raises(ImageError, match="^upload.png: image declares 64x64"):
        decode_rgb("upload.png", small, max_pixels=64 * 64 - 1)


def test_match_refuses_a_bomb_and_a_fifo(library: Path, tmp_path: Path, capsys):
    bomb = tmp_path / "bomb.png"
    bomb.write_bytes(bomb_png(13000, 13000))
    _fails(
        capsys,
        ["match", "--index", library, "--modality", "color", bomb],
        "bomb.png:",
        "13000x13000",
    )
    fifo = tmp_path / "q.png"
    os.mkfifo(fifo)  # no writer: opening it for reading would block forever
    _fails(capsys, ["match", "--index", library, "--modality", "color", fifo], "q.png", "FIFO")


# ---- file names and kinds in a dataset ------------------------------------------------------


HUGE = "F99999999999999999999999_1"


def test_huge_fabric_id_is_a_problem_not_an_overflow(copy: Path, capsys):
    shutil.copy(sorted((copy / "color").glob("*.png"))[0], copy / "color" / f"{HUGE}.png")
    before = tree_digest(copy)
    catalog = scan(copy)
    assert any(HUGE in str(p) and "larger than" in p.message for p in catalog.errors)
    assert main(["data", "check", str(copy)]) == 1
    out = capsys.readouterr().out
    assert f"{HUGE}.png: fabric id in the file name is larger than 2147483647" in out
    assert tree_digest(copy) == before


@pytest.mark.parametrize("bad", ["huge id", "not an image"])
@pytest.mark.parametrize("command", ["embed", "evaluate"])
def test_embed_and_evaluate_refuse_files_the_scan_refuses(
    command: str, bad: str, run, copy: Path, tmp_path: Path, capsys
):
    _, ckpt = run
    if bad == "huge id":
        name = f"{HUGE}.png"
        shutil.copy(sorted((copy / "color").glob("*.png"))[0], copy / "color" / name)
    else:
        name = "F0001_Depth_New_000009.png"
        (copy / "depth" / name).write_bytes(b"not an image at all")
    before = tree_digest(copy)
    out = tmp_path / "out"
    argv = {
        "embed": ["embed", "--checkpoint", ckpt, "--data", copy, "--out", out / "e.npz"],
        "evaluate": ["evaluate", "--checkpoint", ckpt, "--data", copy, "--out", out],
    }[command]
    _fails(capsys, argv, name)
    assert tree_digest(copy) == before


def test_symlink_outside_the_dataset_and_fifo_are_errors(copy: Path, tmp_path: Path, capsys):
    outside = tmp_path / "secret.png"
    shutil.copy(sorted((copy / "color").glob("*.png"))[0], outside)
    (copy / "color" / "F0003_9.png").symlink_to(outside)
    os.mkfifo(copy / "color" / "F0004_9.png")
    inside = copy / "color" / "F0005_9.png"
    inside.symlink_to(sorted((copy / "color").glob("F0005_*.png"))[0])  # inside: fine
    assert main(["data", "check", str(copy)]) == 1  # returns at once: the FIFO is not opened
    out = capsys.readouterr().out
    assert "F0003_9.png: symbolic link to" in out and "outside the dataset folder" in out
    assert "F0004_9.png: is a FIFO (named pipe), not a regular image file" in out
    # A link inside the folder is read, not refused; its item is the one it links to, again
    [said] = [line for line in out.splitlines() if "F0005_9.png" in line]
    assert said.startswith("WARNING ") and "the same bytes as color/F0005_" in said
    catalog = scan(copy)
    paths = {
        p for f in catalog.fabrics for its in f.items.values() for it in its for p in it.frames
    }
    assert inside in paths and copy / "color" / "F0003_9.png" not in paths


# ---- data check on datasets no command can use ---------------------------------------------


def test_data_check_fails_on_an_empty_folder(tmp_path: Path, capsys):
    (tmp_path / "empty").mkdir()
    assert main(["data", "check", str(tmp_path / "empty")]) == 1
    out = capsys.readouterr().out
    assert "no usable image found" in out and "FAILED" in out


def test_data_check_fails_on_one_fabric(tmp_path: Path, capsys):
    one = write_tiny_dataset(tmp_path / "one", fabrics=1)
    before = tree_digest(one)
    assert main(["data", "check", str(one)]) == 1
    out = capsys.readouterr().out
    assert "only one fabric (id 1)" in out and "at least 2 are needed" in out
    assert tree_digest(one) == before


def test_data_check_fails_on_an_unfinished_synth_world(copy: Path, capsys):
    (copy / "synth.json").write_text(
        json.dumps({"generator": "lookfeel.synth", "status": "running"}), encoding="utf-8"
    )
    assert main(["data", "check", str(copy)]) == 1
    assert "synthetic world was not finished" in capsys.readouterr().out
    (copy / "synth.json").write_text(
        json.dumps({"generator": "lookfeel.synth", "status": "complete"}), encoding="utf-8"
    )
    assert not check_dataset(copy).errors


# ---- splits ---------------------------------------------------------------------------------


def test_train_on_one_fabric_is_one_line(tmp_path: Path, capsys):
    one = write_tiny_dataset(tmp_path / "one", fabrics=1)
    _fails(
        capsys,
        ["train", "--config", TINY, "--data", one, "--out", tmp_path / "run"],
        "1 fabric(s) cannot be split",
    )
    with pytest.raises(SplitError, match="at least 2"):
        stratified_fabric_split([1], {1: 0}, n_test=1)


def _thirty(root: Path) -> Path:
    """The README's 30-fabric world: fabrics 26-30 are paper_split=test."""
    data = write_tiny_dataset(root, fabrics=30, drapes=2, fold_presses=1, flat_presses=1, frames=2)
    lines = (data / "labels.csv").read_text(encoding="utf-8").splitlines()
    out = [lines[0]] + [
        ln if int(ln.split(",")[0]) <= 25 else ln[: -len("train")] + "test" for ln in lines[1:]
    ]
    (data / "labels.csv").write_text("\n".join(out) + "\n", encoding="utf-8")
    return data


def _synth_cross_on_thirty_fails(tmp_path: Path, capsys, *expected: str) -> None:
    """Training configs/synth_cross.yaml on `_thirty`'s fabrics fails with ``expected``."""
    data = _thirty(tmp_path / "w")
    train = ["train", "--config", ROOT / "configs/synth_cross.yaml", "--data", data]
    _fails(capsys, [*train, "--out", tmp_path / "r"], *expected)


def test_synth_cross_on_thirty_fabrics_is_one_line(tmp_path: Path, capsys):
    _synth_cross_on_thirty_fails(tmp_path, capsys, "5 folds of 18 fabrics need 90", "there are 25")


def test_synth_cross_error_says_which_fabrics_were_left_out(tmp_path: Path, capsys):
    _synth_cross_on_thirty_fails(tmp_path, capsys, "5 more fabric(s) marked paper_split=test")


def test_split_errors_name_what_was_left_out_and_warn_on_few_training_fabrics():
    ids = list(range(1, 26))
    with pytest.raises(SplitError, match=r"need 90 training fabrics .*there are 25 \(5 more"):
        stratified_fabric_folds(ids, {}, 5, fold_size=18, excluded=5)
    with pytest.warns(UserWarning, match="holding out 18 of 25 fabrics leaves 7 to train on"):
        stratified_fabric_split(ids, {}, n_test=18)


# ---- a shipped --config on data it does not fit: one line, with the --set that fits -----------


def _sets(line: str) -> list[str]:
    """The ``--set "KEY=VALUE"`` flags a message gives, as a shell would pass them."""
    import re
    import shlex

    return [a for q in re.findall(r'--set ("[^"]*")', line) for a in ("--set", *shlex.split(q))]


QUICK = ["--set", "train.steps=2", "--set", "train.val_every=0"]


def _touch_only(root: Path, kind: str = "fold", labels: str | None = None) -> Path:
    """Four fabrics with touch presses of one ``kind`` alone, and ``labels`` as labels.csv."""
    fold, flat = (2, 0) if kind == "fold" else (0, 2)
    data = write_tiny_dataset(root, 4, drapes=1, fold_presses=fold, flat_presses=flat, frames=2)
    shutil.rmtree(data / "depth")
    shutil.rmtree(data / "color")
    if labels is not None:
        (data / "labels.csv").write_text(labels, encoding="utf-8")
    return data


def test_a_class_head_the_labels_lack_says_the_heads_they_have(tmp_path: Path, capsys):
    """QA (a DIGIT owner): `--config physiclear` on recordings labelled with hardness and
    material said only "'roughness' is not a column of labels.csv"; it names every missing
    column and the --set of the heads the labels have, which trains."""
    labels = "fabric_id,hardness,material\n1,0,foam\n2,1,wood\n3,2,metal\n4,0,wood\n"
    data = _touch_only(tmp_path / "digit", labels=labels)
    before = tree_digest(data)
    argv = ["train", "--config", "physiclear", "--data", data, "--out", tmp_path / "r"]
    line = _fails(
        capsys,
        argv,
        "model.class_heads: 'roughness' and 'bumpiness' are not columns of labels.csv (have: "
        "hardness, material); give the heads your labels have: "
        '--set "model.class_heads=[hardness,material]", or --set "model.class_heads=[]" for none',
    )
    assert not (tmp_path / "r").exists()  # refused before any work
    fits = _sets(line)[:2]
    assert fits == ["--set", "model.class_heads=[hardness,material]"]
    quick = [*QUICK, "--set", "model.members=1", "--set", "data.image_size=32"]
    assert main([str(a) for a in [*argv, *fits, *quick]]) == 0, capsys.readouterr().err
    saved = yaml.safe_load((tmp_path / "r" / "config.yaml").read_text(encoding="utf-8"))
    assert saved["model"]["class_heads"] == ["hardness", "material"]
    assert tree_digest(data) == before


@pytest.mark.parametrize("command", ["train", "cv"])
def test_presses_of_another_kind_are_one_line_with_the_kinds_to_train_on(
    command: str, tmp_path: Path, capsys
):
    """QA: a rig of flat presses under `--config tiny` (fold presses) got a line per fabric,
    "fabric N has no touch (fold presses) item", and no word of data.touch_kinds."""
    data = write_tiny_dataset(tmp_path / "flat", 6, drapes=2, fold_presses=0, flat_presses=2)
    argv = [command, "--config", "tiny", "--data", data, "--out", tmp_path / "r"]
    line = _fails(
        capsys,
        argv,
        "none of the 6 fabrics (1, 2, 3 and 3 more) has a touch (fold presses) item; their "
        "presses are flat (the run's data.touch_kinds asks fold): "
        '--set "data.touch_kinds=[flat]" trains on them',
    )
    if command == "train":
        assert main([str(a) for a in [*argv, *_sets(line), *QUICK]]) == 0
        saved = yaml.safe_load((tmp_path / "r" / "config.yaml").read_text(encoding="utf-8"))
        assert saved["data"]["touch_kinds"] == ["flat"]


@pytest.mark.parametrize("command", ["train", "cv"])
def test_views_of_senses_the_data_lacks_are_one_line_with_views_that_fit(
    command: str, tmp_path: Path, capsys
):
    """QA: `--config tiny` (train.views [depth, color, touch]) on touch alone got a line per
    fabric and sense, "fabric N has no depth item", and no word of train.views."""
    data = _touch_only(tmp_path / "touch")
    argv = [command, "--config", "tiny", "--data", data, "--out", tmp_path / "r"]
    line = _fails(
        capsys,
        argv,
        f"{data}: the run's train.views [depth, color, touch] use depth and color, of which "
        'the data holds no item (it holds touch alone): --set "train.views=[touch,touch]" '
        "trains on what it holds",
    )
    if command == "train":
        assert main([str(a) for a in [*argv, *_sets(line), *QUICK]]) == 0
        saved = yaml.safe_load((tmp_path / "r" / "config.yaml").read_text(encoding="utf-8"))
        assert saved["train"]["views"] == ["touch", "touch"]


def test_views_and_press_kinds_the_data_lacks_are_said_together(tmp_path: Path, capsys):
    """Both wrong: a line each, whose --set flags together train."""
    data = _touch_only(tmp_path / "flat", "flat")
    argv = ["train", "--config", "tiny", "--data", data, "--out", tmp_path / "r"]
    assert main([str(a) for a in argv]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert err.startswith(f"lookfeel: 2 problem(s) in {data}:\n")
    assert '--set "train.views=[touch,touch]"' in err
    assert '--set "data.touch_kinds=[flat]"' in err
    assert main([str(a) for a in [*argv, *_sets(err), *QUICK]]) == 0


# ---- libraries -------------------------------------------------------------------------------


def _damaged(library: Path, tmp_path: Path) -> Path:
    lib = tmp_path / "lib"
    shutil.copytree(library, lib)
    return lib


def test_library_without_calibration_is_one_line(library: Path, tmp_path: Path, capsys):
    lib = _damaged(library, tmp_path)
    manifest = json.loads((lib / "manifest.json").read_text(encoding="utf-8"))
    del manifest["calibration"]
    (lib / "manifest.json").write_text(json.dumps(manifest), encoding="utf-8")
    _fails(capsys, ["index", "info", lib], "manifest.json: no 'calibration' entry")


@pytest.mark.parametrize("damage", ["width", "nan"])
def test_library_shard_of_wrong_width_or_nan_is_refused(
    damage: str, library: Path, tmp_path: Path, capsys
):
    lib = _damaged(library, tmp_path)
    shard = sorted(lib.rglob("*.npz"))[0]
    with np.load(shard, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    emb = arrays["embeddings"]
    arrays["embeddings"] = emb[:, :-1] if damage == "width" else np.where(emb > 0, np.nan, emb)
    with shard.open("wb") as f:
        np.savez(f, **arrays)
    expected = "the manifest says width" if damage == "width" else "NaN or infinite"
    with pytest.raises(LibraryError, match=expected):
        Library.open(lib)
    _fails(capsys, ["index", "info", lib], shard.name, expected)


# ---- server options ---------------------------------------------------------------------------


@pytest.fixture
def no_serving(monkeypatch: pytest.MonkeyPatch) -> None:
    """A serve command that got past validation must not block the test: fail instead."""
    import uvicorn

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the server would have started")

    monkeypatch.setattr(uvicorn, "run", refuse)


@pytest.mark.parametrize(
    ("option", "value", "expected"),
    [
        (
            "--port",
            "99999",
            "--port must be between 1 and 65535, or 0 for any free port; got 99999",
        ),
        ("--max-concurrency", "0", "--max-concurrency"),
        ("--max-upload-mb", "0", "--max-upload-mb"),
        ("--max-upload-mb", "-1", "--max-upload-mb"),
    ],
)
def test_serve_options_are_checked(
    option: str, value: str, expected: str, library: Path, capsys, no_serving
):
    _fails(capsys, ["serve", "--index", library, option, value], expected)


def test_serve_threads_are_checked(library: Path, capsys, no_serving):
    _fails(capsys, ["serve", "--index", library, "--threads", "-3"], "--threads", "-3")


def test_serve_options_validate_in_one_place():
    assert ServeOptions().config() == ServeConfig()
    assert ServeOptions(max_upload_mb=0.5, max_megapixels=2).config().max_pixels == 2_000_000
    for kwargs, message in [
        ({"port": -1}, "--port must be between 1 and 65535, or 0 for any free port; got -1"),
        ({"port": 99999}, "--port"),
        ({"threads": -3}, "--threads must be between 1 and 1024; got -3"),
        ({"max_concurrency": 0}, "--max-concurrency must be between 1 and 1024"),
        ({"max_upload_mb": 0}, "--max-upload-mb must be more than 0"),
        ({"max_upload_mb": -1.0}, "--max-upload-mb"),
        ({"max_upload_mb": float("nan")}, "--max-upload-mb"),
        ({"max_megapixels": 0}, "--max-megapixels"),
        ({"host": " "}, "--host"),
    ]:
        with pytest.raises(ServeOptionError, match=message):
            ServeOptions(**kwargs)
    with pytest.raises(ServeOptionError, match="max_concurrency"):
        ServeConfig(max_concurrency=0)
    assert ServeOptions(port=0).port == 0  # any free port, as a script asks for one (QA)


# ---- files written are readable per the umask ------------------------------------------------


def test_written_files_follow_the_umask(tmp_path: Path):
    from lookfeel.atomic import atomic_write_text

    old = os.umask(0o022)
    try:
        assert atomic_write_text(tmp_path / "a.txt", "x").stat().st_mode & 0o777 == 0o644
        os.umask(0o077)
        assert atomic_write_text(tmp_path / "b.txt", "x").stat().st_mode & 0o777 == 0o600
        os.umask(0o002)
        assert atomic_write_text(tmp_path / "c.txt", "x").stat().st_mode & 0o777 == 0o664
    finally:
        os.umask(old)


def test_a_replaced_file_keeps_its_mode_and_a_read_only_one_is_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """QA: an existing output was replaced with the umask's mode (a 0440 checkpoint became
    0644), and one its owner made read-only was replaced too; ``open(path, "w")``, which the
    writes promise to match, keeps the mode and refuses the read-only file."""
    from lookfeel import atomic

    mine = tmp_path / "mine.txt"
    mine.write_text("old", encoding="utf-8")
    mine.chmod(0o640)
    old = os.umask(0o002)
    try:
        assert atomic.atomic_write_text(mine, "new").stat().st_mode & 0o777 == 0o640
    finally:
        os.umask(old)
    # Read-only for this user (the tests run as root, whom the system lets write anything: the
    # check asks os.access as it would answer another user).
    real = os.access
    monkeypatch.setattr(
        atomic.os, "access", lambda p, m, **k: False if Path(p) == mine else real(p, m, **k)
    )
    with pytest.raises(PermissionError) as e:
        atomic.atomic_write_text(mine, "newer")
    assert e.value.filename == str(mine) and "read-only" in str(e.value.strerror)
    assert mine.read_text(encoding="utf-8") == "new" and [p.name for p in tmp_path.iterdir()] == [
        "mine.txt"
    ]


def test_a_failed_write_names_the_file_and_leaves_the_old_one(tmp_path: Path):
    """QA: on a full disk every writer ended in a traceback naming a hidden temp file, or
    torch's own ``unexpected pos`` error naming nothing: the error names the destination
    (the command line prints it as one line), the old file is kept and no temp is left."""
    import errno

    from lookfeel.atomic import atomic_write, atomic_write_text

    out = tmp_path / "e.npz"
    atomic_write_text(out, "old")

    def full(f):
        f.write(b"partial")
        raise OSError(errno.ENOSPC, "No space left on device")

    def torch_short(f):
        raise RuntimeError(
            "[enforce fail at inline_container.cc:672] . unexpected pos 113920 vs 113816"
        )

    with pytest.raises(OSError) as e:
        atomic_write(out, full)
    assert (e.value.errno, e.value.filename) == (errno.ENOSPC, str(out))
    with pytest.raises(OSError) as e:
        atomic_write(out, torch_short)
    assert e.value.filename == str(out) and "is the disk full?" in str(e.value.strerror)
    assert out.read_text(encoding="utf-8") == "old" and [p.name for p in tmp_path.iterdir()] == [
        "e.npz"
    ]
    with pytest.raises(RuntimeError, match="a bug"):  # any other error is not the disk's
        atomic_write(out, lambda f: (_ for _ in ()).throw(RuntimeError("a bug")))


def test_a_long_file_name_gets_a_temp_name_that_fits(tmp_path: Path):
    """QA: a legal 244-character --out failed after all the work with 'File name too long',
    naming the temp file (``.NAME.XXXXXXXX.tmp`` is 14 bytes longer than NAME)."""
    from lookfeel.atomic import _temp_prefix, atomic_write_text, remove_stale_temps

    name = "e" * 240 + ".npz"
    assert atomic_write_text(tmp_path / name, "x").read_text(encoding="utf-8") == "x"
    assert [p.name for p in tmp_path.iterdir()] == [name]
    stale = tmp_path / f"{_temp_prefix(name)}abcd1234.tmp"  # a killed write's leftover
    stale.write_text("half", encoding="utf-8")
    assert len(stale.name.encode()) <= 255
    assert remove_stale_temps(tmp_path / name) == [stale]
    short = tmp_path / "last.pt"
    (tmp_path / ".last.pt.x1y2z3w4.tmp").write_text("half", encoding="utf-8")
    assert remove_stale_temps(short) == [tmp_path / ".last.pt.x1y2z3w4.tmp"]


def test_an_interrupted_command_is_written_again_into_its_folder_leaving_no_temp(
    run, tmp_path: Path, capsys
):
    """QA: an evaluation stopped after its first figures (no metrics.json yet) could not be
    run again into its folder ("not a lookfeel evaluation report"), and the temp files of
    writes killed midway stayed for good after a rerun (only train and index build removed
    theirs)."""
    data, ckpt = run
    out = tmp_path / "ev"
    assert evaluate_cli(ckpt, data, out) == 0
    (out / "metrics.json").unlink()  # as a rewrite stopped before its numbers leaves it
    (out / "report.md").unlink()
    stale = [out / ".metrics.json.ab12cd34.tmp", out / "figures" / ".presses.png.x_y1z2w3.tmp"]
    for f in stale:
        f.write_bytes(b"half")
    mine = out / ".my_notes.tmp"  # not a temp name of lookfeel's: kept
    mine.write_text("mine", encoding="utf-8")
    capsys.readouterr()
    assert evaluate_cli(ckpt, data, out) == 0, capsys.readouterr().err
    assert (out / "metrics.json").is_file() and not any(f.exists() for f in stale)
    assert mine.read_text(encoding="utf-8") == "mine"
    e = tmp_path / "e.npz"
    (tmp_path / ".e.npz.qwerty12.tmp").write_bytes(b"half")
    assert main(["embed", "--checkpoint", str(ckpt), "--data", str(data), "--out", str(e)]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["e.npz", "ev"]


def test_a_report_is_readable_by_the_group(run, tmp_path: Path, capsys):
    data, ckpt = run
    old = os.umask(0o022)
    try:
        assert evaluate_cli(ckpt, data, tmp_path / "ev") == 0
    finally:
        os.umask(old)
    files = [p for p in (tmp_path / "ev").rglob("*") if p.is_file()]
    assert files and all(p.stat().st_mode & 0o777 == 0o644 for p in files), [
        (p.name, oct(p.stat().st_mode)) for p in files
    ]


# ---- the server: bombs, headers, no paths in errors ---------------------------------------------


def test_server_refuses_a_bomb_before_decoding_sets_headers_and_hides_paths(library: Path):
    import httpx

    from lookfeel.serve import background_server, create_app

    config = ServeConfig(max_pixels=1_000_000)
    bomb = bomb_png(13000, 13000)
    with background_server(create_app(library, config)) as url:
        r = httpx.post(
            url + "/api/match",
            data={"modality": "color"},
            files=[("files", ("bomb.png", bomb, "image/png"))],
            timeout=30,
        )
        assert r.status_code == 413, r.text
        assert r.json()["detail"] == (
            "bomb.png: declares 13000x13000 pixels; at most 1 megapixels are decoded"
        )
        for response in (r, httpx.get(url + "/"), httpx.get(url + "/api/library")):
            h = response.headers
            assert h["x-content-type-options"] == "nosniff"
            assert h["x-frame-options"] == "DENY"
            assert "default-src 'self'" in h["content-security-policy"]
        damaged = b"\x89PNG\r\n\x1a\n" + bytes(100)
        r = httpx.post(
            url + "/api/match",
            data={"modality": "color"},
            files=[("files", ("x.png", damaged, "image/png"))],
        )
        assert r.status_code == 422 and "/tmp" not in r.text and "lookfeel-query" not in r.text
        assert httpx.get(url + "/api/library").json()["limits"]["max_pixels"] == 1_000_000


def test_public_messages_keep_file_names_only():
    from lookfeel.serve.app import public_message

    text = "/srv/lib/shards/depth_0000.npz: damaged; see /home/a/b/run/last.pt, or C:\\x\\y.png"
    assert public_message(text) == "depth_0000.npz: damaged; see last.pt, or y.png"


# ---- the demo shows that it is alive ------------------------------------------------------------


def test_demo_steps_are_numbered_and_every_training_run_shows_progress(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    import lookfeel.demo as demo

    seen: dict[str, object] = {}

    def fake_generate(config, out, progress):
        seen["synth_progress"] = progress
        write_tiny_dataset(out, fabrics=3)

    def fake_reproduce(world, out, **kwargs):
        seen["overrides"] = kwargs["overrides"]
        raise KeyboardInterrupt  # stop here: the rest is the real demo's (test_cli)

    monkeypatch.setattr(demo, "generate", fake_generate)
    monkeypatch.setattr(demo, "reproduce", fake_reproduce)
    lines: list[str] = []
    with pytest.raises(KeyboardInterrupt):
        demo.run_demo(
            tmp_path / "demo",
            real_data=tmp_path / "absent",
            overrides=["train.steps=2"],
            log=lines.append,
        )
    assert seen["synth_progress"] is True
    cache = f'data.cache_dir="{tmp_path / "demo" / "cache"}"'  # the runs share decoded images
    assert seen["overrides"] == ["train.progress=true", cache, "train.steps=2"]  # the user's win
    steps = [ln for ln in lines if ln.startswith("[")]
    assert [s[:4] for s in steps] == ["[1/5", "[2/5", "[3/5"], lines
    assert steps[0].endswith(
        f"No real data at {tmp_path / 'absent'} (--data) to summarise: on to the synthetic world."
    )
    assert " min] Generating a synthetic world of 150 fabrics (50 held out)" in steps[1]


def test_the_demo_cache_is_in_its_folder_whatever_the_folder_is_called(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """An override's value is YAML: a folder named "demo #1: a" must not become "demo"."""
    import lookfeel.demo as demo
    from lookfeel.config import RunConfig, load_config
    from lookfeel.config.recipes import recipe_path

    out = tmp_path / "demo #1: a"
    seen: dict[str, list[str]] = {}

    def fake_reproduce(world, where, **kwargs):
        seen["overrides"] = kwargs["overrides"]
        raise KeyboardInterrupt

    monkeypatch.setattr(demo, "generate", lambda c, w, progress: write_tiny_dataset(w, fabrics=3))
    monkeypatch.setattr(demo, "reproduce", fake_reproduce)
    with pytest.raises(KeyboardInterrupt):
        demo.run_demo(out, fabrics=9, log=lambda line: None)
    config = load_config(RunConfig, recipe_path("synth_cross.yaml"), seen["overrides"])
    assert config.data.cache_dir == str(out / "cache")


def test_a_new_demo_world_starts_the_runs_made_on_the_old_one_afresh(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """Runs trained and scored on another world must not be resumed or reported as done."""
    import lookfeel.demo as demo

    out = tmp_path / "demo"
    for rel in ("cross/checkpoints/last.pt", "reproduce/flat-s0/eval.json", "cache/x.npy"):
        (out / rel).parent.mkdir(parents=True)
        (out / rel).write_text("from the old world", encoding="utf-8")
    (out / "notes.txt").write_text("mine", encoding="utf-8")
    seen: dict[str, list[str]] = {}

    def fake_generate(config, world, progress):
        write_tiny_dataset(world, fabrics=3)

    def fake_reproduce(world, where, **kwargs):
        seen["left"] = sorted(p.name for p in out.iterdir())
        raise KeyboardInterrupt

    monkeypatch.setattr(demo, "generate", fake_generate)
    monkeypatch.setattr(demo, "reproduce", fake_reproduce)
    lines: list[str] = []
    with pytest.raises(KeyboardInterrupt):
        demo.run_demo(out, fabrics=9, log=lines.append)
    assert seen["left"] == ["notes.txt", "world"]
    assert any("starting reproduce/, cross/, cache/ afresh" in ln for ln in lines), lines


def test_demo_refuses_a_split_it_cannot_evaluate_before_writing_anything(tmp_path: Path):
    import lookfeel.demo as demo

    for held in (1, 7):
        with pytest.raises(ConfigError, match=f"8 fabrics with {held} held out"):
            demo.run_demo(tmp_path / "demo", fabrics=8, test_fabrics=held, log=lambda line: None)
    assert not (tmp_path / "demo").exists()


# ---- match on an image of the library ----------------------------------------------------------


def test_match_on_a_library_image_names_its_fabric(library: Path, run, capsys):
    from lookfeel.index import Matcher
    from lookfeel.modality import Modality

    data, _ = run
    image = data / "depth" / "F0004_Depth_New_000001.png"
    assert main(["match", "--index", str(library), "--modality", "depth", str(image)]) == 0
    out = capsys.readouterr().out
    assert "fabric 4: the query is library item depth:" in out, out
    matcher = Matcher(Library.open(library))
    r = matcher.match_files([image], Modality.DEPTH)[0]
    assert r.known and r.message.startswith("fabric 4: the query is library item depth:")
    # A library item matched as a query leaves itself out: no identity, the usual verdict.
    item = next(
        i
        for i in (matcher.library.table(Modality.DEPTH).item(k) for k in range(50))
        if i.path == str(image)
    )
    r = matcher.match_item(item.id)
    assert "the query is library item" not in r.message and "chance 1/6 = 0.167" in r.message


@pytest.mark.parametrize(
    ("option", "value", "expected"),
    [
        (
            "--false-accept",
            "1.5",
            "--false-accept (target_false_accept) must be in [0, 1); got 1.5",
        ),
        ("--folds", "-1", "--folds -1: calibration needs at least 2 folds"),
    ],
)
def test_index_build_options_are_one_line(
    option: str, value: str, expected: str, run, tmp_path: Path, capsys
):
    data, ckpt = run
    argv = ["index", "build", "--checkpoint", ckpt, "--data", data, "--out", tmp_path / "lib"]
    _fails(capsys, [*argv, option, value], expected)
    assert not (tmp_path / "lib").exists()


class _Foreign:
    """An object a checkpoint must not hold: loading it would run code from the file."""


def test_a_file_that_is_not_a_checkpoint_is_one_line_with_its_reason(
    run: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    _, ckpt = run
    text = tmp_path / "notes.pt"
    text.write_text("not a checkpoint\n", encoding="utf-8")
    cut = tmp_path / "cut.pt"
    cut.write_bytes(ckpt.read_bytes()[:100])
    foreign = tmp_path / "foreign.pt"
    torch.save({"config": _Foreign(), "model": {}}, foreign)
    npz = tmp_path / "rand.npz"  # a zip archive too, not torch's
    np.savez(npz, a=np.zeros(3))
    for path, reason in (
        (text, "it begins as neither a zip archive nor a pickle"),
        (cut, "(a damaged PyTorch checkpoint: its zip archive cannot be read, as when cut short)"),
        (foreign, "Unsupported global"),
        (npz, "(not a PyTorch checkpoint file: a zip archive, but not one torch.save writes"),
    ):
        assert main(["predict", "--checkpoint", str(path), str(tmp_path / "q.png")]) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1, err
        assert f"{path.name}: not a readable checkpoint" in err[0] and reason in err[0]
        assert "weights_only" not in err[0]  # torch's advice to run the file's code: never
        assert "enforce fail" not in err[0] and "Reader" not in err[0]  # torch's internals


def test_predict_names_a_missing_file_before_asking_what_it_shows(
    run: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    from lookfeel.config import RunConfig, load_config
    from lookfeel.train import train

    data, _ = run
    steps = ["train.steps=2", "train.val_every=0", "train.checkpoint_every=0"]
    config = load_config(RunConfig, TINY, [*steps, "model.num_properties=auto"])
    ckpt = train(config, data, tmp_path / "run").last_checkpoint  # three senses, with heads
    assert main(["predict", "--checkpoint", str(ckpt), str(tmp_path / "missing.png")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "missing.png: file not found" in err[0], err


def test_a_query_of_stacked_press_frames_that_is_not_an_image_says_so(tmp_path: Path):
    """With data.touch_frames a touch query is read with its press's other frames; a file that
    is no image at all is refused as such, not for the way its name is written."""
    from lookfeel.config import DataConfig
    from lookfeel.index.query import load_query_image
    from lookfeel.modality import Modality

    labels = tmp_path / "labels.csv"
    labels.write_text("fabric_id\n1\n", encoding="utf-8")
    config = DataConfig(image_size=16, touch_frames=(0, -1))
    with pytest.raises(ImageError, match=r"labels\.csv: not an image \(\.png, \.jpg, \.jpeg\)"):
        load_query_image(labels, Modality.TOUCH, config)


OUT_FOLDER_COMMANDS = [
    ["train", "--config", "c.yaml", "--data", "d"],
    ["cv", "--config", "c.yaml", "--data", "d"],
    ["reproduce", "--data", "d"],
    ["index", "build", "--checkpoint", "c.pt", "--data", "d"],
    ["evaluate", "--checkpoint", "c.pt", "--data", "d"],
    ["export", "--checkpoint", "c.pt"],
    ["demo"],
]


@pytest.mark.parametrize("command", OUT_FOLDER_COMMANDS, ids=lambda c: " ".join(c[:2]))
def test_an_out_folder_where_a_file_is_is_refused_before_any_work(
    command: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    """Each command that writes a folder refuses a file in its way at once, in one line, exit 1
    (they raised FileExistsError or NotADirectoryError when they first wrote, after their
    work; then argparse's usage error, exit 2, until session 56)."""
    notes = tmp_path / "notes.txt"
    notes.write_text("mine\n", encoding="utf-8")
    cases = (
        (notes, f"--out {notes} exists and is not a folder"),
        (notes / "run", f"--out {notes / 'run'}: {notes} is a file, not a folder to write in"),
    )
    for out, said in cases:
        assert main([*command, "--out", str(out)]) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(f"lookfeel: {said}"), err
    assert notes.read_text(encoding="utf-8") == "mine\n"


def test_embed_out_must_name_a_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    args = ["embed", "--checkpoint", "c.pt", "--data", "d", "--out", str(tmp_path)]
    assert main(args) == 1
    assert capsys.readouterr().err == (
        f"lookfeel: --out {tmp_path} is a folder; name the file to write (e.g. "
        f"{tmp_path / 'embeddings.npz'})\n"
    )


def test_strict_json_writes_null_for_every_number_that_could_not_be_measured(tmp_path: Path):
    from lookfeel.atomic import atomic_write_json

    data = {"a": float("nan"), "b": [1.5, float("inf"), {"c": -float("inf")}], "d": (2, "x")}
    path = atomic_write_json(tmp_path / "r.json", data, indent=1)
    text = path.read_text(encoding="utf-8")
    assert text.endswith("\n") and "NaN" not in text and "Infinity" not in text

    def refuse(word: str) -> None:
        raise AssertionError(f"non-strict JSON: {word}")

    assert json.loads(text, parse_constant=refuse) == {
        "a": None,
        "b": [1.5, None, {"c": None}],
        "d": [2, "x"],
    }


@pytest.mark.parametrize("name", ["q.jpg", "q.png"])
def test_an_empty_query_image_is_said_to_be_empty(library: Path, tmp_path: Path, capsys, name: str):
    """QA: ``lookfeel match`` on a 0-byte .jpg said it "does not begin as" a PNG or JPEG,
    where ``data check`` says "file is empty": the query path now says it as the check does."""
    from lookfeel.config import DataConfig
    from lookfeel.index.query import load_query_image

    empty = tmp_path / name
    empty.write_bytes(b"")
    said = _fails(capsys, ["match", "--index", library, "--modality", "color", empty], name)
    assert said == f"lookfeel: {empty}: file is empty"
    for modality in ("color", "depth"):  # the Python API, as predict reads a query
        with pytest.raises(ImageError) as e:
            load_query_image(empty, modality, DataConfig(image_size=16))
        assert str(e.value) == f"{empty}: file is empty"
