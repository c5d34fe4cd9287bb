"""Running the web app: in the foreground (``lookfeel serve``) or in a background thread
(tests, benchmarks), always on an address the caller chooses (loopback by default)."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

import uvicorn
from fastapi import FastAPI

__all__ = ["background_server", "serve"]


def serve(app: FastAPI, host: str = "127.0.0.1", port: int = 8000, log_level: str = "info") -> None:
    """Serve ``app`` until interrupted (Ctrl-C).

    Raises:
        ServeOptionError: ``host`` or ``port`` (1-65535) is not usable, before anything binds.
    """
    from lookfeel.serve.app import ServeOptions

    ServeOptions(host=host, port=port)  # validates
    uvicorn.run(app, host=host, port=port, log_level=log_level, access_log=False)


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
    """
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.bind((host, port))
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
