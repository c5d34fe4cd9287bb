"""What keeps ``lookfeel serve`` a safe local demo: an unexpected error answered as every other
error (JSON, security headers) and logged on the server, the Host and Origin checks
(`lookfeel.serve.server.LocalGuard`), a warning for listening beyond this machine, HEAD, one id
per item and a thumbnail cache bounded in bytes."""

from __future__ import annotations

import asyncio
import logging
import socket
from collections.abc import Iterator
from pathlib import Path

import httpx
import numpy as np
import pytest
import torch

from lookfeel.cli import main
from lookfeel.index import Library, LibraryItem, Matcher, build_library
from lookfeel.modality import Modality
from lookfeel.serve import ServeConfig, background_server, create_app
from lookfeel.serve.app import SECURITY_HEADERS


@pytest.fixture(scope="module")
def library(run: tuple[Path, Path], tmp_path_factory: pytest.TempPathFactory) -> Library:
    data, ckpt = run
    out = tmp_path_factory.mktemp("safety") / "lib"
    build_library(ckpt, data, out, shard_size=64)
    return Library.open(out)


@pytest.fixture(scope="module")
def url(library: Library) -> Iterator[str]:
    with background_server(create_app(library, ServeConfig())) as base:
        yield base


def _depth_file(run: tuple[Path, Path]) -> tuple:
    data, _ = run
    body = (data / "depth" / "F0002_Depth_New_000000.png").read_bytes()
    return ("files", ("q.png", body, "image/png"))


def _has_security_headers(r: httpx.Response) -> bool:
    return all(r.headers.get(k) == v for k, v in SECURITY_HEADERS.items())


class _Broken(Matcher):
    """A model that fails unexpectedly, naming a path of the server's disk."""

    def embed(self, x: torch.Tensor, modality: Modality) -> np.ndarray:
        raise RuntimeError("/secret/folder/model.pt exploded")


def test_an_unexpected_error_is_a_json_500_with_the_headers_and_a_logged_traceback(
    run, library: Library, caplog: pytest.LogCaptureFixture
):
    app = create_app(library, ServeConfig(), _Broken(library))
    with caplog.at_level(logging.ERROR, logger="lookfeel.serve"), background_server(app) as base:
        r = httpx.post(base + "/api/match", data={"modality": "depth"}, files=[_depth_file(run)])
    assert r.status_code == 500
    assert r.headers["content-type"] == "application/json"
    assert r.json() == {"detail": "internal error (RuntimeError); the server's log says more"}
    assert _has_security_headers(r)
    assert "secret" not in r.text
    [logged] = [x for x in caplog.records if x.name == "lookfeel.serve"]
    assert logged.getMessage() == "serve: POST /api/match failed, answered 500"
    assert logged.exc_info is not None and "exploded" in str(logged.exc_info[1])


def test_on_loopback_only_requests_naming_this_machine_are_answered(url: str):
    port = url.rsplit(":", 1)[1]
    for host in ("evil.example", f"evil.example:{port}", "127.0.0.1.evil.example", "local"):
        r = httpx.get(url + "/api/library", headers={"Host": host})
        assert r.status_code == 403, host
        assert r.json()["detail"] == (
            f"Host {host!r} is not this machine: a server on a loopback address answers only "
            "requests to localhost, 127.0.0.1 or [::1]"
        )
        assert _has_security_headers(r)
    for host in (f"localhost:{port}", "LOCALHOST", f"[::1]:{port}", "127.0.0.1:1", "127.0.0.1"):
        assert httpx.get(url + "/api/library", headers={"Host": host}).status_code == 200, host
    # HTTP/1.0 without Host (httpx always sends one)
    from lookfeel.serve.server import LocalGuard

    guard = LocalGuard(lambda *a: None, "127.0.0.1")  # type: ignore[arg-type]
    assert "Host none is not this machine" in str(guard.refusal({"method": "GET", "headers": []}))


def test_a_post_from_another_site_is_refused(run, url: str):
    origin = url  # http://127.0.0.1:PORT
    for headers, status in (
        ({"Origin": "http://evil.example"}, 403),
        ({"Origin": "null"}, 403),  # a sandboxed frame or a file:// page
        ({"Origin": origin.replace("127.0.0.1", "localhost")}, 403),  # another host name
        ({"Origin": origin}, 200),  # the page itself
        ({}, 200),  # curl, scripts
    ):
        r = httpx.post(url + "/api/match/item", json={"item": "depth:0", "top": 2}, headers=headers)
        assert r.status_code == status, (headers, r.text)
        if status == 403:
            assert r.json()["detail"].endswith(
                "is not this server: a page of another site may not send it requests"
            )
            assert _has_security_headers(r)
    evil = {"Origin": "http://evil.example"}
    r = httpx.post(  # a cross-site form needs no preflight: refused before the model runs
        url + "/api/match", data={"modality": "depth"}, files=[_depth_file(run)], headers=evil
    )
    assert r.status_code == 403
    assert httpx.get(url + "/api/library", headers=evil).status_code == 200  # GET: not checked


def test_on_another_address_any_host_is_taken_and_origin_still_checked(library: Library):
    from lookfeel.serve.server import LocalGuard

    app = create_app(library, ServeConfig())

    async def ask(bound: str, method: str, path: str, **kw: object) -> httpx.Response:
        transport = httpx.ASGITransport(app=LocalGuard(app, bound))
        async with httpx.AsyncClient(transport=transport, base_url="http://testserver") as c:
            return await c.request(method, path, **kw)  # type: ignore[arg-type]

    host = {"Host": "my-laptop.lan:8000"}
    assert asyncio.run(ask("0.0.0.0", "GET", "/api/library", headers=host)).status_code == 200
    body = {"item": "depth:0", "top": 2}
    same = {"Host": "my-laptop.lan:8000", "Origin": "http://my-laptop.lan:8000"}
    ok = asyncio.run(ask("0.0.0.0", "POST", "/api/match/item", json=body, headers=same))
    assert ok.status_code == 200, ok.text
    evil = {**host, "Origin": "http://evil.example"}
    bad = asyncio.run(ask("0.0.0.0", "POST", "/api/match/item", json=body, headers=evil))
    assert bad.status_code == 403 and "another site" in bad.json()["detail"]
    # on loopback the same Host is refused
    assert asyncio.run(ask("127.0.0.1", "GET", "/api/library", headers=host)).status_code == 403


def test_listening_beyond_this_machine_is_warned_of_with_a_url_that_opens(
    library: Library, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
):
    import uvicorn

    ran: list[int] = []

    def run(self: uvicorn.Server, sockets: list[socket.socket]) -> None:  # do not serve
        ran.append(sockets[0].getsockname()[1])
        self.started = True

    monkeypatch.setattr(uvicorn.Server, "run", run)
    lib = str(library.root)
    assert main(["serve", "--index", lib, "--host", "0.0.0.0", "--port", "0"]) == 0
    out, err = capsys.readouterr()
    assert err.count("\n") == 1 and err.startswith("lookfeel: warning: --host 0.0.0.0: ")
    assert "reachable from other machines and has no authentication" in err
    assert f"at http://127.0.0.1:{ran[0]}/ from this machine; other machines use this " in out
    assert "0.0.0.0" not in out
    assert main(["serve", "--index", lib, "--port", "0"]) == 0
    out, err = capsys.readouterr()
    assert err == "" and f"at http://127.0.0.1:{ran[1]}/ (Ctrl-C stops)" in out
    # An address this machine does not have is one error line, and no warning of a demo
    # reachable from elsewhere: it never listened (the warning comes once it is bound).
    assert main(["serve", "--index", lib, "--host", "192.0.2.1", "--port", "0"]) == 1
    out, err = capsys.readouterr()
    assert err.count("\n") == 1 and "reachable from other machines" not in err, err


def test_an_ipv4_mapped_loopback_address_is_loopback():
    from lookfeel.serve.server import is_loopback

    assert is_loopback("::ffff:127.0.0.1") and is_loopback("[::ffff:127.0.0.2]")
    assert not is_loopback("::ffff:10.0.0.1") and not is_loopback("0.0.0.0")


def test_head_is_answered_as_get_without_a_body(url: str):
    for path, mime in (
        ("/", "text/html; charset=utf-8"),
        ("/static/app.js", "text/javascript; charset=utf-8"),
        ("/api/items/depth:0/image", "image/png"),
    ):
        r = httpx.head(url + path)
        assert r.status_code == 200, path
        assert r.headers["content-type"] == mime and r.content == b""
        assert int(r.headers["content-length"]) == len(httpx.get(url + path).content)
        assert _has_security_headers(r)


def test_an_item_has_one_id(library: Library, url: str):
    assert library.item("depth:0").id == "depth:0"
    assert library.item("depth:10").id == "depth:10"
    for bad in ("depth:0 ", "depth:-1", "depth:0x1", "depth:1_0"):
        with pytest.raises(KeyError, match="is not <modality>:<row>"):
            library.item(bad)
    for bad in ("depth:+0", "depth: 0", "depth:00", "depth:01", "depth:\u0966"):
        with pytest.raises(KeyError, match="is not <modality>:<row>"):
            library.item(bad)
        for path in (f"/api/items/{bad}", f"/api/items/{bad}/image"):
            r = httpx.get(url + path)
            assert r.status_code == 404, (bad, path)
            assert r.json()["detail"] == f"item id {bad!r} is not <modality>:<row>"
    r = httpx.get(url + "/api/items/depth:" + "9" * 5000)  # int() refuses over 4300 digits
    assert r.status_code == 404 and r.json()["detail"].endswith("... is not <modality>:<row>")


def test_the_thumbnail_cache_is_bounded_in_bytes(library: Library, monkeypatch):
    import lookfeel.serve.app as app_module

    made: list[str] = []
    real = app_module._thumbnail

    def counted(item: LibraryItem, lib: Library, size: int) -> bytes:
        made.append(item.id)
        return real(item, lib, size)

    one = len(real(library.item("depth:0"), library, 256))
    monkeypatch.setattr(app_module, "_thumbnail", counted)
    for cap, expected in (
        (one, ["depth:0", "depth:1", "depth:0"]),  # depth:1 pushes depth:0 out
        (64 * 1024 * 1024, ["depth:0", "depth:1"]),  # both kept
    ):
        made.clear()
        config = ServeConfig(thumbnail_cache_bytes=cap)
        with background_server(create_app(library, config)) as base:
            for item in ("depth:0", "depth:0", "depth:1", "depth:0"):
                r = httpx.get(f"{base}/api/items/{item}/image")
                assert r.status_code == 200 and r.content.startswith(b"\x89PNG")
        assert made == expected, cap
    assert ServeConfig().thumbnail_cache_bytes == 64 * 1024 * 1024
