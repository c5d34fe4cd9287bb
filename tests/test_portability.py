"""What differs on macOS and Windows, checked here on Linux by playing the other system's part:
workers that end with a killed parent without Linux's help, a replaced file another process
holds open on Windows, the umask read once where ``/proc`` cannot tell it, a ``serve`` port
no other server can share, any text printed on an ASCII stdout, and ``lookfeel.__main__``
imported without running the command. (``--device mps`` is refused: tests/test_devices.py.)"""

from __future__ import annotations

import importlib
import io
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

import lookfeel
from lookfeel import atomic
from lookfeel.atomic import atomic_write_text, file_mode
from lookfeel.processes import die_with_parent
from tests._processes import alive

ROOT = Path(__file__).resolve().parents[1]


def _env() -> dict[str, str]:
    """The environment of a child Python: this lookfeel and this ``tests`` package."""
    paths = [str(Path(lookfeel.__file__).resolve().parents[1]), str(ROOT)]
    old = os.environ.get("PYTHONPATH")
    return dict(os.environ, PYTHONPATH=os.pathsep.join([*paths, *([old] if old else [])]))


def _worker_as_on_windows(parent: int) -> None:
    """`die_with_parent` as a worker on Windows has it: ``getppid`` keeps naming the parent
    after it died, and no kernel signal comes (Linux's ``PR_SET_PDEATHSIG`` is cleared)."""
    import ctypes

    os.getppid = lambda: parent
    die_with_parent(parent)
    ctypes.CDLL(None, use_errno=True).prctl(1, 0, 0, 0, 0)  # PR_SET_PDEATHSIG: none


_PARENT = """
import multiprocessing, os, time
from concurrent.futures import ProcessPoolExecutor
from tests.test_portability import _worker_as_on_windows

pool = ProcessPoolExecutor(
    1,
    mp_context=multiprocessing.get_context("spawn"),
    initializer=_worker_as_on_windows,
    initargs=(os.getpid(),),
)
print(pool.submit(os.getpid).result(), flush=True)
pool.submit(time.sleep, 600)  # busy: a training run that never reads its queue
time.sleep(600)
"""
"""A process that starts a worker as lookfeel's pools do (synth's: spawned, `die_with_parent`
its initializer), prints the worker's id, keeps it busy and waits to be killed."""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="clears a Linux prctl")
def test_a_worker_ends_with_its_killed_parent_where_getppid_cannot_tell():
    """QA (portability): on Windows ``getppid`` keeps naming a dead parent and there is no
    ``prctl``, so a reproduction worker went on training after ``lookfeel reproduce`` was
    killed. The parent's sentinel (`multiprocessing.parent_process`) tells on every system."""
    parent = subprocess.Popen(
        [sys.executable, "-c", _PARENT], cwd=ROOT, env=_env(), stdout=subprocess.PIPE, text=True
    )
    worker = 0
    try:
        assert parent.stdout is not None
        worker = int(parent.stdout.readline())
        assert alive(worker)
        parent.send_signal(signal.SIGKILL)
        parent.wait(timeout=10)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and alive(worker):
            time.sleep(0.05)
        assert not alive(worker), "the worker outlived its killed parent"
    finally:
        if parent.poll() is None:
            parent.kill()
            parent.wait()
        if worker and alive(worker):
            os.kill(worker, signal.SIGKILL)


def test_replacing_a_file_another_process_holds_open_is_retried_on_windows(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """QA (portability): on Windows a checkpoint that ``evaluate`` was reading at that moment
    could not be replaced (PermissionError), and the training run stopped."""
    real_replace = os.replace
    tries: list[str] = []
    slept: list[float] = []
    busy_for = 3  # the reader holds the file for this many tries

    def replace(src: str, dst: str | os.PathLike[str]) -> None:
        tries.append(str(dst))
        if len(tries) <= busy_for:
            raise PermissionError(13, "Access is denied", str(src), None, 5)
        real_replace(src, dst)

    monkeypatch.setattr(sys, "platform", "win32")
    monkeypatch.setattr(os, "replace", replace)
    monkeypatch.setattr(time, "sleep", slept.append)
    path = tmp_path / "last.pt"
    path.write_text("old", encoding="utf-8")
    atomic_write_text(path, "new")
    assert path.read_text(encoding="utf-8") == "new" and len(tries) == 4 and len(slept) == 3
    assert [p.name for p in tmp_path.iterdir()] == ["last.pt"]

    busy_for = 1000  # held for good: raised as before, after about 2 s
    tries.clear()
    slept.clear()
    with pytest.raises(PermissionError) as e:
        atomic_write_text(path, "newer")
    assert e.value.filename == str(path) and path.read_text(encoding="utf-8") == "new"
    assert len(tries) == len(slept) + 1 and 1.5 <= sum(slept) <= 2.5
    assert [p.name for p in tmp_path.iterdir()] == ["last.pt"]


def test_a_refused_replace_elsewhere_is_raised_at_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """On Linux and macOS a PermissionError is a real one: no retry."""
    tries: list[str] = []

    def replace(src: str, dst: str | os.PathLike[str]) -> None:
        tries.append(str(dst))
        raise PermissionError(13, "Permission denied", str(src))

    monkeypatch.setattr(sys, "platform", "darwin")
    monkeypatch.setattr(os, "replace", replace)
    monkeypatch.setattr(time, "sleep", lambda s: pytest.fail(f"slept {s} s"))
    with pytest.raises(PermissionError) as e:
        atomic_write_text(tmp_path / "a.json", "{}")
    assert e.value.filename == str(tmp_path / "a.json") and len(tries) == 1


def test_the_umask_is_read_once_where_proc_cannot_tell_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """QA (portability): on macOS each new file set the process's umask to 0o077 and back, and
    a folder another thread made in that instant was 0o700."""
    umask = os.umask(0o022)
    os.umask(umask)
    calls: list[int] = []
    real_umask = os.umask

    def spy(mask: int) -> int:
        calls.append(mask)
        return real_umask(mask)

    monkeypatch.setattr(os, "umask", spy)
    file_mode()
    assert calls == []  # Linux: read from /proc, never changed

    def no_proc(file: str, *args: object, **kwargs: object) -> object:
        if str(file).startswith("/proc/"):
            raise FileNotFoundError(2, "No such file or directory", file)
        return open(file, *args, **kwargs)

    monkeypatch.setattr(atomic, "open", no_proc, raising=False)  # as on macOS
    monkeypatch.setattr(atomic, "_UMASK", None, raising=False)  # not read yet
    modes = {file_mode() for _ in range(3)}
    path = atomic_write_text(tmp_path / "new.txt", "x")
    assert modes == {0o666 & ~umask} and path.stat().st_mode & 0o777 == 0o666 & ~umask
    assert len(calls) == 2  # set and set back, once
    assert real_umask(umask) == umask  # as it was


def test_serve_takes_its_port_for_itself_on_windows(monkeypatch: pytest.MonkeyPatch):
    """QA (portability): on Windows SO_REUSEADDR lets a second server bind a port in use, so
    "--port N is already in use" never came and two servers shared the port."""
    from lookfeel.serve.server import _bind

    exclusive = -5  # Windows' SO_EXCLUSIVEADDRUSE (~SO_REUSEADDR); not an option here
    real = socket.socket.setsockopt
    set_: list[tuple[int, int]] = []

    def setsockopt(sock: socket.socket, level: int, option: int, value: int) -> None:
        set_.append((level, option))
        if option != exclusive:
            real(sock, level, option, value)

    monkeypatch.setattr(socket.socket, "setsockopt", setsockopt)
    with _bind("127.0.0.1", 0):
        assert (socket.SOL_SOCKET, socket.SO_REUSEADDR) in set_  # Linux: a restart's port back
    monkeypatch.setattr(socket, "SO_EXCLUSIVEADDRUSE", exclusive, raising=False)
    monkeypatch.setattr(sys, "platform", "win32")
    set_.clear()
    with _bind("127.0.0.1", 0):
        assert (socket.SOL_SOCKET, exclusive) in set_
        assert (socket.SOL_SOCKET, socket.SO_REUSEADDR) not in set_


def test_text_its_stdout_cannot_encode_is_escaped_not_a_traceback():
    """QA (portability): on an ASCII stdout (or a Windows code page that lacks a user's label
    text) ``lookfeel match`` ended in UnicodeEncodeError; ``index build --help`` prints "∝"."""
    env = dict(_env(), PYTHONIOENCODING="ascii")
    done = subprocess.run(
        [sys.executable, "-m", "lookfeel", "index", "build", "--help"],
        env=env,
        capture_output=True,
        text=True,
        encoding="ascii",
        check=False,
    )
    assert (done.returncode, done.stderr) == (0, "")
    assert "Calibrates c of P \\u221d exp(-c D\\xb2)" in done.stdout


def test_file_names_on_a_c_locale_still_print_as_their_bytes(monkeypatch: pytest.MonkeyPatch):
    """Only a stdout that would fail changes: ``surrogateescape`` writes a file name's own
    bytes back, as it did."""
    from lookfeel.cli import run

    out = io.TextIOWrapper(io.BytesIO(), encoding="ascii", errors="surrogateescape")
    monkeypatch.setattr(sys, "stdout", out)
    with pytest.raises(SystemExit):
        run(["--version"])
    assert out.errors == "surrogateescape"


def test_importing_lookfeel_main_runs_nothing(monkeypatch: pytest.MonkeyPatch):
    """QA (portability): importing it (pdoc, ``pytest --doctest-modules``) ran the command
    with their own argv."""
    monkeypatch.delitem(sys.modules, "lookfeel.__main__", raising=False)
    monkeypatch.setattr(sys, "argv", ["lookfeel", "data"])  # would print usage and exit 2
    module = importlib.import_module("lookfeel.__main__")
    assert callable(module.run)
