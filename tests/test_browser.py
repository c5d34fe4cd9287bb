"""A real browser drives the web page: upload an image, see ranked fabrics, take a screenshot.

Headless Chromium (Debian's ``chromium`` package) is driven over the DevTools protocol on a
pipe (``--remote-debugging-pipe``: JSON messages separated by NUL bytes on file descriptors 3
and 4), so no WebDriver and no websocket client are needed. The test skips, saying why, where
no Chromium is installed. Set ``LOOKFEEL_SCREENSHOT=path.png`` to keep the screenshot.
"""

from __future__ import annotations

import base64
import contextlib
import fcntl
import json
import os
import re
import select
import shutil
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from lookfeel.index import Library, build_library
from lookfeel.serve import background_server, create_app

from ._library import tiny_run

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


def test_upload_shows_ranked_fabrics_and_their_images(browser: Browser, tmp_path: Path):
    data, ckpt = tiny_run()
    build_library(ckpt, data, tmp_path / "lib", shard_size=64)
    with background_server(create_app(Library.open(tmp_path / "lib"))) as url:
        browser.navigate(url + "/")
        browser.eval(  # what the server's Content-Security-Policy blocks from here on
            "window.blocked = []; document.addEventListener('securitypolicyviolation',"
            " (e) => window.blocked.push(e.violatedDirective + ' ' + e.blockedURI))"
        )
        assert browser.wait_for("document.querySelector('#pick').options.length") == 18
        assert "6 fabrics" in browser.eval("document.querySelector('#library').textContent")

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
        # Each probability bar is as wide as its P (an inline style the CSP blocks: all full).
        shown = browser.eval(
            "[...document.querySelectorAll('.fabric')].map(f => [f.querySelector('.p')"
            ".textContent.slice(4), f.querySelector('.bar div').getBoundingClientRect().width"
            " / f.querySelector('.bar').getBoundingClientRect().width])"
        )
        assert len(shown) == 5 and min(w for _, w in shown) < 0.9
        assert all(abs(float(p) - w) < 0.01 for p, w in shown), shown
        assert browser.eval("window.blocked") == []
        png = browser.screenshot()
        assert png.startswith(b"\x89PNG\r\n\x1a\n") and len(png) > 10_000
        (tmp_path / "serve.png").write_bytes(png)
        if target := os.environ.get("LOOKFEEL_SCREENSHOT"):
            Path(target).write_bytes(png)

        # A file that is not an image: the page shows the server's message.
        bad = tmp_path / "notes.png"
        bad.write_text("not an image")
        browser.set_files("#files", [bad])
        browser.eval("document.querySelector('#match').click()")
        status = browser.wait_for(
            "(() => { const s = document.querySelector('#status');"
            " return s.className === 'error' && s.textContent; })()"
        )
        assert status == "Error 415: notes.png: not a PNG or JPEG image"
        assert browser.eval("document.querySelectorAll('.fabric').length") == 0


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
    (data / "labels.csv").write_text("\n".join(rows) + "\n")
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
