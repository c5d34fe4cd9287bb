"""The web app: a page to match an image of any modality, and the JSON API behind it.

Routes (the OpenAPI schema at ``/openapi.json`` describes the API):

- ``GET /``: the page (plain HTML, CSS and a little JS from this package; nothing external).
  ``HEAD`` of it, of ``/static/*`` and of an item's image is answered as ``GET`` without the
  body.
- ``GET /api/library``: what the library holds and how it is calibrated.
- ``GET /api/fabrics``: every fabric (``fabric_id``) with its labels and a few item ids per
  modality.
- ``GET /api/items/{item_id}``: one item's metadata; ``/api/items/{item_id}/image`` its image
  as a PNG thumbnail (a press video: its frame of deepest contact, as recorded but turned by
  the model's ``data.video_rotate``). Items are
  named by id (``depth:12``: the row in ASCII digits, no sign, space or leading zero, so that
  each item has one URL); the file is looked up in the library, so no request ever names a
  path on disk. An item image is sent with ``Cache-Control: no-cache`` and an ``ETag`` of the
  library (a digest of its manifest), the thumbnail size and the item's id, and answered 304
  to a matching ``If-None-Match``: ids are row numbers, and a library rebuilt under the server
  may put another image at the same row, which a browser must not show from its cache. The
  server keeps at most 2048 thumbnails and ``thumbnail_cache_bytes`` of them in memory.
- ``POST /api/match``: multipart upload, ``modality`` and one or more ``files`` (several touch
  files are the presses of one query, pooled as the Multi-input Net; of several, a press video
  without a press is left out, as ``lookfeel match`` leaves it out, and ``warnings`` says so;
  it says too, in one line, which press videos have no colour, or, for a model trained on grey
  presses, which have colour: `lookfeel.index.match.press_colour_line`).
- ``POST /api/match/item``: match a library item as a query (itself left out).

Each match answers ``results`` as ``lookfeel match --json`` does (`MatchEntry`: a matched
query's `lookfeel.index.MatchResult`, its files as ``path`` and ``paths``, its ``properties`` as
``lookfeel predict``'s, label -> value, probability ..., and ``error`` null), but with file names
only. As ``lookfeel match`` answers each query on its own (`Matcher.match_each`), of several
depth or colour files one that cannot be used (empty, not a PNG or JPEG, undecodable, of the
wrong kind, a depth map without a valid pixel) is its own query's entry: its ``path``,
``paths`` and ``error`` (one line naming it; the other keys null or empty), and the others are
matched (200). A request is refused whole (4xx) only where no file can be used (the first
file's error, as its status says) or for the request itself: too many files, a file or the
request too large or declaring too many pixels (413), a bad field. Touch files are one query
(their presses pooled), which one such press fails: refused as a whole, as when no file can be
used (but a press video without a press among others is left out, as above).

Uploads are limited in size and number and must be PNG or JPEG by content; an image declaring
more than ``max_pixels`` pixels is refused (413) from its header, before anything is decoded (a
0.4 MB PNG can declare 13000 x 13000). A bad upload gets a 4xx with a message naming the file
and no path of the server's disk. Every error is a JSON object whose ``detail`` is one line of
text (a bad field's name and what is wrong with it included), with any value it echoes cut to
`MAX_ECHO` characters. Every response carries ``X-Content-Type-Options: nosniff``, a
``Content-Security-Policy`` allowing only this server's own scripts and styles, and
``X-Frame-Options: DENY``; an unexpected error too: it is answered 500 with such a JSON
object (``internal error (RuntimeError); the server's log says more``, nothing of the
exception's text) and its traceback is logged on the server (logger ``lookfeel.serve``). Which
Host and Origin a request may carry is checked where the app is served
(`lookfeel.serve.server`). The model runs in a thread pool, at most
``max_concurrency`` queries at a time (a semaphore); beyond ``max_waiting`` waiting queries
the server answers 503 instead of queueing without bound. A library rebuilt under the server is
loaded beside the one it serves and answers once loaded (`lookfeel.serve.reload`).
"""

from __future__ import annotations

import asyncio
import hashlib
import io
import json
import logging
import os
import re
import sys
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, fields, replace
from importlib import resources
from math import inf
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import torch
from fastapi import FastAPI, File, Form, HTTPException, Request, UploadFile
from fastapi.exceptions import RequestValidationError
from fastapi.responses import HTMLResponse, JSONResponse, Response
from PIL import Image
from pydantic import BaseModel, Field
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from lookfeel.data import ImageError, decode_depth, decode_rgb, depth_to_unit
from lookfeel.data.files import VIDEO_SUFFIXES
from lookfeel.data.images import declared_size
from lookfeel.data.layout import sniff_video
from lookfeel.data.video import NoPressError, is_video, read_press
from lookfeel.devices import resolve_device
from lookfeel.errors import LookfeelError
from lookfeel.index import (
    FabricMatch,
    ItemRef,
    Library,
    LibraryError,
    LibraryItem,
    Matcher,
    MatchFailure,
    MatchResult,
    PropertyEstimate,
    load_query_bytes,
    query_batch,
    sniff_type,
)
from lookfeel.index.match import press_colour_line, warn_press_kinds
from lookfeel.index.query import VIDEOS_ARE_TOUCH, bytes_frame_size, orientation_note
from lookfeel.modality import Modality
from lookfeel.serve.reload import Served, ServedLibrary

__all__ = [
    "SECURITY_HEADERS",
    "ServeConfig",
    "ServeOptionError",
    "ServeOptions",
    "create_app",
    "public_message",
]

_LOG = logging.getLogger("lookfeel.serve")
"""Where an unexpected error's traceback goes (`_InternalErrors`)."""

_VIDEOS = ", ".join(VIDEO_SUFFIXES)
"""The press videos an upload may be: ``.mov, .mp4, ...``."""

SECURITY_HEADERS = {
    "X-Content-Type-Options": "nosniff",
    "X-Frame-Options": "DENY",
    "Content-Security-Policy": (
        "default-src 'self'; img-src 'self' data: blob:; object-src 'none'; "
        "base-uri 'none'; frame-ancestors 'none'; form-action 'self'"
    ),
    "Referrer-Policy": "no-referrer",
}
"""Headers on every response: no MIME sniffing, no framing, only this server's resources."""

_ABS_PATH = re.compile(r"(?<![\w.])(?:[A-Za-z]:)?[/\\](?:[^\s'\":,/\\]+[/\\])+([^\s'\":,/\\]+)")


def public_message(text: str) -> str:
    """An error message fit for a client: every absolute path cut to its file name."""
    return _ABS_PATH.sub(r"\1", text)


MAX_ECHO = 80
"""The most characters of a client's value (an item id, a file name) an error echoes."""
MAX_DETAIL = 1000
"""The most characters of an error's ``detail`` (a long message is cut, ending in ``...``)."""
_LONG_WORD = re.compile(rf"\S{{{MAX_ECHO + 1},}}")


def _clip(text: str, limit: int = MAX_ECHO) -> str:
    """``text`` cut to its first ``limit`` characters and ``...`` when longer."""
    return text if len(text) <= limit else text[:limit] + "..."


def _one_line(detail: object) -> str:
    """An error's ``detail`` as the client gets it: one line, every run of more than
    `MAX_ECHO` characters without a space (an echoed id or file name) cut to `MAX_ECHO` and
    ``...``, and at most `MAX_DETAIL` characters in all: a 3 MB item id must not come back as
    a 3 MB answer."""
    text = " ".join(str(detail).split())
    return _clip(_LONG_WORD.sub(lambda m: _clip(m.group()), text), MAX_DETAIL)


_WHERE = {"body": "request body", "query": "query", "path": "path", "header": "header"}


def _validation_message(errors: Any) -> str:
    """One line for FastAPI's validation errors: each field by name (``top``, ``modality``,
    ``item``) and what is wrong with it, with the value given (cut to `MAX_ECHO`).

    Example: ``modality: input should be 'depth', 'color' or 'touch'; got 'smell'``.
    """
    parts = []
    for err in errors:
        loc = [str(x) for x in err.get("loc", ())]
        kind = err.get("type", "")
        if kind == "json_invalid":
            why = (err.get("ctx") or {}).get("error", "")
            parts.append("request body: not valid JSON" + (f" ({why})" if why else ""))
            continue
        field = ".".join(loc[1:]) if len(loc) > 1 else _WHERE.get(loc[0] if loc else "", "request")
        msg = str(err.get("msg", "is not valid"))
        msg = msg[:1].lower() + msg[1:]
        got = ""
        if kind != "missing" and "input" in err:
            got = f"; got {_clip(repr(err['input']))}"
        parts.append(f"{field}: {msg}{got}")
    return _one_line("; ".join(parts) or "the request is not valid")


_OTHER_IMAGES = {
    b"GIF87a": "GIF",
    b"GIF89a": "GIF",
    b"BM": "BMP",
    b"II*\x00": "TIFF",
    b"MM\x00*": "TIFF",
    b"\x00\x00\x00\x0cjP  ": "JPEG 2000",
}


def _image_kind(head: bytes) -> str | None:
    """The name of an image format this server does not take (GIF, WebP, ...) from a file's
    first bytes, else None."""
    if head[:4] == b"RIFF" and head[8:12] == b"WEBP":
        return "WebP"
    if head[4:12] in (b"ftypavif", b"ftypheic", b"ftypheix", b"ftypmif1"):
        return "AVIF/HEIF"
    return next((name for magic, name in _OTHER_IMAGES.items() if head.startswith(magic)), None)


def _a_video(name: str, data: bytes) -> bool:
    """Whether an upload is a video, by its content (`sniff_video`) or its name's suffix."""
    return sniff_video(data[:16]) or Path(name).suffix.lower() in VIDEO_SUFFIXES


def _no_press(e: ImageError) -> bool:
    """Whether an upload's error is that its video holds no press (`NoPressError`), also when
    `load_query_bytes` re-raised it as a plain `ImageError` naming the client's file."""
    return isinstance(e, NoPressError) or isinstance(e.__context__, NoPressError)


def _unusable(name: str, data: bytes, modality: Modality) -> tuple[int, str] | None:
    """Why an upload cannot be a query of ``modality``, found from its first bytes before
    anything is decoded, as (HTTP status, one line naming it): empty (422), not a PNG or JPEG
    image, nor for touch a video (415; of another image format, which), or an image header
    that cannot be read (422). None where it is to be decoded (a touch video: its frames are
    checked then)."""
    if not data:
        return 422, f"{name}: the file is empty"
    if modality is Modality.TOUCH and sniff_video(data[:16]):
        return None
    if sniff_type(data[:16]) is None:
        other = _image_kind(data[:16])
        return 415, (
            f"{name}: not a PNG or JPEG image"
            + (f" or a video ({_VIDEOS})" if modality is Modality.TOUCH else "")
            + (f" (a {other} image: save it as PNG or JPEG)" if other else "")
            + (
                f" ({VIDEOS_ARE_TOUCH})"
                if modality is not Modality.TOUCH and _a_video(name, data)
                else ""
            )
        )
    if declared_size(data) is None:
        return 422, f"{name}: cannot decode the image header (not a whole PNG or JPEG)"
    return None


MAX_THUMBNAILS = 2048
"""The most item thumbnails the server keeps in memory (also at most
`ServeConfig.thumbnail_cache_bytes` of them)."""

MAX_PER_MODALITY = 50
"""The most item ids per modality ``GET /api/fabrics?per_modality=N`` lists for each fabric."""


class ServeOptionError(LookfeelError):
    """A server option is out of range; the message names the option and the value."""


_STATIC = {
    "index.html": "text/html; charset=utf-8",
    "app.js": "text/javascript; charset=utf-8",
    "style.css": "text/css; charset=utf-8",
}


def _to_stderr(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


def _need(ok: bool, option: str, value: object, rule: str) -> None:
    if not ok:
        raise ServeOptionError(f"{option} must be {rule}; got {value!r}")


@dataclass(frozen=True)
class ServeConfig:
    """Limits of the web app, checked when made.

    Attributes:
        max_upload_bytes: largest accepted file (413 above).
        max_files: most files in one request (a touch query's presses).
        max_concurrency: queries the model runs at once (threads; 2 cores: 1-2).
        max_waiting: queries that may wait for the model before the server answers 503.
        max_top: largest ``top`` a request may ask for.
        thumbnail_size: longest side of the item images served, in pixels.
        max_pixels: largest width x height of an upload, checked from its header before
            decoding (413 above).
        thumbnail_cache_bytes: most bytes of item thumbnails (PNG) kept in memory; the least
            recently used go first (and `MAX_THUMBNAILS` at most, whatever their size).
        reload_every: seconds between looks, when requests come, at whether the library was
            rebuilt (then it is loaded beside the old one and served; `ServedLibrary`); 0
            serves the library opened at start until the server stops.

    Raises:
        ServeOptionError: a limit below 1, or ``reload_every`` below 0, naming it.
    """

    max_upload_bytes: int = 8 * 1024 * 1024
    max_files: int = 8
    max_concurrency: int = 2
    max_waiting: int = 64
    max_top: int = 20
    thumbnail_size: int = 256
    max_pixels: int = 25_000_000
    thumbnail_cache_bytes: int = 64 * 1024 * 1024
    reload_every: float = 2.0

    def __post_init__(self) -> None:
        _need(
            isinstance(self.reload_every, int | float)
            and not isinstance(self.reload_every, bool)
            and 0 <= self.reload_every < inf,
            "reload_every",
            self.reload_every,
            "a number of seconds, 0 or more",
        )
        for name in (
            "max_upload_bytes",
            "max_files",
            "max_concurrency",
            "max_waiting",
            "max_top",
            "thumbnail_size",
            "max_pixels",
            "thumbnail_cache_bytes",
        ):
            v = getattr(self, name)
            _need(
                isinstance(v, int) and not isinstance(v, bool) and v >= 1,
                name,
                v,
                "a whole number of at least 1",
            )


@dataclass(frozen=True)
class ServeOptions:
    """The options of ``lookfeel serve``, validated in one place when made.

    Attributes:
        host: address to listen on (default loopback only).
        port: TCP port, 1-65535, or 0 for any free one (the server then says which it took).
        threads: PyTorch threads per query, at least 1.
        max_upload_mb: largest upload in MB, more than 0.
        max_concurrency: queries the model runs at once, at least 1 (0 would hang every query).
        max_megapixels: largest upload in megapixels (width x height / 1e6), more than 0.

    Raises:
        ServeOptionError: naming the option (as spelt on the command line) and the value.

    Example:
        >>> opts = ServeOptions(port=8080, max_upload_mb=4)
        >>> app = create_app("lib/", opts.config())
    """

    host: str = "127.0.0.1"
    port: int = 8000
    threads: int = 1
    max_upload_mb: float = 8.0
    max_concurrency: int = 2
    max_megapixels: float = 25.0

    def __post_init__(self) -> None:
        def whole(v: object) -> bool:
            return isinstance(v, int) and not isinstance(v, bool)

        def number(v: object) -> bool:
            return whole(v) or (isinstance(v, float) and v == v and v not in (inf, -inf))

        _need(
            isinstance(self.host, str) and bool(self.host.strip()),
            "--host",
            self.host,
            "an address such as 127.0.0.1",
        )
        _need(
            whole(self.port) and 0 <= self.port <= 65535,
            "--port",
            self.port,
            "between 1 and 65535, or 0 for any free port",
        )
        _need(
            whole(self.threads) and 1 <= self.threads <= 1024,
            "--threads",
            self.threads,
            "between 1 and 1024",
        )
        _need(
            whole(self.max_concurrency) and 1 <= self.max_concurrency <= 1024,
            "--max-concurrency",
            self.max_concurrency,
            "between 1 and 1024 (0 would make every query wait forever)",
        )
        _need(
            number(self.max_upload_mb) and 0 < self.max_upload_mb <= 1024,
            "--max-upload-mb",
            self.max_upload_mb,
            "more than 0 and at most 1024",
        )
        _need(
            number(self.max_megapixels) and 0 < self.max_megapixels <= 1000,
            "--max-megapixels",
            self.max_megapixels,
            "more than 0 and at most 1000",
        )

    def config(self) -> ServeConfig:
        """The app's limits from these options."""
        return ServeConfig(
            max_upload_bytes=max(1, int(self.max_upload_mb * 1024 * 1024)),
            max_concurrency=self.max_concurrency,
            max_pixels=max(1, int(self.max_megapixels * 1e6)),
        )


class LibraryInfo(BaseModel):
    """What the library holds."""

    fabrics: int
    items: dict[str, int]
    modalities: list[Modality]
    uploads: list[Modality]
    """The modalities an uploaded file can be matched as: all of ``modalities`` but touch when
    the model reads several frames of a press together (``data.touch_frames``), which one
    uploaded image cannot give (a library press can still be matched by its id)."""
    default_gallery: dict[str, Modality]
    label_columns: list[str]
    backbone: str
    image_size: int
    color_size: int | None = None
    """Colour's input side when it differs from ``image_size`` (``data.color_size``)."""
    embed_dim: int
    backend: str
    limits: dict[str, int]
    calibration: dict[str, Any]


class ItemInfo(BaseModel):
    """One library item (its file name only; the server's folders are not shown)."""

    id: str
    modality: Modality
    fabric_id: int
    file: str
    kind: str | None = None
    image_url: str


class FabricInfo(BaseModel):
    """One library fabric with a few of its items per modality."""

    fabric_id: int
    """The fabric's id, as a match's ``fabrics[].fabric_id`` and an item's ``fabric_id`` name
    it."""
    name: str | None = None
    """The object's name (``sponge``) where the data names its objects; None for a numbered
    fabric and in a library built before names were recorded."""
    cluster: int | None
    labels: dict[str, float]
    text_labels: dict[str, str] = Field(
        default_factory=dict,
        description="every known label cell as written, words included (material: metal)",
    )
    items: dict[str, list[str]]


class MatchEntry(BaseModel):
    """One query's entry of ``results``, as ``lookfeel match --json`` gives it: a matched
    query's `MatchResult` (its fields, in its order) with ``error`` null, or, for a depth or
    colour file that cannot be used among others that can, that file's ``path``, ``paths``,
    ``query_modality`` and ``error``, the other keys null (``fabrics``, ``properties`` and
    ``timing_ms`` empty)."""

    query_modality: Modality
    gallery_modality: Modality | None
    path: str
    paths: list[str]
    presses: int | None
    known: bool | None
    best_probability: float | None
    unknown_probability: float | None
    threshold: float | None
    c: float | None
    message: str | None
    fabrics: list[FabricMatch]
    properties: dict[str, PropertyEstimate]
    property_fabrics: int | None
    backend: str | None
    timing_ms: dict[str, float]
    error: str | None = Field(
        None,
        description="why the file was not matched, in one line naming it (empty, not a PNG or "
        "JPEG, undecodable, of the wrong kind, a depth map without a valid pixel); null for a "
        "matched query",
    )

    @classmethod
    def matched(cls, result: MatchResult) -> MatchEntry:
        """A matched query's entry, with file names only: the server's folders are not the
        client's business."""

        def ref(r: ItemRef) -> ItemRef:
            return replace(r, path=Path(r.path).name)

        def fab(f: FabricMatch) -> FabricMatch:
            return replace(f, nearest={m: [ref(r) for r in rs] for m, rs in f.nearest.items()})

        public = replace(
            result,
            path=Path(result.path).name,
            paths=[Path(q).name for q in result.paths],
            fabrics=[fab(f) for f in result.fabrics],
        )
        return cls(**{f.name: getattr(public, f.name) for f in fields(public)}, error=None)

    @classmethod
    def failed(cls, name: str, modality: Modality, error: str) -> MatchEntry:
        """The entry of an uploaded file ``name`` that could not be matched, and why."""
        failure = MatchFailure(name, [name], modality, public_message(error))
        return cls(**failure.entry())


class MatchResponse(BaseModel):
    """One result per query: per depth/colour file, or one for all touch presses."""

    results: list[MatchEntry]
    warnings: list[str] = Field(
        default_factory=list,
        description="what `lookfeel match` would warn of, one line each: of several touch "
        "files, a press video without a press, left out (its result's `paths` lists the files "
        "used); a press video given to a model trained on still frames; a press of a kind the "
        "model was not trained on (by its name, F0007_flat_1000.mp4); press videos with no "
        "colour (grey), or with colour for a model trained on grey presses, in one line "
        "naming the first",
    )


class ItemQuery(BaseModel):
    """Match a library item as if it were a new query."""

    item: str = Field(description="item id, e.g. 'depth:12'", examples=["depth:0"])
    top: int = Field(5, ge=1, description="fabrics to return")
    gallery: Modality | None = Field(None, description="modality to match against")


def _item_info(item: LibraryItem) -> ItemInfo:
    return ItemInfo(
        id=item.id,
        modality=item.modality,
        fabric_id=item.fabric_id,
        file=Path(item.image).name,
        kind=item.kind,
        image_url=f"/api/items/{item.id}/image",
    )


def _thumbnail(item: LibraryItem, library: Library, size: int) -> bytes:
    """The item's image as a PNG no larger than ``size``; depth mapped to grey as training; a
    press video shown by its frame of deepest contact, as recorded but turned as the model
    reads it (``data.video_rotate``), not the difference from the untouched sensor a model
    may read.

    Raises:
        ImageError: the file cannot be read (a video: `lookfeel.data.video.VideoError`).
    """
    path = Path(item.image)
    if item.modality is Modality.DEPTH:
        cfg = library.config.data
        unit = depth_to_unit(decode_depth(path), cfg.depth_min_mm, cfg.depth_range_mm)
        im = Image.fromarray((unit * 255.0 + 0.5).astype(np.uint8))
    elif is_video(path):
        turn = library.config.data.video_rotate  # as the library's model reads it
        press = read_press(path, frames=1, subtract_reference=False, rotate=turn)
        im = Image.fromarray(press.images[0])
    else:
        im = Image.fromarray(decode_rgb(path))
    im.thumbnail((size, size))
    buf = io.BytesIO()
    im.save(buf, format="PNG")
    return buf.getvalue()


class _BodyLimit:
    """Refuse request bodies over ``limit`` bytes with a 413, declared or streamed (chunked).

    A declared Content-Length over the limit is refused before anything is read; a body sent
    without one is counted as it arrives and cut off at the limit, so an upload can never fill
    the disk where the form parser spools files.
    """

    def __init__(self, app: ASGIApp, limit: int) -> None:
        self.app = app
        self.limit = limit

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = dict(scope.get("headers", []))
        declared = headers.get(b"content-length", b"").decode("latin-1")
        if declared.isdigit() and int(declared) > self.limit:
            response = JSONResponse(
                {"detail": f"request of {int(declared)} bytes is larger than {self.limit} bytes"},
                status_code=413,
            )
            await response(scope, receive, send)
            return
        received = 0

        async def counted() -> Message:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > self.limit:
                    # FastAPI passes an HTTPException raised while reading the body through.
                    raise HTTPException(413, f"request is larger than {self.limit} bytes")
            return message

        await self.app(scope, counted, send)


class _SecurityHeaders:
    """Add `SECURITY_HEADERS` to every HTTP response (errors included)."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return

        async def with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                present = {k.lower() for k, _ in message.get("headers", [])}
                extra = [
                    (k.lower().encode("latin-1"), v.encode("latin-1"))
                    for k, v in SECURITY_HEADERS.items()
                    if k.lower().encode("latin-1") not in present
                ]
                message = {**message, "headers": [*message.get("headers", []), *extra]}
            await send(message)

        await self.app(scope, receive, with_headers)


class _InternalErrors:
    """Answer an unexpected error (an exception no handler made an answer of) as every other
    error is answered: a JSON 500, ``{"detail": "internal error (RuntimeError); the server's log
    says more"}``, and log its traceback on the server (logger ``lookfeel.serve``). The
    exception's own text is not sent: it may name the server's files. Installed inside
    `_SecurityHeaders`, so that the answer carries `SECURITY_HEADERS`; Starlette's own handler,
    outside every middleware, answers plain text without them. An error after the answer has
    begun cannot be answered: it is raised on, for the ASGI server to log."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        started = False

        async def watched(message: Message) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
            await send(message)

        try:
            await self.app(scope, receive, watched)
        except Exception as exc:
            if started:
                raise
            method, path = scope.get("method", "?"), scope.get("path", "?")
            _LOG.error("serve: %s %s failed, answered 500", method, path, exc_info=exc)
            detail = f"internal error ({type(exc).__name__}); the server's log says more"
            await JSONResponse({"detail": detail}, status_code=500)(scope, receive, send)


def _library_tag(library: Library) -> str:
    """A short digest of a library's manifest (its items' shards, model and settings): which
    library an item id's image comes from, for its ``ETag``."""
    text = json.dumps(library.manifest, sort_keys=True, default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def _etag_matches(if_none_match: str | None, etag: str) -> bool:
    """Whether an ``If-None-Match`` header (``"a", W/"b"`` or ``*``) names ``etag``."""
    if not if_none_match:
        return False
    tags = [t.strip() for t in if_none_match.split(",")]
    return "*" in tags or any(t.removeprefix("W/") == etag for t in tags)


def create_app(
    library: Library | str | os.PathLike[str],
    config: ServeConfig | None = None,
    matcher: Matcher | None = None,
    log: Callable[[str], None] | None = None,
    *,
    device: torch.device | str = "cpu",
) -> FastAPI:
    """Build the web app over a library.

    A library rebuilt under the server (`lookfeel index build` into its folder) is served
    once it is loaded (`ServedLibrary`; ``config.reload_every``).

    Args:
        library: an opened `Library` or its folder.
        config: limits; defaults to `ServeConfig()`.
        matcher: a ready `Matcher` for ``library`` (tests inject one); default: built from the
            library. A rebuilt library gets a `Matcher` of its own.
        log: where a swap is noted in one line (default: standard error).
        device: where the model runs: ``cpu``, ``cuda``, ``cuda:1``, a ``torch.device``, or
            ``auto`` (`lookfeel.devices.resolve_device`), checked before the library is
            opened; a rebuilt library's model runs there too. An injected ``matcher`` keeps
            its own.

    Raises:
        DeviceError: ``device`` is unknown to torch or not usable here.
        LibraryError: the library or its checkpoint cannot be used.
    """
    cfg = config or ServeConfig()
    where = resolve_device(device)  # a device this machine lacks: one line, before any work

    def make_matcher(lib: Library) -> Matcher:
        return Matcher(lib, device=where)

    opened = library if isinstance(library, Library) else Library.open(library)
    served = ServedLibrary(
        opened, matcher, cfg.reload_every, log or _to_stderr, make_matcher=make_matcher
    )
    static = {
        name: (resources.files("lookfeel.serve").joinpath("static", name).read_bytes(), mime)
        for name, mime in _STATIC.items()
    }
    app = FastAPI(
        title="lookfeel",
        summary="Which known fabric is this, how does it look and feel, what are its properties?",
        version="1",
        docs_url=None,  # Swagger UI and ReDoc load scripts from a CDN; the page must not
        redoc_url=None,
    )
    state: dict[str, Any] = {"waiting": 0, "semaphore": None, "thumbnail_bytes": 0}
    thumbnails: OrderedDict[tuple[int, str], bytes] = OrderedDict()
    tags: dict[int, str] = {}  # generation -> `_library_tag`

    def semaphore() -> asyncio.Semaphore:
        if state["semaphore"] is None:  # created in the server's event loop
            state["semaphore"] = asyncio.Semaphore(cfg.max_concurrency)
        sem: asyncio.Semaphore = state["semaphore"]
        return sem

    async def run_model(fn: Any, *args: Any) -> Any:
        if state["waiting"] >= cfg.max_waiting:
            raise HTTPException(503, "server busy: too many queries waiting; retry shortly")
        state["waiting"] += 1
        try:
            async with semaphore():
                return await run_in_threadpool(fn, *args)
        finally:
            state["waiting"] -= 1

    max_body = cfg.max_files * cfg.max_upload_bytes + 64 * 1024
    app.add_middleware(_BodyLimit, limit=max_body)
    app.add_middleware(_InternalErrors)  # inside _SecurityHeaders: a 500 carries them too
    app.add_middleware(_SecurityHeaders)

    @app.exception_handler(StarletteHTTPException)
    async def http_error(request: Request, exc: StarletteHTTPException) -> Response:
        """Every error as ``{"detail": "one line"}``, echoed values cut (`_one_line`)."""
        return JSONResponse(
            {"detail": _one_line(exc.detail)}, status_code=exc.status_code, headers=exc.headers
        )

    @app.exception_handler(RequestValidationError)
    async def invalid_request(request: Request, exc: RequestValidationError) -> Response:
        """A missing or malformed field: 422 naming it (`_validation_message`), as the app's
        own checks answer, not pydantic's list of objects."""
        return JSONResponse({"detail": _validation_message(exc.errors())}, status_code=422)

    @app.api_route(
        "/", methods=["GET", "HEAD"], response_class=HTMLResponse, include_in_schema=False
    )
    def page() -> Response:
        body, mime = static["index.html"]
        return Response(body, media_type=mime)

    @app.api_route("/static/{name}", methods=["GET", "HEAD"], include_in_schema=False)
    def static_file(name: str) -> Response:
        if name not in static:
            raise HTTPException(404, f"no static file {_clip(name)!r}")
        body, mime = static[name]
        return Response(body, media_type=mime, headers={"Cache-Control": "no-cache"})

    @app.get("/api/library", response_model=LibraryInfo)
    def library_info() -> LibraryInfo:
        """What the library holds: fabrics, items per modality, model, calibration, limits."""
        now = served.current()
        lib, match = now.library, now.matcher
        return LibraryInfo(
            fabrics=len(lib.fabrics),
            items={m.value: len(t) for m, t in lib.tables.items()},
            modalities=[m for m in match.model.modalities if m in lib.tables],
            uploads=[
                m
                for m in match.model.modalities
                if m in lib.tables
                and not (m is Modality.TOUCH and lib.config.data.stacks_touch_frames)
            ],
            default_gallery={q.value: g for q, g in lib.calibration.default_gallery.items()},
            label_columns=list(lib.label_columns),
            backbone=lib.config.model.backbone,
            image_size=lib.config.data.image_size,
            color_size=lib.config.data.color_size,
            embed_dim=lib.embed_dim,
            backend=lib.backend,
            limits={
                "max_upload_bytes": cfg.max_upload_bytes,
                "max_files": cfg.max_files,
                "max_top": cfg.max_top,
                "max_pixels": cfg.max_pixels,
            },
            calibration=lib.calibration.to_dict(),
        )

    @app.get("/api/fabrics", response_model=list[FabricInfo])
    def fabrics(per_modality: int = 3) -> list[FabricInfo]:
        """Every fabric with its labels and up to ``per_modality`` item ids per modality
        (0 to `MAX_PER_MODALITY`; 422 outside)."""
        if not 0 <= per_modality <= MAX_PER_MODALITY:
            raise HTTPException(
                422,
                f"per_modality must be between 0 and {MAX_PER_MODALITY}; got {per_modality}",
            )
        lib = served.current().library
        out = []
        for fid, record in sorted(lib.fabrics.items()):
            items = {
                m.value: [f"{m.value}:{r}" for r in t.rows_of(fid)[:per_modality]]
                for m, t in lib.tables.items()
            }
            out.append(
                FabricInfo(
                    fabric_id=fid,
                    name=record.name,
                    cluster=record.cluster,
                    labels=record.labels,
                    text_labels=record.text_labels,
                    items=items,
                )
            )
        return out

    def lookup(lib: Library, item_id: str) -> LibraryItem:
        try:
            return lib.item(item_id)
        except KeyError as e:
            raise HTTPException(404, str(e.args[0])) from None

    @app.get("/api/items/{item_id}", response_model=ItemInfo)
    def item_info(item_id: str) -> ItemInfo:
        """One library item by id (``depth:12``)."""
        return _item_info(lookup(served.current().library, item_id))

    @app.get(
        "/api/items/{item_id}/image",
        response_class=Response,
        responses={
            200: {"content": {"image/png": {}}},
            404: {"description": "no such item"},
            410: {"description": "the item's file can no longer be read"},
        },
    )
    async def item_image(item_id: str, request: Request) -> Response:
        """The item's image as a PNG thumbnail (depth shown as grey, near = dark; a press
        video as its frame of deepest contact, as recorded, turned as the model reads it).
        Sent with an ``ETag`` and ``Cache-Control: no-cache``; 304 to a matching
        ``If-None-Match``."""
        now = served.current()
        item = lookup(now.library, item_id)
        if now.generation not in tags:
            tags[now.generation] = _library_tag(now.library)
        etag = f'"{tags[now.generation]}-{cfg.thumbnail_size}-{item.id}"'
        headers = {"Cache-Control": "no-cache", "ETag": etag}
        if _etag_matches(request.headers.get("if-none-match"), etag):
            return Response(status_code=304, headers=headers)
        key = (now.generation, item.id)
        png = thumbnails.get(key)
        if png is not None:
            thumbnails.move_to_end(key)
        else:
            try:
                png = await run_in_threadpool(_thumbnail, item, now.library, cfg.thumbnail_size)
            except ImageError as e:
                raise HTTPException(
                    410,
                    public_message(f"item {item.id}: its file can no longer be read ({e.reason})"),
                ) from None
            if key not in thumbnails:  # another request may have made it meanwhile
                thumbnails[key] = png
                state["thumbnail_bytes"] += len(png)
            while thumbnails and (
                len(thumbnails) > MAX_THUMBNAILS
                or state["thumbnail_bytes"] > cfg.thumbnail_cache_bytes
            ):
                state["thumbnail_bytes"] -= len(thumbnails.popitem(last=False)[1])
        return Response(png, media_type="image/png", headers=headers)

    app.add_api_route(  # HEAD as GET without the body (uvicorn sends none), out of the schema
        "/api/items/{item_id}/image", item_image, methods=["HEAD"], include_in_schema=False
    )

    def check_top(top: int) -> None:
        if not 1 <= top <= cfg.max_top:
            raise HTTPException(422, f"top must be between 1 and {cfg.max_top}; got {top}")

    def check_modalities(now: Served, modality: Modality, gallery: Modality | None) -> None:
        lib, match = now.library, now.matcher
        try:
            match.check_modality(modality)
            if gallery is not None:
                lib.table(gallery)
        except LibraryError as e:
            raise HTTPException(422, public_message(str(e))) from None

    @app.post(
        "/api/match",
        response_model=MatchResponse,
        responses={
            413: {"description": "a file or the request is too large"},
            415: {
                "description": "no file is a PNG or JPEG image (or, for touch, a video); "
                "touch: one press is not"
            },
            422: {
                "description": "no file can be decoded as this modality (of several depth or "
                "colour files, one that cannot is answered in `results` with its `error`; "
                "touch: one press cannot, or no video holds a press; one without among others "
                "is left out, named in `warnings`), or a bad field"
            },
            503: {"description": "too many queries waiting"},
        },
    )
    async def match_upload(
        modality: Annotated[Modality, Form(description="what the images show")],
        files: Annotated[
            list[UploadFile],
            File(
                description=f"PNG or JPEG images, or touch videos ({_VIDEOS}); several "
                "touch files are one query's presses"
            ),
        ],
        top: Annotated[int, Form(description="fabrics to return")] = 5,
        gallery: Annotated[Modality | None, Form(description="modality to match against")] = None,
    ) -> MatchResponse:
        """Rank the library's fabrics for uploaded images, with probabilities, the nearest
        items of each fabric in every modality and predicted physical properties. Of several
        depth or colour files, one that cannot be used is answered with its ``error`` and the
        others are matched; where none can be, the first one's error is the answer (4xx)."""
        check_top(top)
        now = served.current()  # the whole request is answered from this library
        match = now.matcher
        check_modalities(now, modality, gallery)
        if not files:
            raise HTTPException(422, "no file uploaded")
        if len(files) > cfg.max_files:
            raise HTTPException(413, f"{len(files)} files; at most {cfg.max_files} per query")
        given = [Path(f.filename or f"file {i + 1}").name for i, f in enumerate(files)]
        blobs: list[tuple[int, str, bytes]] = []  # the files to decode: position, name, bytes
        refused: dict[int, tuple[int, str]] = {}  # position -> why not: HTTP status, one line
        for i, (f, name) in enumerate(zip(files, given, strict=True)):
            data = await f.read(cfg.max_upload_bytes + 1)
            if len(data) > cfg.max_upload_bytes:
                raise HTTPException(
                    413, f"{name}: larger than the {cfg.max_upload_bytes} bytes allowed"
                )
            unusable = _unusable(name, data, modality)
            if unusable is not None:
                if modality is Modality.TOUCH:  # one pooled query, which this press fails
                    raise HTTPException(*unusable)
                refused[i] = unusable  # this file's own query; the others are matched
                continue
            # An image's header, read without Pillow (no warning filters); a press video's
            # frames are checked on decoding.
            size = None if sniff_video(data[:16]) else declared_size(data)
            if size is not None and size[0] * size[1] > cfg.max_pixels:
                raise HTTPException(
                    413,
                    f"{name}: declares {size[0]}x{size[1]} pixels; at most "
                    f"{cfg.max_pixels / 1e6:g} megapixels are decoded",
                )
            blobs.append((i, name, data))
        if not blobs:  # no file can be used: the first one's error, as before any was matched
            raise HTTPException(*refused[min(refused)])

        def work() -> tuple[dict[int, MatchResult], dict[int, str], list[str]]:
            # As `lookfeel match` reads files (`Matcher.match_each`): a depth or colour file
            # that cannot be decoded is its own query's error, and the others are matched; of
            # several touch presses (one query), a video without a press is left out with a
            # warning, and the only one, or every one, is an error (the first one's), as is
            # any other press that cannot be decoded. Its warnings (a press video for a model
            # trained on still frames, a press of a kind the model was not trained on, a query
            # turned against the library's items, press videos with no colour) are collected in
            # `notes`, this request's own list (`warnings.catch_warnings` is process-wide, not
            # safe in the server's threads), and answered in `warnings`. Returns each matched
            # query's result and each failed file's error, by the position of its (first) file.
            notes: list[str] = []
            videos: list[tuple[str, bool]] = []  # of the presses read: as `lookfeel match`
            if modality is Modality.TOUCH and not match.data_config.stacks_touch_frames:
                warn_press_kinds(
                    [n for _, n, _ in blobs],
                    match.data_config,
                    "the library's model",
                    notes.append,
                )
            turned = orientation_note(
                [(n, bytes_frame_size(d)) for _, n, d in blobs],
                modality,
                match.shape(modality),
                match.data_config,
                "the library",
                videos=[sniff_video(d[:16]) for _, _, d in blobs],  # as they are read: by content
            )
            if turned is not None:
                notes.append(turned)
            images, names, read = [], [], []
            missed: list[ImageError] = []
            failed: dict[int, str] = {}
            for i, n, d in blobs:
                try:
                    images.append(
                        load_query_bytes(
                            d,
                            n,
                            modality,
                            match.data_config,
                            cfg.max_pixels,
                            trained_on=match.touch_input,
                            warn=notes.append,
                            on_video=lambda name, grey: videos.append((name, grey)),
                        )
                    )
                    names.append(n)
                    read.append(i)
                except ImageError as e:
                    if modality is not Modality.TOUCH:
                        failed[i] = str(e)  # this file's own query, as `lookfeel match` says
                    elif _no_press(e):
                        missed.append(e)
                    else:
                        raise
            if not images:
                if missed:
                    raise missed[0]
                return {}, failed, notes
            colour = press_colour_line(videos, match.trained_on_grey)
            if colour is not None:
                notes.append(colour)
            x = query_batch(images, modality)
            emb = match.embed(x, modality)
            if modality is Modality.TOUCH:
                groups, where = [names], read[:1]
            else:
                groups, where = [[n] for n in names], read
            results = {
                i: match.match_embedding(e, modality, g, top=top, gallery=gallery)
                for e, g, i in zip(emb, groups, where, strict=True)
            }
            return (
                results,
                failed,
                [*notes, *(f"{e}: left out of the pooled query" for e in missed)],
            )

        try:
            matched, failed, warnings = await run_model(work)
        except ImageError as e:
            raise HTTPException(422, public_message(str(e))) from None
        except LibraryError as e:
            raise HTTPException(422, public_message(str(e))) from None
        errors = {**refused, **{i: (422, line) for i, line in failed.items()}}
        if not matched:  # no file could be decoded: the first one's error
            code, line = errors[min(errors)]
            raise HTTPException(code, public_message(line))
        entries = [
            MatchEntry.matched(matched[i])
            if i in matched
            else MatchEntry.failed(given[i], modality, errors[i][1])
            for i in range(len(files))
            if i in matched or i in errors
        ]
        return MatchResponse(
            results=entries,
            warnings=[public_message(w) for w in warnings],
        )

    @app.post("/api/match/item", response_model=MatchResponse)
    async def match_library_item(query: ItemQuery) -> MatchResponse:
        """Match a library item as a query, itself left out of the gallery."""
        check_top(query.top)
        now = served.current()
        match = now.matcher
        item = lookup(now.library, query.item)
        check_modalities(now, item.modality, query.gallery)
        try:
            result = await run_model(
                lambda: match.match_item(item.id, top=query.top, gallery=query.gallery)
            )
        except LibraryError as e:
            raise HTTPException(422, public_message(str(e))) from None
        return MatchResponse(results=[MatchEntry.matched(result)])

    return app
