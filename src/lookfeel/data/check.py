"""`check_dataset`: every problem in a dataset at once, every pixel decoded, nothing modified."""

from __future__ import annotations

from collections.abc import Iterable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path

from lookfeel.data.catalog import Catalog, Fabric
from lookfeel.data.images import ImageError, decode_depth, decode_rgb
from lookfeel.data.layout import scan
from lookfeel.data.problems import Problem
from lookfeel.data.video import is_video, read_press
from lookfeel.modality import Modality

__all__ = ["check_dataset"]


def _decode_problem(path: Path, modality: Modality) -> Problem | None:
    try:
        if modality is Modality.DEPTH:
            d = decode_depth(path)
            if not d.any():
                return Problem(path, "depth image has no valid pixel (all 0)", "warning")
        elif modality is Modality.TOUCH and is_video(path):
            read_press(path)  # decodes, and finds the press: no contact is an error too
        else:
            decode_rgb(path)
    except ImageError as e:
        return Problem(path, e.reason)
    return None


def check_dataset(
    root: str | Path,
    require: Iterable[Modality] | None = None,
    *,
    workers: int = 2,
) -> Catalog:
    """Scan ``root`` and decode every file the scan accepted (all frames of every press).

    Files are only read. Problems found while decoding (truncated or undecodable files, depth
    that is not 16-bit) are added to the scan's; those items are dropped from the catalog. A
    dataset with no usable fabric or only one is an error (no command can hold fabrics out of
    it), as is an unfinished `lookfeel synth` world.

    Args:
        root: the dataset folder.
        require: modalities every fabric must have; ``None``: each modality any fabric has.
        workers: decoding threads.

    Returns:
        The catalog, whose ``problems`` hold every error and warning (``errors`` for the exit
        status) and whose ``skipped`` lists what was not read.
    """
    catalog = scan(root, require)
    jobs = [
        (p, it.modality)
        for f in catalog.fabrics
        for its in f.items.values()
        for it in its
        for p in it.frames
    ]
    if workers > 1 and len(jobs) > 16:
        with ThreadPoolExecutor(workers) as pool:
            found = list(pool.map(lambda j: _decode_problem(*j), jobs))
    else:
        found = [_decode_problem(*j) for j in jobs]
    new = [p for p in found if p is not None]
    bad = {p.path for p in new if p.severity == "error"}
    fabrics = []
    for f in catalog.fabrics:
        items = {
            m: tuple(it for it in its if not bad.intersection(it.frames))
            for m, its in f.items.items()
        }
        fabrics.append(replace(f, items={m: its for m, its in items.items() if its}))
    usable = tuple(f for f in fabrics if f.items)
    new.extend(_size_problems(catalog.root, usable))
    problems = sorted([*catalog.problems, *new], key=lambda p: (str(p.path), p.line or 0))
    return replace(catalog, fabrics=usable, problems=tuple(problems))


def _size_problems(root: Path, fabrics: tuple[Fabric, ...]) -> list[Problem]:
    """An empty dataset, or one of a single fabric, can be trained, evaluated or calibrated on
    by no command (each holds fabrics out), so ``data check`` fails on it."""
    if not fabrics:
        return [
            Problem(
                root,
                "no usable image found: a dataset holds depth/, color/ or touch/ folders of "
                "F<id>_... images (see `lookfeel data check --help`)",
            )
        ]
    if len(fabrics) == 1:
        return [
            Problem(
                root,
                f"only one fabric (id {fabrics[0].id}) has usable images; training, evaluation "
                "and calibration hold fabrics out, so at least 2 are needed",
            )
        ]
    return []
