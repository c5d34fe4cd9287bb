"""The library a running server answers from, and picking up a rebuilt one.

`lookfeel index build` never changes a finished library in place: it swaps a new folder in
(`lookfeel.index.library`). A server that opened the old one would go on answering from it, so
`ServedLibrary` looks, at most every ``check_every`` seconds and only when a request comes,
whether the library's folder is another one now (two ``stat`` calls). When it is, the new library
and its model are loaded in a background thread while requests are still answered from the
old one, then swapped in at once: a request is answered wholly from one library, never a mix.
A rebuilt library that cannot be served (damaged, its checkpoint gone) is named in one line and
the old one is kept; it is tried again when the folder changes again.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from lookfeel.errors import LookfeelError
from lookfeel.index import Library, LibraryError, Matcher
from lookfeel.index.library import MANIFEST, folder_identity

__all__ = ["Served", "ServedLibrary"]

Stamp = tuple[int, int, int, int]


def _stamp(root: Path) -> Stamp | None:
    """Which library is at ``root`` now: its folder (device, inode) and its manifest's (inode,
    modification time), None while there is none (a swap passes through that). A folder's inode
    alone can be reused by a later folder once the first is removed."""
    folder = folder_identity(root)
    try:
        manifest = os.stat(root / MANIFEST)
    except OSError:
        return None
    if folder is None:
        return None
    return (*folder, manifest.st_ino, manifest.st_mtime_ns)


@dataclass(frozen=True)
class Served:
    """One library with the matcher of its model.

    Attributes:
        library: the opened library.
        matcher: embeds queries with the library's model.
        generation: 0 for the library opened at start, then 1, 2, ... for each rebuilt one
            swapped in (what a cache of its items is keyed by).
    """

    library: Library
    matcher: Matcher
    generation: int = 0


class ServedLibrary:
    """The library a server answers from now; a library rebuilt under it replaces it.

    Args:
        library: the library opened at start.
        matcher: its matcher (default: `Matcher(library)`).
        check_every: seconds between looks at the folder; 0 never looks (the library opened at
            start is served until the server stops).
        log: where the one-line notes of a swap go (the server's console).
        make_matcher: builds the matcher of a rebuilt library.

    Example:
        >>> served = ServedLibrary(Library.open("lib"), check_every=2.0)
        >>> now = served.current()  # a request's library and matcher, whole
        >>> now.library.fabrics, now.matcher.match_item("depth:3")
    """

    def __init__(
        self,
        library: Library,
        matcher: Matcher | None = None,
        check_every: float = 2.0,
        log: Callable[[str], None] = print,
        make_matcher: Callable[[Library], Matcher] = Matcher,
    ) -> None:
        self._now = Served(library, matcher if matcher is not None else make_matcher(library))
        self.root = Path(library.root)
        self.check_every = check_every
        self._log = log
        self._make_matcher = make_matcher
        recorded = library.manifest.get("checkpoint", {}).get("path")
        # A library opened with another checkpoint path (moved since the build) keeps it for
        # a rebuild only where the rebuild's own recorded path cannot be used (`_load`).
        self._checkpoint = None if str(library.checkpoint) == recorded else library.checkpoint
        self._identity = _stamp(self.root)
        self._failed: Stamp | None = None
        self._next_check = time.monotonic() + check_every
        self._lock = threading.Lock()
        self._loading: threading.Thread | None = None

    def current(self) -> Served:
        """The library and matcher to answer a request with (never blocks on a reload)."""
        if self.check_every > 0 and time.monotonic() >= self._next_check:
            self._check()
        return self._now

    def _check(self) -> None:
        with self._lock:
            self._next_check = time.monotonic() + self.check_every
            if self._loading is not None and self._loading.is_alive():
                return
            identity = _stamp(self.root)
            # None: no folder there now, which a build's swap passes through; wait for it.
            if identity is None or identity in (self._identity, self._failed):
                return
            self._loading = threading.Thread(
                target=self._load, args=(identity,), name="lookfeel-serve-reload", daemon=True
            )
            self._loading.start()

    def wait(self, timeout: float | None = None) -> None:
        """Wait for a reload in progress to end (tests; a server never waits)."""
        loading = self._loading
        if loading is not None:
            loading.join(timeout)

    def _load(self, identity: Stamp) -> None:
        try:
            try:
                library = Library.open(self.root)
                matcher = self._make_matcher(library)
            except LibraryError:
                if self._checkpoint is None:
                    raise
                library = Library.open(self.root, checkpoint=self._checkpoint)
                matcher = self._make_matcher(library)
        except Exception as e:  # a thread's error would print a traceback nobody reads
            reason = str(e) if isinstance(e, LookfeelError) else f"{type(e).__name__}: {e}"
            with self._lock:
                self._failed = identity
            self._log(
                f"serve: {self.root} was rebuilt but cannot be served ({reason}); still "
                "serving the library opened before"
            )
            return
        with self._lock:
            self._now = Served(library, matcher, self._now.generation + 1)
            self._identity = identity
            self._failed = None
        items = sum(len(t) for t in library.tables.values())
        self._log(
            f"serve: {self.root} was rebuilt; now serving it ({len(library.fabrics)} fabrics, "
            f"{items} items)"
        )
