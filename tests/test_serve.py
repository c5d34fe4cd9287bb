"""The web app on a loopback server: page, API, limits, errors, bounded concurrency, CLI."""

from __future__ import annotations

import dataclasses
import io
import json
import re
import socket
import threading
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import httpx
import numpy as np
import pytest
import torch
from PIL import Image

from lookfeel.cli import main
from lookfeel.index import Library, Matcher, MatchFailure, MatchResult, build_library
from lookfeel.modality import Modality
from lookfeel.serve import ServeConfig, background_server, create_app


class _CountingMatcher(Matcher):
    """Records how many queries are inside the model at once."""

    def __init__(self, library: Library) -> None:
        super().__init__(library)
        self.lock = threading.Lock()
        self.inside = 0
        self.most = 0
        self.calls = 0

    def embed(self, x: torch.Tensor, modality: Modality) -> np.ndarray:
        with self.lock:
            self.inside += 1
            self.calls += 1
            self.most = max(self.most, self.inside)
        time.sleep(0.05)  # hold the model long enough for requests to pile up
        try:
            return super().embed(x, modality)
        finally:
            with self.lock:
                self.inside -= 1


@pytest.fixture(scope="module")
def server(
    run: tuple[Path, Path], tmp_path_factory: pytest.TempPathFactory
) -> Iterator[tuple[str, _CountingMatcher]]:
    data, ckpt = run
    out = tmp_path_factory.mktemp("serve") / "lib"
    build_library(ckpt, data, out, shard_size=64)
    library = Library.open(out)
    matcher = _CountingMatcher(library)
    config = ServeConfig(max_upload_bytes=20_000, max_files=3, max_concurrency=1)
    with background_server(create_app(library, config, matcher)) as url:
        yield url, matcher


def _file(path: Path, name: str | None = None, mime: str = "image/png") -> tuple:
    return ("files", (name or path.name, path.read_bytes(), mime))


def test_page_is_self_contained(server):
    url, _ = server
    page = httpx.get(url + "/")
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
    html = page.text
    assert '<input id="files" name="files" type="file"' in html
    for asset in re.findall(r'(?:src|href)="([^"]+)"', html):
        assert asset.startswith("/"), f"external asset {asset}"  # no CDN: no internet here
        assert httpx.get(url + asset).status_code == 200
    assert "http" not in httpx.get(url + "/static/app.js").text
    assert httpx.get(url + "/static/../../etc/passwd").status_code == 404
    assert httpx.get(url + "/docs").status_code == 404  # Swagger UI would load a CDN


def test_openapi_describes_the_api(server):
    url, _ = server
    schema = httpx.get(url + "/openapi.json").json()
    assert set(schema["paths"]) == {
        "/api/library", "/api/fabrics", "/api/items/{item_id}", "/api/items/{item_id}/image",
        "/api/match", "/api/match/item",
    }  # fmt: skip
    match = schema["paths"]["/api/match"]["post"]
    assert {"413", "415", "422", "503"} <= set(match["responses"])
    assert "multipart/form-data" in match["requestBody"]["content"]
    schemas = schema["components"]["schemas"]
    assert {"MatchEntry", "FabricMatch", "ItemRef", "PropertyEstimate"} <= set(schemas)
    # A result names its files and gives its properties as `lookfeel predict` does; it is a
    # `MatchResult`'s fields and the `error` of a file that could not be used (null if matched).
    result = schemas["MatchEntry"]["properties"]
    assert list(result) == [f.name for f in dataclasses.fields(MatchResult)] + ["error"]
    assert {"path", "paths"} <= set(result) and "query" not in result
    assert result["error"]["anyOf"] == [{"type": "string"}, {"type": "null"}]
    assert result["known"]["anyOf"] == [{"type": "boolean"}, {"type": "null"}]
    assert result["path"] == {"type": "string", "title": "Path"}
    by_label = result["properties"]
    assert by_label["type"] == "object"
    assert by_label["additionalProperties"] == {"$ref": "#/components/schemas/PropertyEstimate"}
    assert list(schemas["PropertyEstimate"]["properties"]) == [
        "value", "probability", "probabilities", "number", "std", "fabrics",
    ]  # fmt: skip
    assert "fabric_id" in schemas["FabricInfo"]["properties"]


def test_library_fabrics_and_item_images(server):
    url, matcher = server
    info = httpx.get(url + "/api/library").json()
    assert info["fabrics"] == 6 and info["items"] == {"depth": 18, "color": 18, "touch": 18}
    assert info["backbone"] == "compact" and info["limits"]["max_files"] == 3
    assert info["uploads"] == info["modalities"] == ["depth", "color", "touch"]
    fabrics = httpx.get(url + "/api/fabrics", params={"per_modality": 1}).json()
    assert [f["fabric_id"] for f in fabrics] == [1, 2, 3, 4, 5, 6]  # as a match names them
    assert "id" not in fabrics[0]  # an `id` is an item's (depth:6)
    assert fabrics[2]["items"] == {"depth": ["depth:6"], "color": ["color:6"], "touch": ["touch:6"]}
    item = httpx.get(url + "/api/items/touch:6").json()
    assert item["fabric_id"] == 3 and item["file"] == "F0003_fold_02_300.png"
    assert "/" not in item["file"]  # no server folder is shown
    for item_id, mode in (("depth:6", "L"), ("color:6", "RGB"), ("touch:6", "RGB")):
        r = httpx.get(f"{url}/api/items/{item_id}/image")
        assert r.status_code == 200 and r.headers["content-type"] == "image/png"
        assert Image.open(io.BytesIO(r.content)).mode == mode
    depth = np.asarray(Image.open(io.BytesIO(httpx.get(url + "/api/items/depth:6/image").content)))
    lib = matcher.library
    assert depth.shape == (24, 24) and depth.max() > depth.min()
    assert lib.item("depth:6").fabric_id == 3
    for bad in ("depth:99", "smell:1", "..%2F..%2Fetc%2Fpasswd", "%2Fetc%2Fpasswd"):
        r = httpx.get(f"{url}/api/items/{bad}/image")
        assert r.status_code == 404, bad


def test_upload_matches_and_touch_presses_pool(run, server):
    url, _ = server
    data, _ = run
    r = httpx.post(
        url + "/api/match",
        data={"modality": "depth", "top": "3"},
        files=[_file(data / "depth/F0003_Depth_New_000001.png", "my drape.png")],
    )
    assert r.status_code == 200, r.text
    [res] = r.json()["results"]
    assert (res["path"], res["paths"]) == ("my drape.png", ["my drape.png"])
    assert "query" not in res and res["fabrics"][0]["fabric_id"] == 3
    thickness = res["properties"]["thickness_mm"]  # as `lookfeel predict` answers, by label
    assert isinstance(thickness["value"], float) and thickness["probability"] is None
    assert thickness["fabrics"] == 5 and thickness["std"] >= 0
    stiffness = res["properties"]["stiffness"]  # a rank (a class of numbers)
    assert stiffness["value"] in range(5) and stiffness["probability"] > 0
    assert len(res["fabrics"]) == 3 and res["known"] is True
    ref = res["fabrics"][0]["nearest"]["touch"][0]
    assert "/" not in ref["path"] and httpx.get(f"{url}/api/items/{ref['id']}/image").is_success
    presses = [_file(data / f"touch/F0004_fold_02_40{i}.png") for i in range(3)]
    r = httpx.post(url + "/api/match", data={"modality": "touch"}, files=presses)
    [res] = r.json()["results"]
    assert res["presses"] == 3 and len(res["fabrics"]) == 5
    r = httpx.post(url + "/api/match/item", json={"item": "color:4", "top": 2})
    [res] = r.json()["results"]
    assert r.status_code == 200 and res["query_modality"] == "color" and len(res["fabrics"]) == 2


def _png_header(width: int, height: int) -> bytes:
    """A PNG's signature and header chunk declaring ``width`` x ``height`` (no pixels)."""
    ihdr = width.to_bytes(4, "big") + height.to_bytes(4, "big") + bytes([8, 0, 0, 0, 0])
    return b"\x89PNG\r\n\x1a\n" + len(ihdr).to_bytes(4, "big") + b"IHDR" + ihdr + bytes(4)


def test_bad_uploads_get_clear_4xx(run, server):
    url, _ = server
    data, _ = run
    depth = data / "depth/F0001_Depth_New_000000.png"

    def post(fields: dict, files: list | None) -> httpx.Response:
        return httpx.post(url + "/api/match", data=fields, files=files)

    cases = [
        (post({"modality": "depth"}, [("files", ("a.txt", b"hello", "text/plain"))]), 415,
         "a.txt: not a PNG or JPEG image"),
        (post({"modality": "depth"}, [_file(data / "color/F0001_1.png")]), 422,
         "F0001_1.png: depth image is mode RGB; expected 16-bit"),
        (post({"modality": "depth"}, [("files", ("big.png", b"\x89PNG\r\n\x1a\n" + bytes(30_000),
                                                 "image/png"))]), 413,
         "big.png: larger than the 20000 bytes allowed"),
        (post({"modality": "depth"}, [_file(depth)] * 4), 413, "4 files; at most 3 per query"),
        (post({"modality": "depth"}, [("files", ("huge.png", _png_header(30_000, 20_000),
                                                 "image/png"))]), 413,
         "huge.png: declares 30000x20000 pixels; at most"),
        (post({"modality": "depth", "top": "99"}, [_file(depth)]), 422,
         "top must be between 1 and 20"),
        (post({"modality": "depth"}, [("files", ("empty.png", b"", "image/png"))]), 422,
         "empty.png: the file is empty"),
        (post({"modality": "depth"}, [("files", ("../../etc/passwd", b"\x89PNG\r\n\x1a\nxx",
                                                 "image/png"))]), 422, "passwd: cannot decode"),
        (httpx.post(url + "/api/match/item", json={"item": "touch:999"}), 404,
         "touch has no item 999"),
    ]  # fmt: skip
    for response, status, message in cases:
        assert response.status_code == status, response.text
        assert message in response.json()["detail"]
    r = post({"modality": "smell"}, [_file(depth)])
    assert r.status_code == 422 and r.json()["detail"].startswith("modality: ")
    r = post({"modality": "depth"}, None)
    assert r.status_code == 422
    big = httpx.post(
        url + "/api/match", content=b"x" * 200_000, headers={"content-type": "multipart/form-data"}
    )
    assert big.status_code == 413 and "larger than" in big.json()["detail"]

    def chunks() -> Iterator[bytes]:  # streamed without a Content-Length: counted as it comes
        yield b'--x\r\nContent-Disposition: form-data; name="modality"\r\n\r\ndepth\r\n'
        for _ in range(20):
            yield b"y" * 10_000

    streamed = httpx.post(
        url + "/api/match",
        content=chunks(),
        headers={"content-type": "multipart/form-data; boundary=x"},
    )
    assert streamed.status_code == 413, streamed.text
    assert "request is larger than 125536 bytes" in streamed.json()["detail"]


def test_of_several_files_one_that_cannot_be_used_is_answered_as_match_answers_it(run, server):
    """As ``lookfeel match`` answers each query: of several depth files, one that cannot be
    used (not a PNG, empty, a header that cannot be read, pixels cut short, the wrong kind) is
    its own entry, the keys of a result null or empty and its ``error`` the line an upload of
    it alone is refused with, as ``lookfeel match --json`` gives a failure; the others are
    matched (200). Where no file can be used, the first one's error refuses the request, as
    does one bad press of a touch query (one pooled query)."""
    from lookfeel.cli.match import _entry

    url, _ = server
    data, _ = run
    good = data / "depth/F0003_Depth_New_000001.png"
    blob = good.read_bytes()
    bad = {
        "cut.png": blob[: len(blob) // 2],  # its header whole, its pixels cut short
        "colour.png": (data / "color/F0001_1.png").read_bytes(),  # 8-bit RGB, not depth
        "header.png": b"\x89PNG\r\n\x1a\nxx",
        "a.txt": b"hello",
        "empty.png": b"",
    }

    def post(names: list[str], modality: str = "depth") -> httpx.Response:
        files = [("files", (n, bad.get(n, blob), "image/png")) for n in names]
        return httpx.post(url + "/api/match", data={"modality": modality}, files=files)

    alone = {n: post([n]) for n in bad}  # each refused whole, as before
    assert {n: r.status_code for n, r in alone.items()} == {
        "cut.png": 422, "colour.png": 422, "header.png": 422, "a.txt": 415, "empty.png": 422,
    }  # fmt: skip
    said = {n: r.json()["detail"] for n, r in alone.items()}
    assert said["cut.png"] == "cut.png: file is truncated"
    [matched] = post(["good.png"]).json()["results"]
    assert matched["error"] is None and matched["path"] == "good.png"
    for names in (["good.png", "cut.png", "colour.png"], ["header.png", "a.txt", "good.png"]):
        r = post(names)
        assert r.status_code == 200, r.text
        results = r.json()["results"]
        assert [e["path"] for e in results] == names
        for name, entry in zip(names, results, strict=True):
            assert list(entry) == list(matched)  # the same keys, in the same order
            if name == "good.png":  # matched as alone (embedded in another batch)
                ranked = [(f["fabric_id"], pytest.approx(f["probability"], abs=1e-4))
                          for f in matched["fabrics"]]  # fmt: skip
                assert [(f["fabric_id"], f["probability"]) for f in entry["fabrics"]] == ranked
                continue
            assert entry["error"] == said[name] and entry["error"].startswith(f"{name}: ")
            failure = MatchFailure(name, [name], Modality.DEPTH, said[name])
            assert entry == json.loads(json.dumps(_entry(failure)))  # `lookfeel match --json`
    r = post(["empty.png", "good.png", "good.png"])
    assert [e["error"] for e in r.json()["results"]] == [said["empty.png"], None, None]
    # No file can be used: the first one's error, whichever step found it.
    for names, status in ((["cut.png", "a.txt"], 422), (["a.txt", "cut.png", "empty.png"], 415)):
        r = post(names)
        assert r.status_code == status and r.json()["detail"] == said[names[0]], r.text
    # A touch query is one query: a press that cannot be used fails it, and it is refused.
    press = (data / "touch/F0004_fold_02_400.png").read_bytes()
    for name, status in (("cut.png", 422), ("a.txt", 415)):
        files = [("files", ("p.png", press, "image/png")), ("files", (name, bad[name], "x/y"))]
        r = httpx.post(url + "/api/match", data={"modality": "touch"}, files=files)
        assert r.status_code == status and r.json()["detail"].startswith(f"{name}: "), r.text


def test_concurrent_requests_share_the_model_one_at_a_time(run, server):
    url, matcher = server
    data, _ = run
    body = (data / "depth/F0002_Depth_New_000000.png").read_bytes()
    before = matcher.calls

    def one(i: int) -> int:
        files = [("files", (f"q{i}.png", body, "image/png"))]
        return httpx.post(url + "/api/match", data={"modality": "depth"}, files=files).status_code

    with ThreadPoolExecutor(6) as pool:
        statuses = list(pool.map(one, range(12)))
    assert statuses == [200] * 12
    assert matcher.calls - before == 12 and matcher.most == 1  # max_concurrency=1 held


def test_cli_serve(server, monkeypatch, capsys):
    _, matcher = server
    served: dict = {}

    def fake_serve(app, host: str, port: int, on_bound) -> None:  # the real one blocks
        served.update(app=app, host=host, port=port)
        on_bound(f"http://{host}:{port}/")

    monkeypatch.setattr("lookfeel.serve.serve", fake_serve)
    lib = str(matcher.library.root)
    assert main(["serve", "--index", lib, "--port", "8123", "--max-upload-mb", "0.5"]) == 0
    assert "at http://127.0.0.1:8123/ (Ctrl-C stops)" in capsys.readouterr().out
    assert (served["host"], served["port"]) == ("127.0.0.1", 8123)
    with background_server(served["app"]) as cli_url:
        info = httpx.get(cli_url + "/api/library").json()
    assert info["limits"]["max_upload_bytes"] == 512 * 1024 and info["fabrics"] == 6
    assert main(["serve", "--index", lib + "-missing"]) == 1
    assert "library folder not found" in capsys.readouterr().err


def test_fabrics_per_modality_out_of_range_is_422(server):
    url, _ = server
    for bad in (-5, 51):
        r = httpx.get(url + "/api/fabrics", params={"per_modality": bad})
        assert r.status_code == 422, bad
        assert r.json()["detail"] == f"per_modality must be between 0 and 50; got {bad}"
    r = httpx.get(url + "/api/fabrics", params={"per_modality": 0})
    assert r.status_code == 200
    assert r.json()[0]["items"] == {"depth": [], "color": [], "touch": []}


def test_cli_serve_on_a_busy_port_says_so_in_one_line_and_never_that_it_serves(server, capsys):
    _, matcher = server
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        args = ["serve", "--index", str(matcher.library.root), "--port", str(port)]
        assert main(args) == 1
    captured = capsys.readouterr()
    assert "Serving" not in captured.out
    assert captured.err == (
        f"lookfeel: --port {port}: 127.0.0.1:{port} is already in use (another server?); "
        "choose another --port\n"
    )


def test_serve_on_port_0_says_the_free_port_it_took(monkeypatch: pytest.MonkeyPatch):
    """QA: `serve --port 0` (a script's way to ask for any free port) was refused; it now
    binds one and says which, as the URL it serves at."""
    import uvicorn
    from fastapi import FastAPI

    from lookfeel.serve import serve

    app = FastAPI()
    said: list[str] = []
    ran: list[int] = []

    def run(self: uvicorn.Server, sockets: list[socket.socket]) -> None:  # do not block
        ran.append(sockets[0].getsockname()[1])
        self.started = True

    monkeypatch.setattr(uvicorn.Server, "run", run)
    serve(app, port=0, on_bound=said.append)
    assert ran and ran[0] > 0
    assert said == [f"http://127.0.0.1:{ran[0]}/"]


def test_a_model_reading_several_frames_of_a_press_takes_no_touch_upload(run, tmp_path: Path):
    """With ``data.touch_frames`` one uploaded image is not a press: the library says touch is
    not uploadable (the page then offers library presses only), and an upload is a 422."""
    from lookfeel.config import RunConfig, load_config
    from lookfeel.train import train

    data, _ = run
    config = load_config(
        RunConfig,
        Path(__file__).resolve().parents[1] / "configs" / "tiny.yaml",
        ["data.touch_frames=[0,1]", "train.steps=2", "train.val_every=0"],
    )
    ckpt = train(config, data, tmp_path / "run").last_checkpoint
    build_library(ckpt, data, tmp_path / "lib", shard_size=64)
    library = Library.open(tmp_path / "lib")
    with background_server(create_app(library, ServeConfig())) as url:
        info = httpx.get(url + "/api/library").json()
        assert info["modalities"] == ["depth", "color", "touch"]
        assert info["uploads"] == ["depth", "color"]
        press = next((data / "touch").glob("*.png"))
        r = httpx.post(url + "/api/match", data={"modality": "touch"}, files=[_file(press)])
        assert r.status_code == 422 and "data.touch_frames" in r.json()["detail"]
        r = httpx.post(url + "/api/match/item", json={"item": "touch:0", "top": 2})
        assert r.status_code == 200


# ---- the page under its CSP; errors in one shape; press videos --------------------------------


def test_the_page_sets_bar_widths_as_its_csp_allows(server):
    """``default-src 'self'`` blocks inline styles and scripts: a ``style`` attribute would be
    dropped (every probability bar drawn full width); a width set through ``element.style``
    is allowed."""
    url, _ = server
    page = httpx.get(url + "/")
    assert "default-src 'self'" in page.headers["content-security-policy"]
    html = page.text
    assert not re.search(r"\sstyle\s*=|<style", html, re.I)  # no inline style
    assert not re.search(r"\son\w+\s*=", html, re.I)  # no inline event handler
    assert all("src=" in tag for tag in re.findall(r"<script[^>]*>", html))  # no inline script
    js = httpx.get(url + "/static/app.js").text
    assert re.search(r"\.style\.width\s*=", js)
    assert not re.search(r"\bstyle\s*:|setAttribute\(\s*[\"']style|\.cssText|style=", js)


def test_the_file_picker_takes_what_the_server_takes(server):
    from lookfeel.data.files import VIDEO_SUFFIXES
    from lookfeel.data.layout import IMAGE_SUFFIXES

    url, _ = server
    (accept,) = re.findall(r'<input id="files"[^>]*accept="([^"]+)"', httpx.get(url + "/").text)
    suffixes = {a for a in accept.split(",") if a.startswith(".")}
    assert suffixes == {*IMAGE_SUFFIXES, *VIDEO_SUFFIXES}


def test_every_error_is_one_line_naming_the_field(server):
    """A bad field is answered as the app's own checks are (422, ``detail`` one line naming
    the field and what is wrong), not with pydantic's list of objects."""
    url, _ = server
    png = ("files", ("a.png", _png_header(4, 4), "image/png"))
    cases = [
        (httpx.post(url + "/api/match", files=[png]), "modality: field required"),
        (httpx.post(url + "/api/match", data={"modality": "smell"}, files=[png]),
         "modality: input should be 'depth', 'color' or 'touch'; got 'smell'"),
        (httpx.post(url + "/api/match", data={"modality": "depth", "top": "abc"}, files=[png]),
         "top: input should be a valid integer, unable to parse string as an integer; "
         "got 'abc'"),
        (httpx.post(url + "/api/match", data={"modality": "depth"}), "files: field required"),
        (httpx.post(url + "/api/match/item", json={"item": "depth:0", "top": 0}),
         "top: input should be greater than or equal to 1; got 0"),
        (httpx.post(url + "/api/match/item", json={"top": 2}), "item: field required"),
        (httpx.post(url + "/api/match/item", json={"item": "depth:0", "gallery": "smell"}),
         "gallery: input should be 'depth', 'color' or 'touch'; got 'smell'"),
        (httpx.post(url + "/api/match/item", content=b"{", headers={"content-type":
                                                                     "application/json"}),
         "request body: not valid JSON"),
        (httpx.get(url + "/api/fabrics", params={"per_modality": "x"}),
         "per_modality: input should be a valid integer"),
    ]  # fmt: skip
    for response, message in cases:
        assert response.status_code == 422, response.text
        detail = response.json()["detail"]
        assert isinstance(detail, str) and "\n" not in detail
        assert detail.startswith(message), detail


def test_an_error_cuts_the_values_it_echoes(server):
    url, _ = server
    long_id = "depth:" + "9" * 100_000
    for response in (
        httpx.post(url + "/api/match/item", json={"item": long_id}),
        httpx.post(url + "/api/match/item", json={"item": "smell" * 20_000 + ":1"}),
        httpx.get(url + "/api/items/" + "x" * 5_000),
        httpx.get(url + "/static/" + "y" * 5_000),
    ):
        assert response.status_code == 404, response.text[:200]
        detail = response.json()["detail"]
        assert len(response.content) < 400 and detail.count("...") == 1, detail
    r = httpx.post(url + "/api/match/item", json={"item": long_id})
    assert r.json()["detail"] == f"item id '{long_id[:79]}... is not <modality>:<row>"
    r = httpx.post(url + "/api/match/item", json={"item": "depth:0", "top": "7" * 5_000})
    assert r.status_code == 422 and len(r.content) < 400, r.text[:200]


def test_an_image_of_another_format_is_refused_saying_which_are_taken(server):
    url, _ = server
    gif, webp = io.BytesIO(), io.BytesIO()
    Image.new("RGB", (8, 8)).save(gif, format="GIF")
    Image.new("RGB", (8, 8)).save(webp, format="WEBP")
    for name, blob, kind in (("a.gif", gif, "GIF"), ("b.webp", webp, "WebP")):
        files = [("files", (name, blob.getvalue(), "image/" + kind.lower()))]
        r = httpx.post(url + "/api/match", data={"modality": "color"}, files=files)
        assert r.status_code == 415
        assert r.json()["detail"] == (
            f"{name}: not a PNG or JPEG image (a {kind} image: save it as PNG or JPEG)"
        )


def _video_library(run: tuple[Path, Path], root: Path) -> Path:
    """A library of four objects' press videos (two presses each) under the tiny model, which
    was trained on still frames and reads a press video too; its data under ``root/data``."""
    pytest.importorskip("av")
    from ._video import PRESS, object_press, write_video

    _, ckpt = run
    data = root / "data"
    (data / "videos").mkdir(parents=True)
    rows = ["object,hardness"]
    for k, name in enumerate(("cork", "pad", "sponge", "spoon")):
        rows.append(f"{name},{k % 3}")
        for n in range(2):
            write_video(data / "videos" / f"{name}_{n}.mov", object_press(k, PRESS, 14, 10 * k + n))
    (data / "labels.csv").write_text("\n".join(rows) + "\n", encoding="utf-8")
    build_library(ckpt, data, root / "lib", shard_size=64)
    return root / "lib"


def test_a_press_video_item_shows_its_deepest_frame_as_recorded(run, tmp_path: Path):
    from lookfeel.data.video import read_press

    from ._video import PRESS

    library = Library.open(_video_library(run, tmp_path))
    with background_server(create_app(library, ServeConfig())) as url:
        item = library.item("touch:0")
        assert item.image.endswith(".mov")
        r = httpx.get(url + "/api/items/touch:0/image")
        assert r.status_code == 200, r.text
        assert r.headers["content-type"] == "image/png"
        shown = np.asarray(Image.open(io.BytesIO(r.content)))
        press = read_press(item.image, subtract_reference=False)
        assert press.indices == (max(PRESS, key=PRESS.__getitem__),)  # the deepest
        assert np.array_equal(shown, press.images[0])  # raw, as recorded
        # A video that can no longer be read: 410, naming the item; what was shown is cached.
        for row in (0, 1):
            Path(library.item(f"touch:{row}").image).write_bytes(b"not a video at all")
        assert httpx.get(url + "/api/items/touch:0/image").content == r.content
        r = httpx.get(url + "/api/items/touch:1/image")
        assert r.status_code == 410
        assert r.json()["detail"].startswith("item touch:1: its file can no longer be read (")


def test_a_pooled_upload_leaves_out_a_video_without_a_press_as_match_does(run, tmp_path: Path):
    import warnings

    from ._video import object_press, write_video

    lib = _video_library(run, tmp_path)
    pressed = tmp_path / "data" / "videos" / "spoon_1.mov"
    static = write_video(tmp_path / "static.mov", object_press(3, {}, t=14))  # never pressed
    matcher = Matcher(Library.open(lib))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        (expected,) = matcher.match_files([pressed, static], Modality.TOUCH, top=3)
    (warned,) = [str(w.message) for w in caught if "left out" in str(w.message)]
    assert warned.startswith(f"{static}: no contact found")
    # All that match warns of, the tiny model's note on press videos included, names cut.
    said = [
        str(w.message).replace(str(static), "static.mov").replace(str(pressed), pressed.name)
        for w in caught
    ]

    def upload(*paths: Path) -> httpx.Response:
        files = [("files", (p.name, p.read_bytes(), "video/quicktime")) for p in paths]
        return httpx.post(url + "/api/match", data={"modality": "touch", "top": "3"}, files=files)

    with background_server(create_app(Library.open(lib), ServeConfig(), matcher)) as url:
        r = upload(pressed, static)
        assert r.status_code == 200, r.text
        body = r.json()
        assert body["warnings"] == said
        assert warned.replace(str(static), "static.mov") in said
        [res] = body["results"]
        assert res["paths"] == ["spoon_1.mov"] and res["presses"] == 1
        assert [(f["fabric_id"], f["probability"]) for f in res["fabrics"]] == [
            (f.fabric_id, f.probability) for f in expected.fabrics
        ]
        assert [w for w in upload(pressed).json()["warnings"] if "left out" in w] == []
        for query in ((static,), (static, static)):  # no press left: the first one's error
            r = upload(*query)
            assert r.status_code == 422
            assert r.json()["detail"].startswith("static.mov: no contact found")


def test_the_listening_socket_is_tcp_without_nagles_delay():
    """QA: every answer over a kept-open connection (a browser's, httpx's) waited about 40 ms
    for the client's delayed ACK: the socket was made with protocol 0, and asyncio turns off
    Nagle's delay only on connections of a socket whose protocol says TCP."""
    from lookfeel.serve.server import _bind

    sock = _bind("127.0.0.1", 0)
    try:
        assert sock.proto == socket.IPPROTO_TCP
        assert sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY) != 0
        sock.listen()
        client = socket.create_connection(sock.getsockname())
        accepted, _ = sock.accept()
        try:  # what asyncio checks before it sets TCP_NODELAY on the connection
            assert accepted.proto == socket.IPPROTO_TCP
        finally:
            accepted.close()
            client.close()
    finally:
        sock.close()


def test_an_uploaded_press_video_is_decoded_once_whether_grey_or_not(
    server, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """Whether an upload is a grey press video is known from the decoding that reads its
    press: asking again decoded one more frame of a colour or one-channel video, and the whole
    of a grey one stored as colour."""
    pytest.importorskip("av")
    from lookfeel.index.match import GREY_VIDEO

    from ._video import count_decoded_frames, grey_and_colour_presses

    _, matcher = server
    colour, grey, stored = grey_and_colour_presses(tmp_path, stored_suffix=".mp4").values()
    # frames decoded, by the suffix of the upload's copy
    decoded = count_decoded_frames(monkeypatch, by="suffix")
    with background_server(create_app(matcher.library, ServeConfig(), matcher)) as url:
        for p in (colour, grey, stored):
            r = httpx.post(
                url + "/api/match",
                data={"modality": "touch", "top": "2"},
                files=[("files", (p.name, p.read_bytes(), "video/mp4"))],
            )
            assert r.status_code == 200, r.text
            greys = [w for w in r.json()["warnings"] if GREY_VIDEO in w]
            assert greys == ([] if p == colour else [f"{p.name}: {GREY_VIDEO}"])
    assert decoded == {".mov": 14, ".mkv": 14, ".mp4": 14}  # each frame once
