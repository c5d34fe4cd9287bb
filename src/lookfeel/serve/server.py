"""Running the web app: in the foreground (``lookfeel serve``) or in a background thread
(tests, benchmarks), always on an address the caller chooses (loopback by default)."""

from __future__ import annotations

import errno
import socket
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import uvicorn
from fastapi import FastAPI

__all__ = ["background_server", "serve"]


_STARTUP_FAILURE = 3
"""Exit status of a server that bound its address but did not start (uvicorn's)."""


def _bind(host: str, port: int) -> socket.socket:
    """A TCP socket bound to ``host:port`` as uvicorn binds one (IPv6 for an address with a
    colon; port 0 picks a free one).

    Raises:
        ServeOptionError: naming ``--port`` when another program has the port, else ``--host``
            and ``--port`` with the system's reason (no such address, a port that needs root).
    """
    from lookfeel.serve.app import ServeOptionError

    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    # Marked TCP, so that asyncio turns off Nagle's delay on each connection it accepts (it
    # does so only for a socket whose protocol says TCP; protocol 0 left every answer over a
    # kept-open connection, a browser's, waiting about 40 ms for the client's delayed ACK),
    # and off here too, for the connections that inherit it.
    sock = socket.socket(family, socket.SOCK_STREAM, socket.IPPROTO_TCP)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    try:
        sock.bind((host, port))
    except OSError as e:
        sock.close()
        if e.errno == errno.EADDRINUSE:
            raise ServeOptionError(
                f"--port {port}: {host}:{port} is already in use (another server?); "
                "choose another --port"
            ) from None
        raise ServeOptionError(
            f"--host {host} --port {port}: cannot listen there: {e.strerror or e}"
        ) from None
    return sock


def serve(
    app: FastAPI,
    host: str = "127.0.0.1",
    port: int = 8000,
    log_level: str = "info",
    on_bound: Callable[[str], None] | None = None,
) -> None:
    """Serve ``app`` until interrupted (Ctrl-C).

    Args:
        app: the app (`create_app`).
        host: address to listen on (loopback by default).
        port: TCP port, 1-65535.
        log_level: uvicorn's log level.
        on_bound: called with the server's URL (``http://127.0.0.1:8000/``) once the address
            is bound, before serving starts: where ``lookfeel serve`` says it is serving, so
            that it never says so of an address it could not take.

    Raises:
        ServeOptionError: ``host`` or ``port`` is not usable, before anything binds, or the
            address cannot be bound (the port is in use, say).
        SystemExit: status 3 when the server bound its address but did not start (uvicorn
            has logged why), as ``uvicorn.run`` exits.
    """
    from lookfeel.serve.app import ServeOptions

    ServeOptions(host=host, port=port)  # validates
    sock = _bind(host, port)
    try:
        port = sock.getsockname()[1]  # the one taken, where 0 asked for any free port
        if on_bound is not None:
            url_host = f"[{host}]" if ":" in host else host
            on_bound(f"http://{url_host}:{port}/")
        config = uvicorn.Config(app, host=host, port=port, log_level=log_level, access_log=False)
        server = uvicorn.Server(config)
        server.run(sockets=[sock])
    finally:
        sock.close()
    if not server.started:
        sys.exit(_STARTUP_FAILURE)


@contextmanager
def background_server(
    app: FastAPI, host: str = "127.0.0.1", port: int = 0, timeout: float = 30.0
) -> Iterator[str]:
    """Run ``app`` in a daemon thread for the duration of a ``with`` block.

    Args:
        app: the app.
        host: address to bind (loopback by default).
        port: 0 picks a free port.
        timeout: seconds to wait for the server to start.

    Yields:
        The base URL, e.g. ``http://127.0.0.1:41234``.

    Raises:
        ServeOptionError: the address cannot be bound (`serve`'s message).
    """
    sock = _bind(host, port)
    bound_port = sock.getsockname()[1]
    config = uvicorn.Config(app, log_level="warning", access_log=False, lifespan="off")
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    deadline = time.monotonic() + timeout
    while not server.started:
        if not thread.is_alive() or time.monotonic() > deadline:
            sock.close()
            raise RuntimeError(f"the server on {host}:{bound_port} did not start")
        time.sleep(0.01)
    try:
        yield f"http://{host}:{bound_port}"
    finally:
        server.should_exit = True
        thread.join(timeout)
        sock.close()
