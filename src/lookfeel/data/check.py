"""`check_dataset`: every problem in a dataset at once, every pixel decoded, nothing modified."""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np

from lookfeel.data.catalog import Catalog, Fabric
from lookfeel.data.images import ImageError, decode_depth, decode_rgb
from lookfeel.data.layout import IMAGE_SUFFIXES, VIDEO_SUFFIXES, scan
from lookfeel.data.problems import Problem
from lookfeel.data.video import NoPressError, is_video, read_press
from lookfeel.modality import Modality

__all__ = ["PLAUSIBLE_DEPTH_MM", "check_dataset", "size_problems"]


PLAUSIBLE_DEPTH_MM = (200, 8000)
"""Range in which the median of a depth map's valid pixels must lie to read as millimetres.

Depth cameras see from about 250-500 mm (Azure Kinect, Kinect v2, RealSense D435) out to 4.5-8 m
(Kinect v2 reports at most 8 m), and a drape is captured at about 1 m (GelFabric's Kinect
depth: medians 999-1089 mm; the synthetic world's likewise). A camera writing centimetres puts a
scene 1 m away at 100, one writing 0.1 mm units puts a scene 1 m away at 10,000: both outside."""


def _depth_unit_problem(path: Path, depth: np.ndarray) -> Problem | None:
    """A warning when the median of ``depth``'s valid (non-zero) pixels is implausible as
    millimetres (`PLAUSIBLE_DEPTH_MM`): the file was most likely written in other units, and
    the preprocessing (``clip((d - 800) / 500, 0, 1)``) would turn it into a blank image."""
    median = float(np.median(depth[depth > 0]))
    low, high = PLAUSIBLE_DEPTH_MM
    if low <= median <= high:
        return None
    guess = "centimetres" if median < low else "0.1 mm units, or saturated"
    return Problem(
        path,
        f"median of the valid pixels is {median:,.0f}, implausible as millimetres: lookfeel "
        f"reads depth in mm and a depth camera sees {low:,} to {high:,} mm ({guess}?); convert "
        "the file to millimetres",
        "warning",
    )


def _decode_problem(path: Path, modality: Modality) -> Problem | None:
    try:
        if modality is Modality.TOUCH and is_video(path):
            read_press(path)  # decodes every frame and finds the press
        elif modality is Modality.DEPTH:
            d = decode_depth(path)
            if not d.any():
                return Problem(path, "depth image has no valid pixel (all 0)", "warning")
            return _depth_unit_problem(path, d)
        else:
            decode_rgb(path)
    except NoPressError as e:
        return Problem(path, f"{e.reason}; runs leave this recording out", "warning")
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
    touch video is decoded and its press found; one without a press is a warning (runs leave
    it out: `lookfeel.data.drop_unpressed`). A
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
    new.extend(size_problems(catalog.root, usable))
    problems = sorted([*catalog.problems, *new], key=lambda p: (str(p.path), p.line or 0))
    return replace(catalog, fabrics=usable, problems=tuple(problems))


def size_problems(root: Path, fabrics: Sequence[Fabric]) -> list[Problem]:
    """Why no command can use a dataset of these usable ``fabrics``, if so.

    An empty dataset, or one of a single fabric, can be trained, evaluated or calibrated on by
    no command (each holds fabrics out), so ``data check`` fails on it and ``data info`` reports
    it. An empty one whose ``root`` itself holds press videos or ``F<id>_`` images was most
    likely given one level too deep (``ROOT/videos`` instead of ``ROOT``); the message says so.
    """
    if not fabrics:
        return [Problem(root, "no usable image found: " + _empty_hint(root))]
    if len(fabrics) == 1:
        only = fabrics[0]
        who = f"object {only.name!r}" if only.name is not None else f"fabric (id {only.id})"
        return [
            Problem(
                root,
                f"only one {who} has usable images; training, evaluation and calibration hold "
                "fabrics out, so at least 2 are needed",
            )
        ]
    return []


def _empty_hint(root: Path) -> str:
    """What an empty dataset should hold, or where the files given directly in ``root`` go."""
    files = sorted(p for p in root.iterdir() if p.is_file() and not p.name.startswith("."))
    videos = [p for p in files if p.suffix.lower() in VIDEO_SUFFIXES]
    images = [p for p in files if p.suffix.lower() in IMAGE_SUFFIXES and re.match(r"F\d+_", p.name)]
    if videos:
        return (
            f"{root} holds {len(videos)} press video(s) directly (e.g. {videos[0].name}); they "
            f"belong in {root / 'videos'}/ (is this the videos/ folder? give its parent)"
        )
    if images:
        return (
            f"{root} holds {len(images)} F<id>_ image(s) directly (e.g. {images[0].name}); they "
            "belong in its depth/, color/ or touch/ folder (is this one of those folders? give "
            "its parent)"
        )
    return (
        "a dataset holds depth/, color/ or touch/ folders of F<id>_... images, or a videos/ "
        "folder of <object>_<n> press videos (see `lookfeel data check --help`)"
    )
