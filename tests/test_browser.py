"""A real browser drives the web page: upload an image, see ranked fabrics, take a screenshot.

Headless Chromium (Debian's ``chromium`` package) is driven over the DevTools protocol on a
pipe (``--remote-debugging-pipe``: JSON messages separated by NUL bytes on file descriptors 3
and 4), so no WebDriver and no websocket client are needed. The tests skip, saying why, where
no Chromium is installed. Set ``LOOKFEEL_SCREENSHOT=path.png`` to keep the screenshot.

What a real server does not do on demand (fail with a plain-text 500, hang, answer a proxy's
HTML) the tests make it do through `Faults`, a wrapper around the real app that answers chosen
paths itself and records every request (so a test can tell that nothing was uploaded).
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import fcntl
import json
import os
import re
import select
import shutil
import subprocess
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from starlette.responses import HTMLResponse, JSONResponse, PlainTextResponse, Response
from starlette.types import ASGIApp, Receive, Scope, Send

from lookfeel.index import Library, build_library
from lookfeel.serve import ServeConfig, background_server, create_app

from ._library import tiny_library, tiny_run

BROWSERS = ("chromium", "chromium-browser", "google-chrome", "chrome-headless-shell")


def find_browser() -> str | None:
    """The first Chromium-family browser on PATH (``LOOKFEEL_CHROMIUM`` overrides)."""
    if os.environ.get("LOOKFEEL_CHROMIUM"):
        return os.environ["LOOKFEEL_CHROMIUM"]
    for name in BROWSERS:
        if path := shutil.which(name):
            return path
    return None


class Browser:
    """Headless Chromium and one page, driven over the DevTools protocol on a pipe."""

    def __init__(self, binary: str, profile: Path, width: int = 1200, height: int = 1000) -> None:
        to_browser_r, self._write = os.pipe()
        self._read, from_browser_w = os.pipe()
        # Move the child's ends above 9 so that putting them on 3 and 4 cannot clobber either.
        child_r = fcntl.fcntl(to_browser_r, fcntl.F_DUPFD_CLOEXEC, 10)
        child_w = fcntl.fcntl(from_browser_w, fcntl.F_DUPFD_CLOEXEC, 10)
        os.close(to_browser_r)
        os.close(from_browser_w)

        def wire_pipes() -> None:  # in the child: the protocol's fixed descriptors 3 and 4
            os.dup2(child_r, 3)
            os.dup2(child_w, 4)

        args = [
            binary, "--headless", "--no-sandbox", "--disable-gpu", "--remote-debugging-pipe",
            f"--user-data-dir={profile}", "--no-first-run", "--disable-extensions",
            "--disable-background-networking", "--disable-dev-shm-usage", "about:blank",
        ]  # fmt: skip
        self.process = subprocess.Popen(
            args,
            pass_fds=(3, 4),  # kept open past close_fds, which runs after preexec_fn
            preexec_fn=wire_pipes,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        os.close(child_r)
        os.close(child_w)
        self._buffer = b""
        self._next_id = 0
        self.session: str | None = None
        target = self.call("Target.createTarget", url="about:blank")["targetId"]
        self.session = self.call("Target.attachToTarget", targetId=target, flatten=True)[
            "sessionId"
        ]
        self.call("Emulation.setDeviceMetricsOverride", width=width, height=height,
                  deviceScaleFactor=1, mobile=False)  # fmt: skip

    def call(self, method: str, timeout: float = 30.0, **params: Any) -> dict[str, Any]:
        """Send one command and wait for its answer (events in between are dropped)."""
        self._next_id += 1
        msg: dict[str, Any] = {"id": self._next_id, "method": method, "params": params}
        if self.session is not None and not method.startswith(("Target.", "Browser.")):
            msg["sessionId"] = self.session
        os.write(self._write, json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while True:
            while b"\0" in self._buffer:
                raw, self._buffer = self._buffer.split(b"\0", 1)
                reply = json.loads(raw)
                if reply.get("id") == self._next_id:
                    if "error" in reply:
                        raise RuntimeError(f"{method}: {reply['error']}")
                    result: dict[str, Any] = reply.get("result", {})
                    return result
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self._read], [], [], left)[0]:
                raise TimeoutError(f"no answer to {method} in {timeout} s")
            chunk = os.read(self._read, 1 << 20)
            if not chunk:
                raise RuntimeError("the browser closed the DevTools pipe")
            self._buffer += chunk

    def eval(self, expression: str) -> Any:
        """Evaluate JavaScript in the page; return its (JSON) value."""
        r = self.call("Runtime.evaluate", expression=expression, returnByValue=True)
        if "exceptionDetails" in r:
            raise RuntimeError(f"{expression}: {r['exceptionDetails']}")
        return r["result"].get("value")

    def wait_for(self, expression: str, timeout: float = 30.0) -> Any:
        """Poll a JavaScript expression until it is truthy; return its value."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if value := self.eval(expression):
                return value
            time.sleep(0.05)
        raise TimeoutError(f"{expression!r} stayed false for {timeout} s")

    def navigate(self, url: str) -> None:
        self.call("Page.navigate", url=url)
        self.wait_for("document.readyState === 'complete'")

    def set_files(self, selector: str, paths: list[Path]) -> None:
        """Choose files in an ``<input type=file>``, as a user would."""
        root = self.call("DOM.getDocument")["root"]["nodeId"]
        node = self.call("DOM.querySelector", nodeId=root, selector=selector)["nodeId"]
        self.call("DOM.setFileInputFiles", nodeId=node, files=[str(p) for p in paths])

    def described(self, selector: str) -> tuple[str, str]:
        """The accessible name and description Chromium computes for an element (what a
        screen reader says of it)."""
        root = self.call("DOM.getDocument")["root"]["nodeId"]
        node = self.call("DOM.querySelector", nodeId=root, selector=selector)["nodeId"]
        (ax, *_) = self.call("Accessibility.getPartialAXTree", nodeId=node, fetchRelatives=False)[
            "nodes"
        ]
        return ax.get("name", {}).get("value", ""), ax.get("description", {}).get("value", "")

    @contextlib.contextmanager
    def phone(self, width: int) -> Iterator[None]:
        """Show the page as a phone ``width`` CSS pixels wide, then as the desktop again."""
        self.call("Emulation.setDeviceMetricsOverride", width=width, height=740,
                  deviceScaleFactor=1, mobile=True)  # fmt: skip
        try:
            yield
        finally:
            self.call("Emulation.setDeviceMetricsOverride", width=1200, height=1000,
                      deviceScaleFactor=1, mobile=False)  # fmt: skip

    @contextlib.contextmanager
    def offline(self) -> Iterator[None]:
        """No network for the page (every fetch fails, as when the server has stopped)."""
        self.call("Network.enable")
        self.call("Network.emulateNetworkConditions", offline=True, latency=0,
                  downloadThroughput=-1, uploadThroughput=-1)  # fmt: skip
        try:
            yield
        finally:
            self.call("Network.emulateNetworkConditions", offline=False, latency=0,
                      downloadThroughput=-1, uploadThroughput=-1)  # fmt: skip
            self.call("Network.disable")

    def screenshot(self) -> bytes:
        return base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])

    def close(self) -> None:
        with contextlib.suppress(RuntimeError, TimeoutError, OSError):
            self.call("Browser.close", timeout=5)
        try:
            self.process.wait(5)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait(5)
        os.close(self._write)
        os.close(self._read)


HANG = "hang"
"""A `Faults` answer: none, until the test ends (a server that stopped answering)."""


class Faults:
    """The app, but a request for a path in ``answers`` gets that answer instead of the app's.

    Attributes:
        answers: path -> a response to send, or `HANG`.
        seen: ``"METHOD /path"`` of every request, in order.
    """

    def __init__(self, app: ASGIApp) -> None:
        self.app = app
        self.answers: dict[str, Response | str] = {}
        self.seen: list[str] = []
        self.release = threading.Event()  # ends every hung request (set when the test ends)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "http":
            self.seen.append(f"{scope['method']} {scope['path']}")
            answer = self.answers.get(scope["path"])
            if answer == HANG:
                while not self.release.is_set():
                    await asyncio.sleep(0.05)
                answer = PlainTextResponse("released", status_code=504)
            if isinstance(answer, Response):
                await answer(scope, receive, send)
                return
        await self.app(scope, receive, send)


@pytest.fixture(scope="module")
def library(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tiny_library(tmp_path_factory, "browser-library", shard_size=64)


@contextlib.contextmanager
def serve_faults(library: Path, config: ServeConfig | None = None) -> Iterator[tuple[str, Faults]]:
    """The real app over ``library`` behind `Faults`: its URL and the faults to set."""
    faults = Faults(create_app(Library.open(library), config))
    with background_server(faults) as url:  # type: ignore[arg-type]
        try:
            yield url, faults
        finally:
            faults.release.set()  # before the server stops: it waits for every request


def error_shown(browser: Browser) -> str:
    """The error the page shows (in its role="alert" region), once it shows one."""
    text: str = browser.wait_for("document.querySelector('#error').textContent")
    return text


def upload(browser: Browser, modality: str, files: list[Path]) -> None:
    """Choose ``files`` as ``modality`` and press Match."""
    browser.eval(f"document.querySelector('#modality').value = {json.dumps(modality)}")
    browser.set_files("#files", files)
    browser.eval("document.querySelector('#match').click()")


def cards(browser: Browser) -> int:
    n: int = browser.eval("document.querySelectorAll('.fabric').length")
    return n


@pytest.fixture(scope="module")
def browser(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Browser]:
    binary = find_browser()
    if binary is None:
        pytest.skip(
            "no Chromium found (looked for " + ", ".join(BROWSERS) + "); on Debian: "
            "apt-get install -y chromium"
        )
    b = Browser(binary, tmp_path_factory.mktemp("chromium-profile"))
    yield b
    b.close()


def test_upload_shows_ranked_fabrics_and_their_images(
    browser: Browser, library: Path, tmp_path: Path
):
    data, _ = tiny_run()
    with background_server(create_app(Library.open(library))) as url:
        browser.navigate(url + "/")
        browser.eval(  # what the server's Content-Security-Policy blocks from here on
            "window.blocked = []; document.addEventListener('securitypolicyviolation',"
            " (e) => window.blocked.push(e.violatedDirective + ' ' + e.blockedURI))"
        )
        assert browser.wait_for("document.querySelector('#pick').options.length") == 18
        assert "6 fabrics" in browser.eval("document.querySelector('#library').textContent")
        # Each library item to pick, its fabric by `fabric_id` (as /api/fabrics names it).
        pick = browser.eval("document.querySelector('#pick').options[0].text")
        assert re.fullmatch(r"fabric 1: depth \(depth:\d+\)", pick), pick

        # A depth map of fabric 3: results appear, fabric 3 first, images in every modality.
        browser.eval("document.querySelector('#modality').value = 'depth'")
        browser.set_files("#files", [data / "depth/F0003_Depth_New_000001.png"])
        browser.eval("document.querySelector('#match').click()")
        browser.wait_for("document.querySelectorAll('.fabric').length === 5")
        first = browser.eval("document.querySelector('.fabric h3').textContent")
        assert first == "#1 fabric 3"
        assert browser.eval("document.querySelector('#status').className") == "known"
        images = browser.wait_for(
            "(() => { const im = [...document.querySelectorAll('.fabric img')];"
            " return im.every(i => i.complete && i.naturalWidth > 0) && im.length; })()"
        )
        assert images == 15  # 5 fabrics x (depth, colour, touch)
        props = browser.eval("document.querySelector('.props').textContent")
        # As `lookfeel match` labels them: the likeliest fabrics' labels, not the heads'.
        assert props.startswith("Properties (the 5 likeliest fabrics weighted by P): thickness_mm ")
        # Read from `properties` by label as `lookfeel predict` gives them: a number's value
        # with its spread, a rank (a class) with its share, as `lookfeel match` prints them.
        number, rank = r"[\d.]+ ± [\d.]+", r"\d \(\d+%\)"
        assert re.fullmatch(
            rf".*: thickness_mm {number} · density {number} · stiffness {rank} · "
            rf"stretchiness {rank}",
            props,
        ), props
        # Each probability bar is as wide as its P (an inline style the CSP blocks: all full).
        shown = browser.eval(
            "[...document.querySelectorAll('.fabric')].map(f => [f.querySelector('.p')"
            ".textContent.slice(4), f.querySelector('.bar div').getBoundingClientRect().width"
            " / f.querySelector('.bar').getBoundingClientRect().width])"
        )
        assert len(shown) == 5 and min(w for _, w in shown) < 0.9
        assert all(abs(float(p) - w) < 0.01 for p, w in shown), shown
        # The bar is drawn only (its P is printed beside it); each image's caption names its
        # file (not only a hover title), and its alt does not say the caption again.
        assert (
            browser.eval("[...document.querySelectorAll('.bar')].map(b => b.ariaHidden)")
            == ["true"] * 5
        )
        figures = browser.eval(
            "[...document.querySelectorAll('.fabric figure')].map(f => [f.querySelector('img')"
            ".alt, f.querySelector('figcaption').textContent, f.querySelector('img').title])"
        )
        assert len(figures) == 15
        for alt, caption, path in figures:
            assert alt == "" and caption.endswith(Path(path).name), (alt, caption, path)
        assert browser.eval("window.blocked") == []
        png = browser.screenshot()
        assert png.startswith(b"\x89PNG\r\n\x1a\n") and len(png) > 10_000
        (tmp_path / "serve.png").write_bytes(png)
        if target := os.environ.get("LOOKFEEL_SCREENSHOT"):
            Path(target).write_bytes(png)

        # A file that is not an image: the page shows the server's message.
        # It is an error about the file: the file input says so to a screen reader.
        bad = tmp_path / "notes.png"
        bad.write_text("not an image", encoding="utf-8")
        assert browser.eval("document.querySelector('#files').ariaInvalid") is None
        browser.set_files("#files", [bad])
        browser.eval("document.querySelector('#match').click()")
        assert error_shown(browser) == "Error 415: notes.png: not a PNG or JPEG image"
        assert cards(browser) == 0
        assert browser.eval("document.querySelector('#status').textContent") == ""
        assert browser.eval("document.querySelector('#files').ariaInvalid") == "true"
        _, description = browser.described("#files")
        assert description.startswith("Error 415: notes.png: not a PNG or JPEG image")


def test_named_objects_show_by_name_with_their_words(browser: Browser, tmp_path: Path):
    pytest.importorskip("av")
    from ._video import PRESS, object_press, write_video

    _, ckpt = tiny_run()  # trained on still frames: it reads press videos too
    data = tmp_path / "objects"
    (data / "videos").mkdir(parents=True)
    objects = {  # ranks and words that repeat are classes (as `lookfeel data info` says)
        "sponge": ("0", "foam"),
        "spoon": ("2", "metal"),
        "cork": ("1", "wood"),
        "pad": ("0", "foam"),
    }
    rows = ["object,hardness,material"]
    for k, (name, (hardness, material)) in enumerate(objects.items()):
        rows.append(f"{name},{hardness},{material}")
        for n in range(2):
            write_video(data / "videos" / f"{name}_{n}.mov", object_press(k, PRESS, 14, 10 * k + n))
    (data / "labels.csv").write_text("\n".join(rows) + "\n", encoding="utf-8")
    build_library(ckpt, data, tmp_path / "lib", shard_size=64)
    with background_server(create_app(Library.open(tmp_path / "lib"))) as url:
        browser.navigate(url + "/")
        assert browser.wait_for("document.querySelector('#pick').options.length") == 4
        options = browser.eval("[...document.querySelector('#pick').options].map(o => o.text)")
        assert [o.split(":")[0] for o in options] == ["cork", "pad", "sponge", "spoon"]

        browser.eval("document.querySelector('#pick').selectedIndex = 3")  # a press of spoon
        browser.eval("document.querySelector('#match-item').click()")
        browser.wait_for("document.querySelectorAll('.fabric').length === 4")
        titles = browser.eval(
            "[...document.querySelectorAll('.fabric h3')].map(h => h.textContent)"
        )
        assert sorted(t.split(" ", 1)[1] for t in titles) == ["cork", "pad", "sponge", "spoon"]
        metas = browser.eval(
            "[...document.querySelectorAll('.fabric .meta')].map(m => m.textContent)"
        )
        assert "hardness 2 · material metal" in metas  # a rank as the whole number it is
        props = browser.eval("document.querySelector('.props').textContent")
        assert re.fullmatch(
            r"Properties \(the \d likeliest objects weighted by P[^)]*\): "
            r"hardness [012] \(\d+%\) · material (foam|metal|wood) \(\d+%\)",
            props,
        ), props


def test_the_form_says_what_each_field_is(browser: Browser, library: Path):
    with background_server(create_app(Library.open(library))) as url:
        browser.navigate(url + "/")
        browser.wait_for("document.querySelector('#pick').options.length")
        # The query form has a heading, to find it by; its fields say what they are for.
        assert browser.eval("document.querySelector('#query h2').textContent") == "Match an image"
        assert browser.described("#query")[0] == "Match an image"
        assert browser.described("#top")[0].startswith("Fabrics to show")
        name, description = browser.described("#files")
        assert name.startswith("Images or press videos")
        # The hint is the file input's description, with the server's limits in MB.
        assert description.startswith("Several touch images are the presses of one query")
        assert description.endswith("Up to 8 files a query, at most 8 MB each.")


def test_a_phone_screen_needs_no_sideways_scrolling(
    browser: Browser, library: Path, tmp_path: Path
):
    """WCAG 1.4.10 (reflow): at 360 and 320 px the cards, their images and a long file name
    (no spaces to break at) stay within the screen."""
    data, _ = tiny_run()
    long = tmp_path / ("F0003_" + "x" * 120 + ".png")
    long.write_bytes((data / "depth/F0003_Depth_New_000001.png").read_bytes())
    # How far the page, or anything in a card or the query box, reaches past its right edge
    # (the screen's width, not innerWidth: a phone zooms out to show a page wider than it).
    wide = (
        "((width) => { const out = [document.documentElement.scrollWidth - width];"
        " for (const box of document.querySelectorAll('.fabric, #query')) {"
        "   const right = box.getBoundingClientRect().right;"
        "   for (const e of box.querySelectorAll('*')) out.push("
        "     e.getBoundingClientRect().right - right); }"
        " return Math.max(...out); })"
    )
    with background_server(create_app(Library.open(library))) as url:
        for width in (360, 320):
            with browser.phone(width):
                browser.navigate(url + "/")
                browser.wait_for("document.querySelector('#pick').options.length")
                browser.eval("document.querySelector('#modality').value = 'depth'")
                browser.set_files("#files", [long])
                browser.eval("document.querySelector('#files').dispatchEvent(new Event('change'))")
                assert browser.eval("document.querySelector('#preview .file').textContent") == (
                    long.name
                )
                assert browser.eval(f"{wide}({width})") <= 0, (
                    f"the file's name spills at {width} px"
                )
                browser.eval("document.querySelector('#match').click()")
                browser.wait_for("document.querySelectorAll('.fabric').length === 5")
                browser.wait_for(
                    "[...document.querySelectorAll('.fabric img')].every(i => i.complete)"
                )
                assert long.name in browser.eval("document.querySelector('.result h2').textContent")
                assert browser.eval(f"{wide}({width})") <= 0, f"the page is wider than {width} px"


def test_an_error_answer_says_what_failed_and_clears_the_old_results(
    browser: Browser, library: Path
):
    data, _ = tiny_run()
    query = [data / "depth/F0003_Depth_New_000001.png"]
    failures = {  # what the server or a proxy answers -> what the page says
        PlainTextResponse("Internal Server Error", 500): (
            "Error: the server failed (HTTP 500 Internal Server Error)"
        ),
        JSONResponse({"detail": "internal error (RuntimeError); see the log"}, 500): (
            "Error 500: internal error (RuntimeError); see the log"
        ),
        JSONResponse({"message": "upstream failed"}, 502): (  # JSON, but not the server's
            "Error: the server failed (HTTP 502 Bad Gateway)"
        ),
        HTMLResponse("<html><body>Bad Gateway</body></html>", 502): (
            "Error: the server failed (HTTP 502 Bad Gateway)"
        ),
    }
    with serve_faults(library) as (url, faults):
        browser.navigate(url + "/")
        browser.wait_for("document.querySelector('#pick').options.length")
        assert browser.eval("document.querySelector('#error').getAttribute('role')") == "alert"
        for answer, said in failures.items():
            faults.answers.pop("/api/match", None)
            upload(browser, "depth", query)
            browser.wait_for("document.querySelectorAll('.fabric').length === 5")
            faults.answers["/api/match"] = answer
            browser.eval("document.querySelector('#match').click()")
            assert error_shown(browser) == said
            assert cards(browser) == 0  # not the last query's answer under the new error
            assert browser.eval("document.querySelector('#files').ariaInvalid") is None

        # The server has gone: said in words, and the old results are gone too.
        faults.answers.pop("/api/match")
        browser.eval("document.querySelector('#match').click()")
        browser.wait_for("document.querySelectorAll('.fabric').length === 5")
        with browser.offline():
            browser.eval("document.querySelector('#match').click()")
            said = error_shown(browser)
        assert said == "Error: cannot reach the server (is lookfeel serve still running?)"
        assert cards(browser) == 0

        # No file chosen: an error about the file input, which says so.
        browser.navigate(url + "/")
        browser.wait_for("document.querySelector('#pick').options.length")
        browser.eval("document.querySelector('#match').click()")
        assert error_shown(browser) == "Choose one or more images first."
        assert browser.eval("document.querySelector('#files').ariaInvalid") == "true"
        assert browser.described("#files")[1].startswith("Choose one or more images first.")


def test_a_server_that_stops_answering_is_given_up_on(browser: Browser, library: Path):
    data, _ = tiny_run()
    with serve_faults(library) as (url, faults):
        browser.navigate(url + "/")
        browser.wait_for("document.querySelector('#pick').options.length")
        faults.answers["/api/match"] = HANG
        browser.eval("answerTimeoutS = 0.5")  # 120 s on the page (a first query loads a model)
        upload(browser, "depth", [data / "depth/F0003_Depth_New_000001.png"])
        busy = (
            "[document.querySelector('#results').ariaBusy,"
            " document.querySelector('#match').disabled, document.querySelector('#status')"
            ".textContent]"
        )
        assert browser.eval(busy) == ["true", True, "Matching…"]
        said = error_shown(browser)
        assert said == (
            "Error: no answer from the server in 0.5 s; is lookfeel serve still running? Try again."
        )
        assert browser.eval(busy) == ["false", False, ""]


def test_the_library_is_read_or_the_page_says_why_not(browser: Browser, library: Path):
    answers = {
        JSONResponse({"detail": "no library here"}, 503): (
            "Cannot read the library: Error 503: no library here"
        ),
        PlainTextResponse("Internal Server Error", 500): (
            "Cannot read the library: Error: the server failed (HTTP 500 Internal Server Error)"
        ),
    }
    with serve_faults(library) as (url, faults):
        for answer, said in answers.items():
            faults.answers["/api/library"] = answer
            browser.navigate(url + "/")
            assert error_shown(browser) == said


def test_several_files_are_each_announced(browser: Browser, library: Path):
    data, _ = tiny_run()
    files = [data / "depth/F0003_Depth_New_000001.png", data / "depth/F0005_Depth_New_000002.png"]
    with background_server(create_app(Library.open(library))) as url:
        browser.navigate(url + "/")
        browser.wait_for("document.querySelector('#pick').options.length")
        upload(browser, "depth", files)
        browser.wait_for("document.querySelectorAll('.result').length === 2")
        said = browser.eval("document.querySelector('#status').textContent")
        verdict = r"(fabric \d \(P = [\d.]+\)|no known fabric \(best fabric \d, P = [\d.]+\))"
        assert re.fullmatch(
            rf"2 results: {files[0].name}: {verdict}; {files[1].name}: {verdict}\.", said
        ), said


def test_a_file_that_cannot_be_used_is_shown_beside_the_matched_ones(
    browser: Browser, library: Path, tmp_path: Path
):
    """Of several depth files, one the server cannot use (pixels cut short) is answered with
    its error beside the others' matches: its card names it and shows the error, as errors are
    shown; the status line counts it and says why; the matched file's card is whole."""
    data, _ = tiny_run()
    good = data / "depth/F0003_Depth_New_000001.png"
    cut = tmp_path / "cut.png"
    cut.write_bytes(good.read_bytes()[:300])
    with background_server(create_app(Library.open(library))) as url:
        browser.navigate(url + "/")
        browser.wait_for("document.querySelector('#pick').options.length")
        upload(browser, "depth", [good, cut])
        browser.wait_for("document.querySelectorAll('.result').length === 2")
        said = browser.eval("document.querySelector('#status').textContent")
        verdict = r"(fabric \d \(P = [\d.]+\)|no known fabric \(best fabric \d, P = [\d.]+\))"
        assert re.fullmatch(
            rf"2 results: {good.name}: {verdict}; cut\.png: file is truncated\.", said
        ), said
        assert browser.eval("document.querySelector('#error').textContent") == ""
        assert browser.eval("document.querySelector('#files').ariaInvalid") is None
        shown = browser.eval(
            "[...document.querySelectorAll('.result')].map(r => [r.className,"
            " r.querySelector('h2').textContent, r.querySelectorAll('.fabric').length])"
        )
        assert shown[0][0] == "result" and shown[0][2] == 5
        assert shown[1] == ["result failed", "depth query (cut.png): not matched", 0]
        why = "document.querySelector('.result.failed .why')"
        assert browser.eval(f"{why}.textContent") == "cut.png: file is truncated"
        assert browser.eval(f"getComputedStyle({why}).color") == browser.eval(
            "getComputedStyle(document.querySelector('#error')).color"
        )  # as an error is shown


def test_too_big_or_too_many_files_are_refused_before_uploading(
    browser: Browser, library: Path, tmp_path: Path
):
    data, _ = tiny_run()
    big = tmp_path / "big.png"
    big.write_bytes((data / "depth/F0003_Depth_New_000001.png").read_bytes().ljust(1_572_864))
    config = ServeConfig(max_upload_bytes=1024 * 1024, max_files=2)
    with serve_faults(library, config) as (url, faults):
        browser.navigate(url + "/")
        browser.wait_for("document.querySelector('#pick').options.length")
        assert browser.described("#files")[1].endswith("Up to 2 files a query, at most 1 MB each.")
        depth = sorted((data / "depth").iterdir())
        for files, said in [
            ([big], "Error: big.png: 1.5 MB; at most 1 MB per file"),
            (depth[:3], "Error: 3 files chosen; at most 2 per query"),
        ]:
            upload(browser, "depth", files)
            assert error_shown(browser) == said
            assert browser.eval("document.querySelector('#files').ariaInvalid") == "true"
        assert "POST /api/match" not in faults.seen
        upload(browser, "depth", depth[:2])  # within the limits: sent, and answered
        browser.wait_for("document.querySelectorAll('.result').length === 2")
        assert faults.seen.count("POST /api/match") == 1
        assert browser.eval("document.querySelector('#files').ariaInvalid") is None
