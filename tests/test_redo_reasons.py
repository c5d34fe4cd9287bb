"""Work done again says why: a library rebuild that embeds the finished library's shards again
names the part of their key that changed, and cv scoring a trained run again names the keys of
its kept result that differ (as after upgrading lookfeel or changing a setting)."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path
from typing import Any

import pytest

from lookfeel import __version__
from lookfeel.config import RunConfig, load_config
from lookfeel.crossval import cross_validate
from lookfeel.index import build_library

from ._tiny import write_tiny_dataset
from .test_crossval import OVERRIDES, TINY

# ---- index build ---------------------------------------------------------------------------

PREPROCESS_CHANGED = "the preprocessing changed: a newer lookfeel or other data.* settings"
EARLIER_MANIFEST = (
    "made by an earlier lookfeel, whose manifest records less of what its shards were made from"
)


def _edit_manifest(lib: Path, edit: Any) -> None:
    """Rewrite ``lib``'s manifest as ``edit(manifest)`` leaves it, every shard given a key this
    lookfeel never makes (as the library's maker made its keys otherwise)."""
    path = lib / "manifest.json"
    manifest = json.loads(path.read_text(encoding="utf-8"))
    for entry in manifest["modalities"].values():
        for shard in entry["shards"]:
            shard["key"] = "old-" + shard["key"]
    edit(manifest)
    path.write_text(json.dumps(manifest), encoding="utf-8")


def _shard_lines(printed: str) -> list[str]:
    return [line for line in printed.splitlines() if line.startswith("  shard ")]


def test_a_rebuild_says_which_part_of_the_shard_key_changed(
    run, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    source, ckpt = run
    data = Path(shutil.copytree(source, tmp_path / "data"))
    out = tmp_path / "lib"
    new = build_library(ckpt, data, out, shard_size=8, progress=True)
    assert new.redo_reason is None  # a new library: nothing to say
    assert not any("again" in line for line in _shard_lines(capsys.readouterr().out))
    manifest = json.loads((out / "manifest.json").read_text(encoding="utf-8"))
    assert set(manifest["shard_key"]) == {"checkpoint", "preprocess", "touch_frame"}
    assert all("files" in s for e in manifest["modalities"].values() for s in e["shards"])
    same = build_library(ckpt, data, out, shard_size=8, progress=True)
    assert (same.shards_reused, same.redo_reason) == (9, None)  # everything reused
    assert not any("again" in line for line in _shard_lines(capsys.readouterr().out))

    # A newer lookfeel (or other data.* settings) preprocesses otherwise: every shard, said once.
    _edit_manifest(out, lambda m: m["shard_key"].update(preprocess="0" * 16))
    redone = build_library(ckpt, data, out, shard_size=8, progress=True)
    assert (redone.shards_embedded, redone.redo_reason) == (9, f"({PREPROCESS_CHANGED})")
    lines = _shard_lines(capsys.readouterr().out)
    assert lines[:2] == [
        "  shard 1/9 shards/depth-00000.npz (8 items) embedded again (the preprocessing "
        "changed: a newer lookfeel or other data.* settings)",
        "  shard 2/9 shards/depth-00001.npz (8 items) embedded again",
    ]
    assert all(line.endswith(" embedded again") for line in lines[1:])

    # Made by a lookfeel whose manifest did not record the parts of the key: it says so.
    def earlier(m: dict[str, Any]) -> None:
        del m["shard_key"]
        for entry in m["modalities"].values():
            for shard in entry["shards"]:
                del shard["files"]

    _edit_manifest(out, earlier)
    assert build_library(ckpt, data, out, shard_size=8).redo_reason == f"({EARLIER_MANIFEST})"

    # Another checkpoint (by content) with other preprocessing: both parts named.
    def other_checkpoint(m: dict[str, Any]) -> None:
        m["checkpoint"]["sha256"] = "f" * 64
        m["shard_key"].update(checkpoint="f" * 64, preprocess="0" * 16)

    _edit_manifest(out, other_checkpoint)
    with pytest.warns(UserWarning, match="replacing the library built from"):
        both = build_library(ckpt, data, out, shard_size=8, replace=True)
    assert both.redo_reason == f"(another checkpoint; {PREPROCESS_CHANGED})"

    # One file touched: only its shard, and why; another shard size; a damaged shard file.
    os.utime(data / "depth/F0006_Depth_New_000002.png", ns=(1, 10**18))
    touched = build_library(ckpt, data, out, shard_size=8)
    assert (touched.shards_embedded, touched.redo_reason) == (1, "(the files changed)")
    bigger = build_library(ckpt, data, out, shard_size=16)
    assert bigger.redo_reason == "(another --shard-size: 16, was 8)"
    (out / "shards/color-00001.npz").unlink()
    (out / "shards/color-00001.npz").write_bytes(b"damaged")
    damaged = build_library(ckpt, data, out, shard_size=16)
    assert (damaged.shards_embedded, damaged.redo_reason) == (
        1,
        "(the library's shard file was missing or damaged)",
    )
    moved = Path(shutil.copytree(data, tmp_path / "moved"))
    with pytest.warns(UserWarning, match="replacing the library built from"):
        elsewhere = build_library(ckpt, moved, out, shard_size=16, replace=True)
    assert (elsewhere.shards_embedded, elsewhere.redo_reason) == (6, "(another data folder)")


class _Kill(Exception):
    pass


def test_a_rebuild_killed_and_run_again_still_reuses_the_finished_library_s_shards(
    run, tmp_path: Path
):
    source, ckpt = run
    data = Path(shutil.copytree(source, tmp_path / "data"))
    out = tmp_path / "lib"
    build_library(ckpt, data, out, shard_size=8)
    (data / "depth/F0006_Depth_New_000002.png").unlink()  # the last depth shard changes

    def kill(name: str, rows: int) -> None:
        raise _Kill

    with pytest.raises(_Kill):  # killed right after embedding the changed shard
        build_library(ckpt, data, out, shard_size=8, on_shard=kill)
    # The work folder's manifest lists every shard, written or not: those it lacks are still
    # the finished library's, linked, not embedded again.
    resumed = build_library(ckpt, data, out, shard_size=8)
    assert (resumed.shards_embedded, resumed.shards_reused) == (0, 9)
    assert resumed.redo_reason is None


# ---- cv ------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_tiny_dataset(tmp_path_factory.mktemp("cv") / "data", fabrics=7, drapes=3)


def test_cv_scoring_a_run_again_names_what_its_kept_result_differs_in(data: Path, tmp_path: Path):
    config = load_config(RunConfig, TINY, OVERRIDES)
    out = tmp_path / "cv"
    cross_validate(config, data, out, folds=[0], n_boot=0, log=lambda _: None)
    result = out / "seed0-fold0" / "result.json"

    def again(edit: Any) -> str:
        saved = json.loads(result.read_text(encoding="utf-8"))
        edit(saved)
        result.write_text(json.dumps(saved), encoding="utf-8")
        logs: list[str] = []
        cross_validate(config, data, out, folds=[0], n_boot=0, log=logs.append)
        assert logs[0].startswith("seed 0 fold 0: trained before, scoring again (")
        return logs[0].removeprefix("seed 0 fold 0: trained before, scoring again ")

    # Scored by an earlier lookfeel, before data.video_rotate was a config field.
    def earlier(saved: dict[str, Any]) -> None:
        del saved["key"]["config"]["data"]["video_rotate"]
        saved.pop("software", None)

    assert again(earlier) == (
        "(scored by an earlier lookfeel or with other settings: data.video_rotate 0, "
        "was not recorded)"
    )

    # Another version that scored otherwise: the first differences named, then how many more.
    def other_version(saved: dict[str, Any]) -> None:
        key = saved["key"]
        saved["software"]["lookfeel"] = "0.0.1"
        del key["config"]["data"]["video_rotate"]
        key["config"]["train"]["steps"] += 1
        key["cross_map_hubs"] += 1
        key["retired"] = True

    assert again(other_version) == (
        "(scored by lookfeel 0.0.1 or with other settings: data.video_rotate 0, was not "
        "recorded; train.steps 6, was 7; cross_map_hubs 10, was 11; and 1 more)"
    )
    assert again(lambda saved: saved.pop("key")) == (
        "(scored by an earlier lookfeel, whose result.json records no key)"
    )
    result.unlink()
    logs: list[str] = []
    cross_validate(config, data, out, folds=[0], n_boot=0, log=logs.append)
    assert logs[0] == "seed 0 fold 0: trained before, scoring again (no result.json kept)"
    # Scored again with these settings: kept, and nothing more said.
    logs.clear()
    cross_validate(config, data, out, folds=[0], n_boot=0, log=logs.append)
    assert logs[0].startswith("seed 0 fold 0: done before, kept (")
    assert json.loads(result.read_text(encoding="utf-8"))["software"]["lookfeel"] == __version__


def test_the_command_line_says_why_in_its_library_line(
    run, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    from lookfeel.cli import main

    data, ckpt = run
    out = tmp_path / "lib"
    argv = ["index", "build", "--checkpoint", str(ckpt), "--data", str(data), "--out", str(out)]
    assert main([*argv, "--shard-size", "8", "--quiet"]) == 0
    capsys.readouterr()
    _edit_manifest(out, lambda m: m["shard_key"].update(preprocess="0" * 16))
    assert main([*argv, "--shard-size", "8", "--quiet"]) == 0  # rebuilt in place
    said = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("Library ")]
    assert said and f"9 shard(s) embedded ({PREPROCESS_CHANGED}), 0 reused;" in said[0]
