"""A running server picks up a library rebuilt under it (`ServedLibrary`): requests are answered
from the old one until the new one is loaded, a rebuild that cannot be served is named and the
old one kept, and ``reload_every=0`` serves the library opened at start until the end."""

from __future__ import annotations

import json
import os
import shutil
import time
from collections.abc import Callable
from pathlib import Path

import httpx
import pytest

from lookfeel.index import Library, build_library
from lookfeel.serve import ServeConfig, ServeOptionError, background_server, create_app
from lookfeel.serve.reload import ServedLibrary

from ._tiny import write_tiny_dataset


@pytest.fixture(scope="module")
def libraries(
    run: tuple[Path, Path], tmp_path_factory: pytest.TempPathFactory
) -> tuple[Path, Path]:
    """(six fabrics, four fabrics): two complete libraries of the tiny model, made once."""
    data, ckpt = run
    root = tmp_path_factory.mktemp("reload")
    six = root / "six"
    build_library(ckpt, data, six, shard_size=64)
    fewer = write_tiny_dataset(root / "data4", fabrics=4)
    four = root / "four"
    build_library(ckpt, fewer, four, shard_size=64)
    return six, four


def _swap_in(new: Path, lib: Path) -> None:
    """Put a copy of ``new`` at ``lib`` as `lookfeel index build` swaps: two renames."""
    staged = lib.with_name(lib.name + ".building")
    shutil.copytree(new, staged)
    os.rename(lib, lib.with_name(lib.name + ".replaced"))
    os.rename(staged, lib)
    shutil.rmtree(lib.with_name(lib.name + ".replaced"))


def _served(
    library: Path, tmp_path: Path, check_every: float
) -> tuple[Path, ServedLibrary, list[str]]:
    """(LIB, its ServedLibrary, the notes it logs): a copy of ``library`` served."""
    lib = tmp_path / "lib"
    shutil.copytree(library, lib)
    notes: list[str] = []
    return lib, ServedLibrary(Library.open(lib), check_every=check_every, log=notes.append), notes


def _until(condition: Callable[[], bool], timeout: float = 30.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.05)
    return False


def test_a_running_server_serves_the_library_rebuilt_under_it(
    libraries: tuple[Path, Path], run: tuple[Path, Path], tmp_path: Path
) -> None:
    six, _ = libraries
    _, ckpt = run
    lib = tmp_path / "lib"
    shutil.copytree(six, lib)
    notes: list[str] = []
    app = create_app(lib, ServeConfig(reload_every=0.05), log=notes.append)
    with background_server(app) as url, httpx.Client(base_url=url, timeout=30) as client:
        assert client.get("/api/library").json()["fabrics"] == 6
        # the user rebuilds the library from other data while the server runs
        fewer = write_tiny_dataset(tmp_path / "data4", fabrics=4)
        with pytest.warns(UserWarning, match="replacing the library built from"):
            build_library(ckpt, fewer, lib, shard_size=64, replace=True)
        assert _until(lambda: client.get("/api/library").json()["fabrics"] == 4), notes
        assert [n for n in notes if "now serving it (4 fabrics" in n], notes
        fabrics = client.get("/api/fabrics").json()
        assert sorted(f["fabric_id"] for f in fabrics) == [1, 2, 3, 4]
        item = fabrics[0]["items"]["depth"][0]
        image = client.get(f"/api/items/{item}/image")
        assert image.status_code == 200 and image.content.startswith(b"\x89PNG")
        answer = client.post("/api/match/item", json={"item": item, "top": 3})
        assert answer.status_code == 200, answer.text
        assert {f["fabric_id"] for f in answer.json()["results"][0]["fabrics"]} <= {1, 2, 3, 4}


def test_a_rebuild_that_cannot_be_served_is_named_and_the_old_library_kept(
    libraries: tuple[Path, Path], tmp_path: Path
) -> None:
    _, four = libraries
    lib, served, notes = _served(libraries[0], tmp_path, check_every=0.01)
    damaged = tmp_path / "damaged"
    shutil.copytree(four, damaged)
    manifest = json.loads((damaged / "manifest.json").read_text(encoding="utf-8"))
    (damaged / manifest["modalities"]["depth"]["shards"][0]["file"]).write_bytes(b"not a shard")
    _swap_in(damaged, lib)
    for _ in range(5):  # several requests: tried once, named once
        time.sleep(0.02)
        now = served.current()
        served.wait(30)
    assert len(now.library.fabrics) == 6 and now.generation == 0
    assert len(notes) == 1 and "cannot be served" in notes[0], notes
    assert "shard missing or damaged" in notes[0] and "still serving" in notes[0]
    _swap_in(four, lib)  # repaired: the next rebuild is served
    assert _until(lambda: (served.current(), served.wait(30))[0].generation == 1)
    assert len(served.current().library.fabrics) == 4
    assert "now serving it (4 fabrics" in notes[-1]


def test_reload_every_0_serves_the_library_opened_at_start(
    libraries: tuple[Path, Path], tmp_path: Path
) -> None:
    _, four = libraries
    lib, served, notes = _served(libraries[0], tmp_path, check_every=0)
    _swap_in(four, lib)
    time.sleep(0.05)
    assert served.current().generation == 0 and len(served.current().library.fabrics) == 6
    served.wait(30)
    assert notes == []


@pytest.mark.parametrize("value", [-1.0, float("nan"), float("inf"), True, "2"])
def test_reload_every_must_be_seconds(value: object) -> None:
    with pytest.raises(ServeOptionError, match="reload_every must be a number of seconds"):
        ServeConfig(reload_every=value)  # type: ignore[arg-type]


def test_an_item_image_is_revalidated_so_a_rebuild_never_shows_a_stale_one(
    libraries: tuple[Path, Path], tmp_path: Path
) -> None:
    """QA: item images were cached an hour by the browser under row-number ids, so a library
    rebuilt under the server could show another fabric's image at the same id. They are now
    sent with ``no-cache`` and an ETag of the library and the item: 304 while unchanged, a new
    image once the library is another."""
    six, four = libraries
    lib = tmp_path / "lib"
    shutil.copytree(six, lib)
    app = create_app(lib, ServeConfig(reload_every=0.05), log=lambda _: None)
    with background_server(app) as url, httpx.Client(base_url=url, timeout=30) as client:
        first = client.get("/api/items/depth:0/image")
        assert first.status_code == 200 and first.headers["cache-control"] == "no-cache"
        etag = first.headers["etag"]
        assert etag.startswith('"') and etag.endswith('-256-depth:0"')
        assert client.get("/api/items/depth:1/image").headers["etag"] != etag
        for sent in (etag, f"W/{etag}", f'"other", {etag}', "*"):
            again = client.get("/api/items/depth:0/image", headers={"If-None-Match": sent})
            assert again.status_code == 304 and again.content == b"", sent
            assert again.headers["etag"] == etag
        _swap_in(four, lib)
        assert _until(lambda: client.get("/api/library").json()["fabrics"] == 4)
        fresh = client.get("/api/items/depth:0/image", headers={"If-None-Match": etag})
        assert fresh.status_code == 200 and fresh.content.startswith(b"\x89PNG")
        assert fresh.headers["etag"] != etag
