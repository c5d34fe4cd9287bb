"""A library opened while `lookfeel index build` swaps a new one in is read whole, old or new:
`Library.open` waits for a swap a running build is making, and reads again when the library
was replaced while it read (QA: false "rebuild was stopped" and "shard missing" errors)."""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

from lookfeel.index import Library, LibraryError
from lookfeel.index import library as library_module

from ._library import tiny_library


@pytest.fixture(scope="module")
def library(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tiny_library(tmp_path_factory, "race", shard_size=8)


def _mid_swap(library: Path, tmp_path: Path) -> tuple[Path, Path, Path]:
    """(LIB, LIB.building, LIB.replaced) as a build leaves them between its two renames: the
    previous library aside, the new one complete in the work folder, none at LIB."""
    out, work, aside = tmp_path / "lib", tmp_path / "lib.building", tmp_path / "lib.replaced"
    shutil.copytree(library, aside)
    shutil.copytree(library, work)
    return out, work, aside


@contextmanager
def _build_lock(out: Path) -> Iterator[int]:
    """Hold ``LIB.lock`` as a running build does (exclusive flock, the PID in it)."""
    fd = os.open(out.with_name(out.name + ".lock"), os.O_RDWR | os.O_CREAT, 0o666)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        os.pwrite(fd, f"{os.getpid()}\n".encode("ascii"), 0)
        yield fd
    finally:
        os.close(fd)  # releases the lock if still held


def test_an_open_during_a_running_swap_waits_for_it_and_reads_the_new_library(
    library: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    out, work, aside = _mid_swap(library, tmp_path)
    lock = tmp_path / "lib.lock"
    # No build holds the lock (a killed build's file, with its PID): the rebuild was stopped.
    lock.write_text("99999\n", encoding="utf-8")
    with pytest.raises(LibraryError, match=r"stopped while moving the new library in \(it is "):
        Library.open(out)
    lock.unlink()
    with pytest.raises(LibraryError, match=r"stopped while moving the new library in \(it is "):
        Library.open(out)

    # A build holds it: open waits for the swap, which the "build" finishes once open has
    # seen its lock held (no timing: the order is forced).
    seen = threading.Event()
    real_held = getattr(library_module, "is_held", lambda path: False)  # (before the fix: none)

    def held(path: Path) -> bool:
        got = real_held(path)
        if got:
            seen.set()
        return got

    monkeypatch.setattr(library_module, "is_held", held, raising=False)
    with _build_lock(out) as fd:

        def finish_swap() -> None:
            seen.wait(30)
            os.rename(work, out)
            shutil.rmtree(aside)
            lock.unlink()
            fcntl.flock(fd, fcntl.LOCK_UN)

        builder = threading.Thread(target=finish_swap)
        builder.start()
        try:
            opened = Library.open(out)
        finally:
            seen.set()
            builder.join()
    assert seen.is_set() and opened.root == out
    assert len(opened) == len(Library.open(library))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["lib"]

    # A build that holds the lock but does not finish the swap in time: said, not "stopped".
    out, work, aside = _mid_swap(library, tmp_path / "slow")
    monkeypatch.setattr(library_module, "SWAP_WAIT", 0.0)
    with _build_lock(out), pytest.raises(LibraryError) as e:
        Library.open(out)
    assert str(e.value) == (
        f"{out}: not found: a `lookfeel index build` running now is moving a new library in "
        f"(it holds {out}.lock) and has not finished in 0 s; open it again when that build ends"
    )


def _swapped_at_first_read(
    out: Path, monkeypatch: pytest.MonkeyPatch, new_manifest: dict[str, Any] | None = None
) -> list[Path]:
    """Make a build swap a new library in at ``out`` as `Library.open` reads its first shard:
    without ``new_manifest``, the old folder is renamed away as the shard is opened (it is gone)
    and the new one, the same, moved in right after; with it, the new library (that manifest)
    is in place before the shard is opened, so the read finds the new library's shard.
    Returns the shards read."""
    real = library_module.read_shard
    reads: list[Path] = []

    def swap(aside: Path) -> None:
        new = shutil.copytree(aside, out.with_name(out.name + ".building"))
        if new_manifest is not None:
            (new / "manifest.json").write_text(json.dumps(new_manifest), encoding="utf-8")
        os.rename(new, out)
        shutil.rmtree(aside)

    def read_shard(path: Path, key: str | None = None) -> Any:
        reads.append(path)
        if len(reads) > 1:
            return real(path, key)
        aside = out.with_name(out.name + ".replaced")
        os.rename(out, aside)
        if new_manifest is not None:
            swap(aside)
            return real(path, key)
        got = real(path, key)
        swap(aside)
        return got

    monkeypatch.setattr(library_module, "read_shard", read_shard)
    return reads


def test_a_library_replaced_while_it_is_read_is_read_again(
    library: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    shards = len(list((library / "shards").iterdir()))
    # The shard is gone when read (the old library renamed away): not "missing or damaged".
    out = shutil.copytree(library, tmp_path / "lib")
    with monkeypatch.context() as m:
        reads = _swapped_at_first_read(out, m)
        opened = Library.open(out)
    assert len(reads) == 1 + shards and len(opened) == len(Library.open(library))
    # The shards are read from the new library: the whole library is read again, not the
    # old manifest kept with the new library's files.
    out = shutil.copytree(library, tmp_path / "other")
    manifest = json.loads((out / "manifest.json").read_text(encoding="utf-8"))
    manifest["fabrics"][0]["name"] = "swapped in"
    with monkeypatch.context() as m:
        reads = _swapped_at_first_read(out, m, manifest)
        opened = Library.open(out)
    first = int(manifest["fabrics"][0]["id"])
    assert len(reads) == 2 * shards and opened.fabrics[first].name == "swapped in"


def test_a_damaged_shard_is_still_reported_at_once(
    library: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    out = shutil.copytree(library, tmp_path / "lib")
    (out / "shards/depth-00001.npz").write_bytes(b"damaged")
    real = library_module.read_shard
    reads: list[Path] = []

    def read_shard(path: Path, key: str | None = None) -> Any:
        reads.append(path)
        return real(path, key)

    monkeypatch.setattr(library_module, "read_shard", read_shard)
    with pytest.raises(LibraryError, match=r"depth-00001.npz: shard missing or damaged"):
        Library.open(out)
    assert [p.name for p in reads] == ["depth-00000.npz", "depth-00001.npz"]  # read once
