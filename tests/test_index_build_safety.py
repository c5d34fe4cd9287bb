"""Building over a library never loses it: a rebuild writes beside it and swaps the new one in
only when complete (a kill at any step leaves one usable library), one build at a time; and
bad input to `index build`/`index info` (press kinds, a damaged calibration, a file for the
library folder) is one line."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path
from typing import Any

import pytest

from lookfeel.checkpoint import read_checkpoint, save_checkpoint
from lookfeel.cli import main
from lookfeel.index import Library, LibraryError, Matcher, build_library
from lookfeel.index import build as build_module
from lookfeel.index.calibrate import Calibration, CalibrationError
from lookfeel.modality import Modality, PressKind

from ._library import tiny_library


class _Kill(Exception):
    """Stands for a kill (Ctrl-C, SIGKILL) at one step of a build."""


@pytest.fixture(scope="module")
def library(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tiny_library(tmp_path_factory, "safety", shard_size=8)


def _files(root: Path) -> dict[str, str]:
    """Every file under ``root``: its path there -> SHA-256 of its content."""
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*"))
        if p.is_file()
    }


def _beside(out: Path) -> list[str]:
    """What a build left beside ``out`` (work folder, old library, lock)."""
    return sorted(p.name for p in out.parent.iterdir() if p.name.startswith(f"{out.name}."))


def _other_checkpoint(ckpt: Path, path: Path) -> Path:
    """The same weights saved again with another step: a checkpoint of other content."""
    state = read_checkpoint(ckpt)
    state["step"] = int(state["step"]) + 1
    return save_checkpoint(path, state)


def _kill_in_calibration(monkeypatch: pytest.MonkeyPatch) -> None:
    def killed(*args: object, **kwargs: object) -> None:
        raise _Kill

    monkeypatch.setattr(build_module, "calibrate", killed)


def test_a_rebuild_from_another_checkpoint_keeps_the_library_until_it_is_complete(
    run, library: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
):
    data, ckpt = run
    out = shutil.copytree(library, tmp_path / "lib")
    before = _files(out)
    other = _other_checkpoint(ckpt, tmp_path / "other.pt")
    # Not without --replace: refused before any work, naming both checkpoints.
    with pytest.raises(LibraryError, match=r"lib: holds a finished library built from checkpoint "):
        build_library(other, data, out, shard_size=8)
    assert _files(out) == before and _beside(out) == []
    argv = ["index", "build", "--checkpoint", str(other), "--data", str(data), "--out", str(out)]
    assert main([*argv, "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "pass --replace" in err and str(other) in err and err.count("\n") == 1
    # Killed while calibrating: the finished library is as it was, and still matches.
    with monkeypatch.context() as m:
        _kill_in_calibration(m)
        with pytest.raises(_Kill), pytest.warns(UserWarning, match="replacing the library built"):
            build_library(other, data, out, shard_size=8, replace=True)
    assert _files(out) == before and _beside(out) == ["lib.building"]
    lib = Library.open(out)
    assert lib.manifest["checkpoint"]["path"] == str(ckpt)
    assert Matcher(lib).match_item("depth:0", top=1).fabrics[0].fabric_id == 1
    assert main(["index", "info", str(out)]) == 0
    assert "a rebuild is running or was stopped in" in capsys.readouterr().out
    # Run again: the new library's shards were embedded before the kill; it is swapped in.
    with pytest.warns(UserWarning, match="replacing the library built"):
        done = build_library(other, data, out, shard_size=8, replace=True)
    assert (done.shards_embedded, done.shards_reused) == (0, 9)
    assert _beside(out) == []
    assert (
        Library.open(out).manifest["checkpoint"]["sha256"]
        != json.loads((library / "manifest.json").read_text(encoding="utf-8"))["checkpoint"][
            "sha256"
        ]
    )


def test_a_rebuild_after_new_data_keeps_the_library_and_unchanged_inputs_give_the_same_files(
    run, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    _, ckpt = run
    data = shutil.copytree(run[0], tmp_path / "data")
    out = tmp_path / "lib"
    build_library(ckpt, data, out, shard_size=8)
    before = _files(out)
    again = build_library(ckpt, data, out, shard_size=8)  # the same inputs: the same bytes
    assert (again.shards_embedded, again.shards_reused) == (0, 9)
    assert _files(out) == before and _beside(out) == []
    (data / "depth/F0006_Depth_New_000002.png").unlink()
    with monkeypatch.context() as m:
        _kill_in_calibration(m)
        with pytest.raises(_Kill):
            build_library(ckpt, data, out, shard_size=8)
    assert _files(out) == before
    assert len(Library.open(out).table(Modality.DEPTH)) == 18
    resumed = build_library(ckpt, data, out, shard_size=8)
    assert (resumed.shards_embedded, resumed.shards_reused) == (0, 9)  # embedded before the kill
    assert len(Library.open(out).table(Modality.DEPTH)) == 17 and _beside(out) == []


def test_a_rebuild_with_nothing_changed_reuses_the_calibration_and_says_so(
    run, library: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
):
    data, ckpt = run
    out = shutil.copytree(library, tmp_path / "lib")
    before = json.loads((out / "manifest.json").read_text(encoding="utf-8"))
    real, seeds = build_module.calibrate, []

    def counted(*args: Any, **kwargs: Any) -> Calibration:
        seeds.append(kwargs["seed"])
        return real(*args, **kwargs)

    monkeypatch.setattr(build_module, "calibrate", counted)
    again = build_library(ckpt, data, out, shard_size=8, progress=True)
    assert (again.shards_embedded, again.shards_reused) == (0, 9)
    assert seeds == []  # not recalibrated
    after = json.loads((out / "manifest.json").read_text(encoding="utf-8"))
    assert after["calibration"] == before["calibration"] == again.calibration.to_dict()
    printed = capsys.readouterr().out
    assert f"  calibration of 9 pairs reused from {out / 'manifest.json'} (every shard" in printed
    assert "calibrating" not in printed
    # Another setting: the same shards, calibrated again, and said so before it starts.
    other = build_library(ckpt, data, out, shard_size=8, seed=1, progress=True)
    assert (other.shards_embedded, seeds) == (0, [1])
    printed = capsys.readouterr().out
    assert printed.endswith(
        "  shard 9/9 shards/touch-00002.npz (2 items)\n  calibrating 9 pairs (depth 18 items, "
        "color 18 items, touch 18 items; up to 1000 queries each, 5 folds) (again: seed 1, "
        "was 0)\n"
    )
    assert (
        json.loads((out / "manifest.json").read_text(encoding="utf-8"))["calibration"]["seed"] == 1
    )
    # Another way of calibrating (lookfeel's own version is the same between sessions).
    monkeypatch.setattr(build_module, "CALIBRATION_VERSION", build_module.CALIBRATION_VERSION + 1)
    build_library(ckpt, data, out, shard_size=8, seed=1, progress=True)
    assert seeds == [1, 1]
    assert capsys.readouterr().out.endswith(" (again: the calibration code changed)\n")
    # A library from before the manifest said what it was calibrated with (QA, upgrading).
    manifest = json.loads((out / "manifest.json").read_text(encoding="utf-8"))
    del manifest["calibration_made"]
    manifest["calibration_key"] = "0" * 40
    (out / "manifest.json").write_text(json.dumps(manifest), encoding="utf-8")
    build_library(ckpt, data, out, shard_size=8, seed=1, progress=True)
    printed = capsys.readouterr().out
    assert printed.endswith(" (again: the library was calibrated by an earlier lookfeel)\n")


def test_a_build_killed_between_the_renames_is_finished_by_the_next(
    run, library: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
):
    data, ckpt = run
    out = shutil.copytree(library, tmp_path / "lib")
    before = _files(out)
    moves: list[tuple[Path, Path]] = []
    real_move = build_module._move

    def second_move_killed(src: Path, dst: Path) -> None:
        moves.append((src, dst))
        if len(moves) == 2:
            raise _Kill
        real_move(src, dst)

    with monkeypatch.context() as m:
        m.setattr(build_module, "_move", second_move_killed)
        with pytest.raises(_Kill):
            build_library(ckpt, data, out, shard_size=8)
    assert moves == [(out, tmp_path / "lib.replaced"), (tmp_path / "lib.building", out)]
    assert not out.exists() and _files(tmp_path / "lib.replaced") == before
    with pytest.raises(LibraryError, match=r"stopped while moving the new library in \(it is "):
        Library.open(out)
    assert main(["index", "info", str(out)]) == 1
    err = capsys.readouterr().err
    assert "run `lookfeel index build` again" in err and "lib.building to" in err
    build_library(ckpt, data, out, shard_size=8)
    assert _files(out) == before and _beside(out) == []
    # Killed while removing the old library: the next build removes what is left of it.
    with monkeypatch.context() as m:
        m.setattr(build_module, "_remove_library", lambda folder: (_ for _ in ()).throw(_Kill))
        with pytest.raises(_Kill):
            build_library(ckpt, data, out, shard_size=8)
    assert _files(out) == before and _beside(out) == ["lib.replaced"]
    Library.open(out)
    build_library(ckpt, data, out, shard_size=8)
    assert _files(out) == before and _beside(out) == []


def test_one_build_at_a_time_per_library(run, tmp_path: Path):
    data, ckpt = run
    out = tmp_path / "lib"
    refused: list[str] = []

    def second_build(name: str, rows: int) -> None:
        if not refused:
            with pytest.raises(LibraryError) as e:
                build_library(ckpt, data, out, shard_size=64)
            refused.append(str(e.value))

    build_library(ckpt, data, out, shard_size=64, on_shard=second_build)
    assert refused == [
        f"{out}: another `lookfeel index build` is writing this library (PID {os.getpid()}, "
        f"lock {tmp_path / 'lib.lock'}); wait for it to end, or stop it"
    ]
    assert _beside(out) == []  # the lock is gone with its build
    (tmp_path / "lib.lock").write_text(
        "99999\n", encoding="utf-8"
    )  # left by a killed build: not held
    build_library(ckpt, data, out, shard_size=64)
    # A file of the user's by that name is in the way, never removed (QA).
    (tmp_path / "lib.lock").write_text("my notes\n", encoding="utf-8")
    with pytest.raises(LibraryError, match=r"lib.lock is in the way of the build's lock"):
        build_library(ckpt, data, out, shard_size=64)
    assert (tmp_path / "lib.lock").read_text(encoding="utf-8") == "my notes\n"


def test_unknown_press_kinds_are_one_usage_line(run, tmp_path: Path, capsys):
    data, ckpt = run
    argv = ["index", "build", "--checkpoint", str(ckpt), "--data", str(data)]
    with pytest.raises(SystemExit) as e:
        main([*argv, "--out", str(tmp_path / "lib"), "--kinds", "fold,bogus"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "argument --kinds: 'bogus' is not a press kind (choose from fold, flat, rand)" in err
    assert "Traceback" not in err and not (tmp_path / "lib").exists()


@pytest.mark.parametrize(
    "key, value, message",
    [
        ("pairs.color_to_color.c", "abc", "calibration.pairs.color_to_color.c is 'abc', not a num"),
        ("pairs.color_to_color.threshold", None, "color.threshold is None, not a number"),
        ("pairs.depth_to_touch.n_present", 1.5, "touch.n_present is 1.5, not a whole number"),
        ("pairs.depth_to_touch.mapped", "yes", "depth_to_touch.mapped is 'yes', not true or false"),
        ("pairs.depth_to_touch.query", "smell", "touch.query is 'smell', not a modality (depth,"),
        ("pairs.depth_to_touch.extra", 1, "calibration.pairs.depth_to_touch: unknown key 'extra'"),
        ("default_gallery.touch", "smell", "calibration.default_gallery.touch is 'smell', not a"),
        ("folds", "5", "calibration.folds is '5', not a whole number >= 0"),
        ("pairs", [], "calibration.pairs is [], not a mapping"),
    ],
)
def test_a_damaged_calibration_is_one_line_naming_the_manifest_and_key(
    library: Path, tmp_path: Path, capsys, key: str, value: object, message: str
):
    out = shutil.copytree(library, tmp_path / "lib")
    manifest = json.loads((out / "manifest.json").read_text(encoding="utf-8"))
    *above, last = key.split(".")
    entry = manifest["calibration"]
    for k in above:
        entry = entry[k]
    entry[last] = value
    (out / "manifest.json").write_text(json.dumps(manifest), encoding="utf-8")
    with pytest.raises(LibraryError) as e:
        Library.open(out)
    assert str(e.value).startswith(f"{out / 'manifest.json'}: ") and message in str(e.value)
    assert main(["index", "info", str(out)]) == 1
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_a_calibration_reads_back_what_it_wrote(library: Path):
    cal = Library.open(library).calibration
    assert Calibration.from_dict(json.loads(json.dumps(cal.to_dict()))) == cal
    with pytest.raises(CalibrationError, match=r"^calibration.seed: missing$"):
        Calibration.from_dict({k: v for k, v in cal.to_dict().items() if k != "seed"})


def test_info_on_a_file_says_to_give_the_folder(library: Path, tmp_path: Path, capsys):
    stray = tmp_path / "rand.npz"
    stray.write_bytes(b"PK")
    for path in (stray, library / "manifest.json"):
        assert main(["index", "info", str(path)]) == 1
        assert capsys.readouterr().err == (
            f"lookfeel: {path}: is a file, not a library folder (give the folder that holds "
            "manifest.json)\n"
        )


def test_a_build_into_the_current_folder_is_refused(
    run, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    data, ckpt = run
    (tmp_path / "lib").mkdir()
    monkeypatch.chdir(tmp_path / "lib")  # the swap would leave the shell in a removed folder
    with pytest.raises(LibraryError, match=r"^\.: is the current folder or holds it, .*\(cd "):
        build_library(ckpt, data, ".")
    assert _beside(tmp_path / "lib") == []


def test_a_link_to_a_library_keeps_pointing_at_the_rebuilt_one(run, library: Path, tmp_path: Path):
    data, ckpt = run
    real = shutil.copytree(library, tmp_path / "real")
    link = tmp_path / "lib"
    link.symlink_to(real)
    build_library(ckpt, data, link, shard_size=8)
    assert link.is_symlink() and Library.open(link).root == link
    assert sorted(p.name for p in tmp_path.iterdir()) == ["lib", "real"]


def test_press_kinds_the_data_lacks_leave_touch_out_with_a_warning(run, tmp_path: Path):
    data, ckpt = run  # fold and flat presses, no rand ones
    with pytest.warns(UserWarning, match=r"no rand presses: touch is left out of the library"):
        build_library(ckpt, data, tmp_path / "lib", kinds=[PressKind.RAND])
    assert "touch" not in Library.open(tmp_path / "lib").modalities


def test_a_rebuild_keeps_a_file_of_the_user_s_in_the_library_by_refusing(
    run, library: Path, tmp_path: Path
):
    """QA: notes put in a library folder were deleted by the next build without a word (the
    swap removes the whole old folder). A library holding files no build writes is not
    rebuilt, and says which; a library of its own files alone is."""
    data, ckpt = run
    lib = shutil.copytree(library, tmp_path / "lib")
    (lib / "NOTES.txt").write_text("which checkpoint this was", encoding="utf-8")
    before = _files(lib)
    with pytest.raises(LibraryError) as e:
        build_library(ckpt, data, lib, shard_size=8)
    assert str(e.value) == (
        f"{lib}: the library holds a file it did not write (NOTES.txt); a rebuild replaces the "
        "whole folder, so move it out first (nothing was changed)"
    )
    assert _files(lib) == before and _beside(lib) == []
    (lib / "NOTES.txt").unlink()
    build_library(ckpt, data, lib, shard_size=8)
    assert Library.open(lib).root == lib


def test_a_library_of_a_plugin_backbone_opened_without_the_plugin_says_so(
    library: Path, tmp_path: Path, capsys
):
    """QA: it said "malformed manifest ...; rebuild", which would not help: the manifest is
    whole, the plugin that registers its backbone was not loaded."""
    out = shutil.copytree(library, tmp_path / "lib")
    manifest = json.loads((out / "manifest.json").read_text(encoding="utf-8"))
    manifest["config"]["model"]["backbone"] = "lfplug_gone"
    (out / "manifest.json").write_text(json.dumps(manifest), encoding="utf-8")
    assert main(["index", "info", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.startswith(
        f"lookfeel: {out / 'manifest.json'}: its model's config does not load: model.backbone: "
        "'lfplug_gone' is not one of alexnet, compact, resnet18 (one of your own: import its "
        "module first, or name it in LOOKFEEL_PLUGINS or lookfeel --plugin"
    )
    assert "malformed" not in err and "rebuild" not in err and err.count("\n") == 1
