"""Decoding images in worker processes, in order, while the caller uses what is ready.

Decoding a PNG and resizing it hold Python's GIL for about a third of the time (measured on
320x240 GelSight frames), so threads stop scaling after two or three: 16 threads on an H100
host decoded 870 images/s. Worker processes have no shared GIL. `decode_in_processes` runs
the loader's own per-file decoding (`ImageLoader.decode_one`) in ``workers`` processes
through a `torch.utils.data.DataLoader` (results come back in shared memory, a chunk of
images as one tensor) and yields, chunk by chunk and in the order given, what each file
decoded to, for the caller to keep (`ImageLoader.adopt`). (The loader comes in as a factory:
this module does not import `lookfeel.data.images`, which imports it.)

- Same bytes as threads: the workers call the same function with the same settings, and the
  disk cache (``data.cache_dir``) is shared (written atomically).
- The caller's torch RNG is left as it was: whether files decode in processes or threads
  (how many, ``data.decode``, the platform) changes no training run.
- Errors as in one process: a file that fails in a worker is decoded again by the caller,
  which raises the very error (naming the file) that a thread would have.
- Warnings as in one process: what a worker warns while decoding a file (a truncated video,
  `lookfeel.data.video.TruncatedVideoWarning`) is warned again by the caller, in order, as
  its chunk comes back, where the caller's warning filters and display see it. What the
  loader says once of all the files (a depth image with no valid pixel,
  `lookfeel.data.images.BlankDepthWarning`) is not warned by a worker: it comes back as a
  note with the file's entries (`ImageLoader.take`, as a press video's ``grey``), and the
  caller's loader says it once, as threads would have.
- Workers are forked on Linux (they start in milliseconds), spawned elsewhere (seconds: each
  imports torch); each dies with the process that started it (`die_with_parent`).
"""

from __future__ import annotations

import functools
import os
import sys
import warnings
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import torch
from torch.utils.data import DataLoader, Dataset

from lookfeel.data.catalog import Item
from lookfeel.processes import can_fork, die_with_parent

__all__ = ["Decoded", "Decoder", "decode_in_processes"]

Entries = dict[str, np.ndarray]
"""What one file decoded to, by the loader's store it belongs in (`ImageLoader.take`)."""
Warned = tuple[tuple[type[Warning], str], ...]
"""What decoding one file warned: each warning's category and message."""
Row = tuple[int, Entries | None, Warned]
"""One decoded file: its position among the jobs, what it decoded to, what it warned."""


class Decoder(Protocol):
    """What a worker needs of a loader (`lookfeel.data.images.ImageLoader`)."""

    def decode_one(self, item: Item, *, views: bool = False) -> None: ...

    def take(self, path: Path) -> Entries: ...


@dataclass(frozen=True)
class Decoded:
    """One chunk of files decoded by the workers, in the order they were asked for.

    Attributes:
        paths: the chunk's files.
        entries: per file, what it decoded to; ``None`` where the worker failed (decode it
            again in this process to raise the file's own error).
    """

    paths: tuple[Path, ...]
    entries: tuple[Entries | None, ...]


def _sendable(category: type[Warning]) -> type[Warning]:
    """``category`` where another process can import it by name, else `UserWarning`."""
    module = sys.modules.get(category.__module__)
    return category if getattr(module, category.__qualname__, None) is category else UserWarning


class _Jobs(Dataset[Row]):
    """The files to decode, decoded by a loader built inside each worker."""

    def __init__(
        self, new_loader: Callable[[], Decoder], jobs: Sequence[tuple[Path, Item]], views: bool
    ) -> None:
        self.new_loader = new_loader
        self.jobs = list(jobs)
        self.views = views
        self._loader: Decoder | None = None

    def __len__(self) -> int:
        return len(self.jobs)

    def __getitem__(self, i: int) -> Row:
        if self._loader is None:
            self._loader = self.new_loader()
        path, item = self.jobs[i]
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")  # every one goes back; the caller's filters choose
            try:
                self._loader.decode_one(item, views=self.views)
            except Exception:  # raised again, with its own message (and warnings), by the caller
                self._loader.take(path)
                return i, None, ()
        warned = tuple((_sendable(w.category), str(w.message)) for w in caught)
        return i, self._loader.take(path), warned


Stacked = list[tuple[list[int], dict[str, torch.Tensor]]]
"""A chunk's entries: groups of rows (positions in the chunk), each with one tensor per key."""


def _collate(rows: list[Row]) -> tuple[list[int], Stacked, list[Warned]]:
    """A chunk as few tensors as possible: rows whose entries share keys, shapes and dtypes
    are stacked (one shared-memory block per key instead of one per image); failed rows
    are in no group. With each row's warnings."""
    groups: dict[tuple[Any, ...], list[int]] = {}
    for pos, (_, e, _) in enumerate(rows):
        if e is not None:
            sig = tuple((k, a.shape, a.dtype.str) for k, a in sorted(e.items()))
            groups.setdefault(sig, []).append(pos)
    stacked: Stacked = []
    for sig, members in groups.items():
        tensors = {}
        for key, _, _ in sig:
            tensors[key] = torch.from_numpy(np.stack([_row(rows, p)[key] for p in members]))
        stacked.append((members, tensors))
    return [i for i, _, _ in rows], stacked, [w for _, _, w in rows]


def _row(rows: list[Row], pos: int) -> Entries:
    e = rows[pos][1]
    assert e is not None  # only rows that decoded are grouped
    return e


def _worker_init(parent: int, _worker_id: int) -> None:
    die_with_parent(parent)


def _entries(stacked: Stacked, n: int) -> list[Entries | None]:
    """Undo `_collate`: per row, its entries as numpy views of the stacked tensors."""
    out: list[Entries | None] = [None] * n
    for members, tensors in stacked:
        arrays = {k: t.numpy() for k, t in tensors.items()}
        for j, pos in enumerate(members):
            out[pos] = {k: a[j] for k, a in arrays.items()}
    return out


def decode_in_processes(
    new_loader: Callable[[], Decoder],
    jobs: Sequence[tuple[Path, Item]],
    workers: int,
    *,
    views: bool = False,
    chunk: int = 32,
) -> Iterator[Decoded]:
    """Decode ``jobs`` (file, item) in ``workers`` processes, each with its own loader; yield
    them in order, ``chunk`` files at a time, as they are ready.

    Args:
        new_loader: makes, in each worker, the loader that decodes there (picklable, e.g.
            ``functools.partial(ImageLoader, config, cache_root)``): the caller's settings
            and disk cache.
        jobs: the files to decode and an item of each (its modality, its views).
        workers: processes (at least 1).
        views: decode the training views of items that have them (`ImageLoader.preload`).
        chunk: files per job sent to a worker.
    """
    if not jobs:
        return
    dataset = _Jobs(new_loader, jobs, views)
    context = "fork" if can_fork() else "spawn"
    batches = DataLoader(
        dataset,
        batch_size=chunk,
        shuffle=False,
        num_workers=max(1, min(workers, -(-len(jobs) // chunk))),
        collate_fn=_collate,
        worker_init_fn=functools.partial(_worker_init, os.getpid()),
        multiprocessing_context=context,
        prefetch_factor=4,
        # Its own generator: a DataLoader draws its workers' base seed from the one it is
        # given, else from torch's global RNG, which would shift a training run's dropout and
        # every draw after by whether its images happened to decode in processes.
        generator=torch.Generator(),
    )
    for index, stacked, warned in batches:
        for row in warned:
            for category, message in row:
                warnings.warn(message, category, stacklevel=2)
        entries = _entries(stacked, len(index))
        yield Decoded(tuple(jobs[i][0] for i in index), tuple(entries))
