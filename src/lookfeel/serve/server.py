"""Running the web app: in the foreground (``lookfeel serve``) or in a background thread
(tests, benchmarks), always on an address the caller chooses (loopback by default).

The app is served behind `LocalGuard`, a check of two request headers for a demo server
without login:

- Host, against DNS rebinding (a web page whose name is made to point at 127.0.0.1 reading
  this server's answers as its own): on a loopback address (``127.0.0.1``, ``::1``,
  ``localhost``) only a request naming this machine is answered, ``Host: localhost``,
  ``127.0.0.1``, ``[::1]`` or the address listened on, with any port; any other Host, or none,
  gets 403. On any other address the names the server is reached by cannot be known, and every
  Host is taken.
- Origin, against other web sites' forms (a cross-site multipart POST needs no CORS
  preflight, so any page could make the server run its model): a request other than GET or
  HEAD that carries an Origin whose host and port differ from its Host header's gets 403,
  whatever the address. A request without Origin (curl, scripts) is taken.

A refusal is a JSON ``{"detail": "one line"}`` with the app's `SECURITY_HEADERS`, as the app's
own errors are. Listening beyond this machine (``--host 0.0.0.0``: no login, anyone who can
reach the machine can use the server) is warned of by ``lookfeel serve``; for an unspecified
address (``0.0.0.0``, ``::``) the URL said is this machine's loopback one (`local_url`).
"""

from __future__ import annotations

import errno
import ipaddress
import socket
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from urllib.parse import urlsplit

import uvicorn
from fastapi import FastAPI
from starlette.responses import JSONResponse
from starlette.types import ASGIApp, Receive, Scope, Send

__all__ = [
    "LocalGuard",
    "background_server",
    "is_loopback",
    "is_unspecified",
    "local_url",
    "serve",
]

_LOCAL_NAMES = ("localhost", "127.0.0.1", "[::1]")
"""The Host names a server listening on a loopback address answers (with any port)."""

_DEFAULT_PORTS = {"http": 80, "https": 443}


def is_loopback(host: str) -> bool:
    """Whether listening on ``host`` keeps a server to this machine: a loopback address
    (``127.0.0.1``, ``127.0.0.2``, ``::1``) or ``localhost``. Any other name is taken as
    reachable from elsewhere (it is not resolved)."""
    name = host.strip().strip("[]").lower()
    if name == "localhost":
        return True
    try:
        address = ipaddress.ip_address(name)
    except ValueError:
        return False
    mapped = getattr(address, "ipv4_mapped", None)  # ::ffff:127.0.0.1 is 127.0.0.1
    return bool((mapped or address).is_loopback)


def is_unspecified(host: str) -> bool:
    """Whether ``host`` is ``0.0.0.0`` or ``::``: every network interface of this machine."""
    try:
        return ipaddress.ip_address(host.strip().strip("[]")).is_unspecified
    except ValueError:
        return False


def local_url(host: str, port: int) -> str:
    """The URL a browser on this machine opens for a server on ``host:port``: for an
    unspecified address (``0.0.0.0``, ``::``, which no browser can open) the loopback address
    of its family, else ``host`` itself (``http://[::1]:8000/`` for an IPv6 address)."""
    if is_unspecified(host):
        host = "::1" if ":" in host else "127.0.0.1"
    url_host = f"[{host}]" if ":" in host else host
    return f"http://{url_host}:{port}/"


def _split_host(value: str) -> tuple[str, int | None] | None:
    """(name, port or None) of a Host header (``localhost:8000``, ``[::1]:8000``,
    ``example.org``), the name lower-cased with an IPv6 address's brackets kept; None when it
    is not one."""
    value = value.strip().lower()
    if value.startswith("["):
        end = value.find("]")
        if end < 0:
            return None
        name, rest = value[: end + 1], value[end + 1 :]
    else:
        name, colon, port = value.partition(":")
        rest = colon + port
    if not rest:
        return (name, None) if name else None
    if not (rest.startswith(":") and rest[1:].isascii() and rest[1:].isdigit()):
        return None
    return (name, int(rest[1:])) if name and len(rest) <= 6 else None


def _same_origin(origin: str, host: str | None) -> bool:
    """Whether an Origin header (``http://127.0.0.1:8000``) names the host and port of a Host
    header (``127.0.0.1:8000``); a port left out is the Origin's scheme's default."""
    if host is None:
        return False
    try:
        parts = urlsplit(origin.strip())
        origin_port = parts.port
    except ValueError:
        return False
    default = _DEFAULT_PORTS.get(parts.scheme.lower())
    given = _split_host(host)
    if parts.hostname is None or default is None or given is None:
        return False
    name = parts.hostname.lower()
    name = f"[{name}]" if ":" in name else name
    return (name, origin_port or default) == (given[0], given[1] or default)


class LocalGuard:
    """The Host and Origin checks of a served app (the module's docstring says which).

    Args:
        app: the app (`lookfeel.serve.create_app`'s).
        host: the address it listens on: a loopback one turns the Host check on.
    """

    def __init__(self, app: ASGIApp, host: str) -> None:
        self.app = app
        self.host_check = is_loopback(host)
        bound = host.strip().strip("[]").lower()
        self.names = {*_LOCAL_NAMES, f"[{bound}]" if ":" in bound else bound}

    def refusal(self, scope: Scope) -> str | None:
        """Why a request is refused (one line), or None where it is taken."""
        headers = {k.lower(): v for k, v in scope.get("headers", [])}
        raw_host = headers.get(b"host")
        host = None if raw_host is None else raw_host.decode("latin-1")
        if self.host_check:
            given = None if host is None else _split_host(host)
            if given is None or given[0] not in self.names:
                shown = "none" if host is None else repr(host[:80])
                return (
                    f"Host {shown} is not this machine: a server on a loopback address answers "
                    "only requests to localhost, 127.0.0.1 or [::1]"
                )
        origin = headers.get(b"origin")
        if origin is not None and scope.get("method", "GET") not in ("GET", "HEAD"):
            text = origin.decode("latin-1")
            if not _same_origin(text, host):
                return (
                    f"Origin {text[:80]!r} is not this server: a page of another site may not "
                    "send it requests"
                )
        return None

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "http":
            why = self.refusal(scope)
            if why is not None:
                from lookfeel.serve.app import SECURITY_HEADERS

                answer = JSONResponse({"detail": why}, status_code=403, headers=SECURITY_HEADERS)
                await answer(scope, receive, send)
                return
        await self.app(scope, receive, send)


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
    # A port another program has must be refused. On Windows SO_REUSEADDR would let this
    # socket share it (which server answers is then undefined): there the port is taken
    # for this socket alone. Elsewhere SO_REUSEADDR only lets a restarted server take its
    # port back from the closed connections of the last one.
    if sys.platform == "win32" and hasattr(socket, "SO_EXCLUSIVEADDRUSE"):
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_EXCLUSIVEADDRUSE, 1)
    else:
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
    """Serve ``app`` until interrupted (Ctrl-C), behind `LocalGuard`.

    Args:
        app: the app (`create_app`).
        host: address to listen on (loopback by default).
        port: TCP port, 1-65535.
        log_level: uvicorn's log level.
        on_bound: called with the server's URL (``http://127.0.0.1:8000/``; for ``0.0.0.0``
            or ``::``, this machine's loopback one, `local_url`) once the address is bound,
            before serving starts: where ``lookfeel serve`` says it is serving, so that it
            never says so of an address it could not take.

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
            on_bound(local_url(host, port))
        guarded = LocalGuard(app, host)
        config = uvicorn.Config(
            guarded, host=host, port=port, log_level=log_level, access_log=False
        )
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
    """Run ``app`` in a daemon thread for the duration of a ``with`` block, behind
    `LocalGuard` as `serve` runs it.

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
    config = uvicorn.Config(
        LocalGuard(app, host), log_level="warning", access_log=False, lifespan="off"
    )
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
