"""`check_dataset`: every problem in a dataset at once, every pixel decoded, nothing modified."""

from __future__ import annotations

import contextlib
import functools
import math
import re
import threading
import warnings
from collections import Counter, defaultdict
from collections.abc import Iterable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TextIO

import numpy as np

from lookfeel.config import DataConfig
from lookfeel.data.catalog import Catalog, Fabric, Item
from lookfeel.data.images import GELSIGHT_SIZE, ImageError, decode_depth, decode_rgb
from lookfeel.data.layout import (
    FOLDER_ALIASES,
    IMAGE_SUFFIXES,
    NOT_A_VIDEO_CONTAINER,
    VIDEO_SUFFIXES,
    duplicate_files,
    scan,
)
from lookfeel.data.problems import Problem
from lookfeel.data.video import (
    NoPressError,
    Press,
    TruncatedVideoWarning,
    TwoPressesWarning,
    _block_factor,
    _light_change,
    _shrink,
    is_video,
    read_press,
)
from lookfeel.modality import Modality
from lookfeel.progress import bar as progress_bar

__all__ = [
    "MIN_IN_RANGE",
    "MIN_SIDE",
    "PLAUSIBLE_DEPTH_MM",
    "PRESSED_START_LEVELS",
    "SAME_SHAPE_LOG_RATIO",
    "UNREAD_IMAGE_SUFFIXES",
    "check_dataset",
    "decode_problem",
    "range_problems",
    "size_problems",
    "unread_problems",
]


PLAUSIBLE_DEPTH_MM = (200, 8000)
"""Range in which the median of a depth map's valid pixels must lie to read as millimetres.

Depth cameras see from about 250-500 mm (Azure Kinect, Kinect v2, RealSense D435) out to 4.5-8 m
(Kinect v2 reports at most 8 m), and a drape is captured at about 1 m (GelFabric's Kinect
depth: medians 999-1089 mm; the synthetic world's likewise). A camera writing centimetres puts a
scene 1 m away at 100, one writing 0.1 mm units puts a scene 1 m away at 10,000: both outside."""


MIN_IN_RANGE = 0.2
"""Share of a dataset's valid depth pixels that must lie inside the range raw depth is mapped
from (``data.depth_min_mm`` to ``+ data.depth_range_mm``), else ``data check`` warns: the rest
become 0 or 1, and an image with almost nothing inside is a constant. GelFabric has 77% inside
(800-1300 mm); a room behind the cloth that lies beyond the range may leave less (a drape at
1.15 m before a wall at 1.6 m: 29%), which is harmless while the cloth lies inside; depth
shifted by 0.8 m has none."""

UNREAD_IMAGE_SUFFIXES = frozenset(
    {".tif", ".tiff", ".bmp", ".gif", ".webp", ".exr", ".hdr", ".pfm", ".pgm", ".ppm"}
    | {".pnm", ".jp2", ".heic", ".heif", ".dng", ".npy", ".npz"}
)
"""Suffixes of images (and arrays) that lookfeel does not read: one in a modality folder is an
error of ``data check`` saying what to convert it to (the scan lists it as skipped)."""

_CONVERT = {
    Modality.DEPTH: "a 16-bit greyscale PNG in millimetres (0 = no reading)",
    Modality.COLOR: "an 8-bit RGB PNG or JPEG",
    Modality.TOUCH: "8-bit RGB PNG or JPEG frames, or a press video",
}


MIN_SIDE = 16
"""Shorter side, in pixels, below which ``data check`` warns of an image or press video
(`_small_problems`). The networks read inputs of 64 to 320 px a side (``data.image_size``,
``data.color_size``), so every image is enlarged to that size, and one of fewer than 16 px a
side can hold no texture (a weave's repeat, a press's ridges span several pixels of a
full-size image): it was most likely saved as a thumbnail or an icon."""


@dataclass(frozen=True)
class _Decoded:
    """What decoding one file found: a problem, its frame size (w, h), for depth the counts
    of its valid pixels (inside the mapped range, in all) and a sample of them, and for a press
    video whether it has no colour (`lookfeel.data.video.Press.grey`; None for anything else),
    its no-contact reference, small and grey (`_small_reference`), and the warnings decoding it
    gave (a truncated video, more than one press: `_recording_video_warnings`); for a still
    colour or touch image, whether it has no colour (``grey_image``: `_is_grey`; None for
    anything else)."""

    problem: Problem | None = None
    size: tuple[int, int] | None = None
    depth: tuple[int, int, np.ndarray] | None = None
    grey: bool | None = None
    reference: np.ndarray | None = None
    warned: tuple[Problem, ...] = ()
    grey_image: bool | None = None


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


def _depth_sample(depth: np.ndarray, low: float, high: float) -> tuple[int, int, np.ndarray]:
    """(valid pixels inside [low, high], valid pixels, about 2,000 of them evenly spaced)."""
    valid = depth[depth > 0]
    inside = int(np.count_nonzero((valid >= low) & (valid <= high)))
    step = max(1, valid.size // 2000)
    return inside, int(valid.size), valid[::step]


_VIDEO_WARNINGS: tuple[type[Warning], ...] = (TruncatedVideoWarning, TwoPressesWarning)
"""What `read_press` warns about a video it reads all the same: ``data check`` reports each as a
warning of the file (`_recording_video_warnings`)."""

_recording = threading.local()
"""``into``: the list the warnings of the file this thread decodes go to (`decode_problem`)."""


@contextlib.contextmanager
def _recording_video_warnings() -> Iterator[None]:
    """While this is entered, what `read_press` warns (`_VIDEO_WARNINGS`) in a thread that is
    decoding a file (`decode_problem`) goes to that file's own record instead of being shown:
    ``data check`` reports it as a warning of the file, as ``train`` and ``predict`` warn it.

    `warnings.catch_warnings` swaps the process's warning filters and display, so it is not
    safe in decoding threads (two threads' filters can outlive both): the calling thread enters
    this once, around all the decoding, and the decoding threads only append to a list of their
    own (`_recording`). Every such warning is kept ("always"), however the caller filters them;
    other warnings, and these outside a decoding, are shown as before."""
    with warnings.catch_warnings():
        shown = warnings.showwarning

        def show(
            message: Warning | str,
            category: type[Warning],
            filename: str,
            lineno: int,
            file: TextIO | None = None,
            line: str | None = None,
        ) -> None:
            into = getattr(_recording, "into", None)
            if into is not None and issubclass(category, _VIDEO_WARNINGS):
                into.append((category, str(message)))
            else:
                shown(message, category, filename, lineno, file, line)

        warnings.showwarning = show
        for category in _VIDEO_WARNINGS:
            warnings.simplefilter("always", category)
        yield


def _warned_problem(path: Path, category: type[Warning], message: str) -> Problem:
    """A warning of ``path`` from what `read_press` warned of it, without the path it begins
    with, saying what to do about a truncated file."""
    text = message.removeprefix(f"{path}: ")
    if issubclass(category, TruncatedVideoWarning):
        text = text.removesuffix("; reading those")
        text += "; runs read those: copy the whole file again, or record it again"
    return Problem(path, text, "warning")


_LUMA = np.array([0.299, 0.587, 0.114], dtype=np.float32)
"""BT.601 luma weights: how the press detector's small frames are grey."""


def _small_reference(press: Press) -> np.ndarray:
    """(h, w) float32: the no-contact reference of a press video, grey and block-averaged to
    about 40x30 like the frames the press detector sees (5 KB: `_pressed_start_problems`
    compares the references of a whole dataset)."""
    grey = press.reference @ _LUMA
    return _shrink(grey, _block_factor(*grey.shape))


def decode_problem(path: Path, modality: Modality) -> _Decoded:
    """Decode one file as ``data check`` does (every frame of a press video), and say what is
    wrong with it, if anything. Inside `_recording_video_warnings` (as `check_dataset` decodes),
    what `read_press` warns of a video is in `_Decoded.warned` rather than warned."""
    into: list[tuple[type[Warning], str]] = []
    _recording.into = into
    try:
        decoded = _decode(path, modality)
    finally:
        _recording.into = None
    if not into:
        return decoded
    return replace(decoded, warned=tuple(_warned_problem(path, c, m) for c, m in into))


def _decode(path: Path, modality: Modality) -> _Decoded:
    config = DataConfig()
    try:
        if modality is Modality.TOUCH and is_video(path):
            press = read_press(path)  # decodes every frame and finds the press
            h, w = press.images.shape[1:3]
            return _Decoded(size=(w, h), grey=press.grey, reference=_small_reference(press))
        if modality is Modality.DEPTH:
            d = decode_depth(path)
            size = (d.shape[1], d.shape[0])
            if not d.any():
                blank = Problem(path, "depth image has no valid pixel (all 0)", "warning")
                return _Decoded(blank, size)
            unit = _depth_unit_problem(path, d)
            if unit is not None:
                return _Decoded(unit, size)
            low = config.depth_min_mm
            return _Decoded(None, size, _depth_sample(d, low, low + config.depth_range_mm))
        rgb = decode_rgb(path)
        return _Decoded(size=(rgb.shape[1], rgb.shape[0]), grey_image=_is_grey(rgb))
    except NoPressError as e:
        return _Decoded(Problem(path, f"{e.reason}; runs leave this recording out", "warning"))
    except ImageError as e:
        return _Decoded(Problem(path, e.reason))


def _is_grey(rgb: np.ndarray) -> bool:
    """Whether the (H, W, 3) image ``rgb`` has the same value in its red, green and blue
    everywhere: a greyscale file (mode L or LA, converted to RGB as it is read) or grey stored
    as colour. Every 8th pixel of every 8th row first, which almost any colour image fails,
    so that only a grey one is compared whole."""

    def equal(a: np.ndarray) -> bool:
        return bool((a[..., 0] == a[..., 1]).all() and (a[..., 1] == a[..., 2]).all())

    return equal(rgb[::8, ::8]) and equal(rgb)


def check_dataset(
    root: str | Path,
    require: Iterable[Modality] | None = None,
    *,
    workers: int = 2,
    progress: bool = False,
) -> Catalog:
    """Scan ``root`` and decode every file the scan accepted (all frames of every press).

    Files are only read. Problems found while decoding (truncated or undecodable files, depth
    that is not 16-bit) are added to the scan's; those items are dropped from the catalog. A
    touch video is decoded and its press found; one without a press is a warning (runs leave
    it out: `lookfeel.data.drop_unpressed`), as is what reading it warns in runs (a truncated
    file, more than one press: `_recording_video_warnings`), press videos of more than one
    aspect ratio, grey videos (no colour) among colour ones (`_colour_problems`), grey colour
    or touch images among colour ones (`_grey_image_problems`), images and videos smaller than
    `MIN_SIDE` (`_small_problems`), and a video whose first frames look pressed compared with
    its object's others (`_pressed_start_problems`). A dataset with no usable fabric or only
    one is an error (no command can hold fabrics out of it), as is an unfinished `lookfeel
    synth` world.

    Args:
        root: the dataset folder.
        require: modalities every fabric must have; ``None``: each modality any fabric has.
        workers: decoding threads.
        progress: show a progress bar (tqdm) on stderr of the files decoded (``lookfeel data
            check``: a world of 300 fabrics takes most of a minute).

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
    # A bar over the files decoded, closed (its line cleared) however decoding ends.
    bar = functools.partial(progress_bar, total=len(jobs), desc="check", unit="file", show=progress)
    with _recording_video_warnings():
        if workers > 1 and len(jobs) > 16:
            with ThreadPoolExecutor(workers) as pool:
                decoded = list(bar(pool.map(lambda j: decode_problem(*j), jobs)))
        else:
            decoded = list(bar(decode_problem(*j) for j in jobs))
    new = [d.problem for d in decoded if d.problem is not None]
    new.extend(w for d in decoded for w in d.warned)
    bad = {p.path for p in new if p.severity == "error"}
    sizes = {j[0]: d.size for j, d in zip(jobs, decoded, strict=True) if d.size is not None}
    greys = {j[0]: d.grey for j, d in zip(jobs, decoded, strict=True) if d.grey is not None}
    refs = {
        j[0]: d.reference for j, d in zip(jobs, decoded, strict=True) if d.reference is not None
    }
    grey_images = {
        j[0]: d.grey_image for j, d in zip(jobs, decoded, strict=True) if d.grey_image is not None
    }
    fabrics = []
    for f in catalog.fabrics:
        items = {
            m: tuple(it for it in its if not bad.intersection(it.frames))
            for m, its in f.items.items()
        }
        fabrics.append(replace(f, items={m: its for m, its in items.items() if its}))
    usable = tuple(f for f in fabrics if f.items)
    new.extend(size_problems(catalog.root, usable))
    new.extend(range_problems(catalog.root, [d.depth for d in decoded if d.depth is not None]))
    new.extend(_shape_problems(usable, sizes))
    new.extend(_colour_problems(catalog.root, usable, greys))
    new.extend(_grey_image_problems(usable, grey_images))
    new.extend(_small_problems(usable, sizes))
    new.extend(_pressed_start_problems(usable, refs))
    new.extend(_class_problems(catalog, usable))
    new.extend(duplicate_files(usable))  # a query would find its own copy
    unread, skipped = unread_problems(catalog)
    new.extend(unread)
    scanned = [_what_it_is(p) for p in catalog.problems]
    problems = sorted([*scanned, *new], key=lambda p: (str(p.path), p.line or 0))
    return replace(catalog, fabrics=usable, problems=tuple(problems), skipped=skipped)


def _what_it_is(problem: Problem) -> Problem:
    """A scan's problem, or for a video file the scan refused by its first bytes
    (`NOT_A_VIDEO_CONTAINER`), what decoding it says the file is, in the words ``lookfeel
    predict`` uses (`read_press`: "the file is an image (png_pipe), not a video"). The scan's
    own words stay where decoding finds nothing more to say."""
    if problem.message != NOT_A_VIDEO_CONTAINER or problem.path is None:
        return problem
    said = decode_problem(problem.path, Modality.TOUCH).problem
    return said if said is not None and said.severity == "error" else problem


def range_problems(root: Path, samples: Sequence[tuple[int, int, np.ndarray]]) -> list[Problem]:
    """One warning when fewer than `MIN_IN_RANGE` of the depth maps' valid pixels lie inside
    the range raw depth input maps to [0, 1], by `DataConfig`'s defaults (``data check`` reads
    no run config); files whose values do not read as millimetres are left to their own
    warning."""
    inside = sum(s[0] for s in samples)
    total = sum(s[1] for s in samples)
    if not total or inside >= MIN_IN_RANGE * total:
        return []
    c = DataConfig()
    low, high = c.depth_min_mm, c.depth_min_mm + c.depth_range_mm
    p5, p50, p95 = np.percentile(np.concatenate([s[2] for s in samples]), [5, 50, 95])
    return [
        Problem(
            root / Modality.DEPTH.value,
            f"only {inside / total:.0%} of the valid depth pixels lie between "
            f"{low:,.0f} and {high:,.0f} mm, the range raw depth input maps to 0..1 "
            f"(data.depth_min_mm {low:g}, data.depth_range_mm {c.depth_range_mm:g}: the "
            "defaults; this check reads no run config): the rest become 0 or 1, so the network "
            f"sees an almost constant image; the depth maps' median is {p50:,.0f} mm (5th-95th "
            f"percentile {p5:,.0f}-{p95:,.0f}): set data.depth_min_mm and data.depth_range_mm "
            "so the cloth lies inside (data.depth_input: registered maps heights above the "
            "floor instead and does not use depth_min_mm)",
            "warning",
        )
    ]


_MAX_NAMED = 8
"""Classes named in full by `_class_problems` before the rest are counted."""


def _class_problems(catalog: Catalog, fabrics: Sequence[Fabric]) -> list[Problem]:
    """A warning per label column that held-out fabrics cannot be scored on, counting only the
    usable ``fabrics`` (those with images):

    - a column whose every known value is the same (every hardness 1): nothing to tell apart,
      so a class head (``model.class_heads``) refuses it and a probe learns nothing from it;
    - a text column of classes (some class shared by two fabrics: a column of all-different
      words is descriptions) with classes of one fabric (metal on one object only): held out,
      that fabric's class was never trained on; trained on, it has no held-out fabric, so a
      class head or probe can neither learn nor be scored on it across fabrics.

    A rank (hardness 0/1/2) held by one fabric is no warning: ranks are numbers too, which the
    property head regresses, and a scale's end held by one fabric is common (the tests' tiny
    datasets have one)."""
    path = catalog.root / "labels.csv"
    noun = "object" if any(f.name is not None for f in fabrics) else "fabric"
    out = []
    for col in (*catalog.label_columns, *catalog.text_columns):
        members: dict[str, list[Fabric]] = defaultdict(list)
        for f in fabrics:
            k = f.class_of(col)
            if k is not None:
                members[k].append(f)
        known = sum(len(v) for v in members.values())
        if known >= 2 and len(members) == 1:
            (value,) = members
            out.append(
                Problem(
                    path,
                    f"column {col!r} is constant: every {noun} with a value has {value!r} "
                    f"({known} of {len(fabrics)}), so there is nothing to tell apart: a class "
                    "head (model.class_heads) refuses it, and a probe can neither learn nor "
                    f"score it on held-out {noun}s; add {noun}s that differ, or leave the "
                    "column out",
                    "warning",
                )
            )
            continue
        if col not in catalog.text_columns or max(map(len, members.values()), default=0) < 2:
            continue  # numbers, or all-different words (descriptions)
        single = sorted((k, v[0]) for k, v in members.items() if len(v) == 1)
        if not single:
            continue
        named = ", ".join(f"{k!r} ({f.display_name})" for k, f in single[:_MAX_NAMED])
        more = f" and {len(single) - _MAX_NAMED} more" if len(single) > _MAX_NAMED else ""
        out.append(
            Problem(
                path,
                f"column {col!r}: {len(single)} class(es) of one {noun} each, {named}{more}: "
                f"on whichever side of a split that {noun} falls, its class is either never "
                f"trained on or has no held-out {noun}, so a class head (model.class_heads) or "
                f"probe cannot learn and score it on held-out {noun}s; label more {noun}s of "
                "these classes, or merge them into others",
                "warning",
            )
        )
    return out


SAME_SHAPE_LOG_RATIO = 0.03
"""Two aspect ratios within this of each other (in log, about 3%) are one shape: resized to the
square input alike (`lookfeel.index.query.orientation_of` takes one within it of 1 as square)."""


def _shape(size: tuple[int, int], modality: Modality) -> tuple[int, int]:
    """The shape whose aspect is resized to the square input: 960x720 GelSight frames are
    cropped to their central square first (``data.touch_crop: auto``)."""
    return (1, 1) if modality is Modality.TOUCH and size == GELSIGHT_SIZE else size


def _shape_problems(fabrics: Sequence[Fabric], sizes: dict[Path, tuple[int, int]]) -> list[Problem]:
    """One warning per modality whose images (or press videos) come in more than one aspect
    ratio: each is resized to one square input, so each aspect is stretched differently (a
    portrait frame among landscape ones is most likely rotated). Sizes of one aspect are
    resized alike and not reported."""
    by_size: dict[Modality, dict[tuple[int, int], list[Item]]] = defaultdict(dict)
    for f in fabrics:
        for m, its in f.items.items():
            for it in its:
                size = sizes.get(it.frames[0])
                if size is not None:
                    by_size[m].setdefault(size, []).append(it)
    out = []
    for m, groups in by_size.items():
        common = max(groups, key=lambda k: len(groups[k]))
        cw, ch = _shape(common, m)
        odd = [
            k
            for k in groups
            if abs(math.log((_shape(k, m)[0] / _shape(k, m)[1]) / (cw / ch))) > SAME_SHAPE_LOG_RATIO
        ]
        if not odd:
            continue
        noun = "press" if m is Modality.TOUCH else "image"
        listed = ", ".join(
            f"{w}x{h} ({n} {noun + ('es' if noun == 'press' else 's') if n != 1 else noun})"
            for (w, h), n in Counter({k: len(v) for k, v in groups.items()}).most_common()
        )
        first = groups[odd[0]][0].frames[0]
        ow, oh = _shape(odd[0], m)
        turned = (ow > oh) != (cw > ch) and ow != oh and cw != ch
        what = "frames" if m is Modality.TOUCH else "images"
        out.append(
            Problem(
                first,
                f"{m.value} {what} come in {len(groups)} sizes of different shape: {listed}; "
                "each is resized to the network's one square input (data.image_size), so each "
                "shape is stretched differently"
                + (
                    f" (this one is {'portrait' if oh > ow else 'landscape'} among "
                    f"{'landscape' if oh > ow else 'portrait'} ones: most likely turned)"
                    if turned
                    else ""
                )
                + f"; record them alike, or turn or crop them to {common[0]}x{common[1]}",
                "warning",
            )
        )
    return out


_FEW_GREY = 3
"""Grey press videos that `_colour_problems` names; the others are counted."""

_GREY_READ = (
    "GelSight's and DIGIT's colours carry the surface's slopes, and a grey video gives the "
    "same value in each channel"
)


def _colour_problems(
    root: Path, fabrics: Sequence[Fabric], greys: dict[Path, bool]
) -> list[Problem]:
    """One warning where the touch press videos of ``fabrics`` mix grey ones (no colour:
    `lookfeel.data.video.Press.grey`, as ``greys`` says of each decoded video) and colour
    ones: a model reads the grey ones unlike the others. The warning names the first grey
    video, counts them and names a few. A dataset whose videos are all grey gets one milder
    warning, for ``root``: it trains, but a model trained on colour presses does not read it
    as it reads those. Videos without a press (no entry in ``greys``) are not counted."""
    videos = [
        it.frames[0]
        for f in fabrics
        for it in f.items.get(Modality.TOUCH, ())
        if it.frames[0] in greys
    ]
    grey = [p for p in videos if greys[p]]
    if not grey:
        return []
    if len(grey) == len(videos):
        all_of = (
            f"all {len(videos)} touch press videos have"
            if len(videos) > 1
            else "the one touch press video has"
        )
        return [
            Problem(
                root,
                f"{all_of} no colour (grey): a model trains on them, but one trained on colour "
                f"presses does not read them as it reads those ({_GREY_READ})",
                "warning",
            )
        ]
    return [_grey_among_colour(grey, len(videos), "touch press video", _GREY_READ, "record")]


def _grey_among_colour(grey: Sequence[Path], of: int, noun: str, why: str, fix: str) -> Problem:
    """The warning on ``grey[0]`` that ``grey`` files of ``of`` (``noun``s, all of one modality)
    have no colour, unlike the others: one named alone, several counted with a few named;
    ``why`` it matters, and what to do (``fix``: ``record`` them in colour or ``use`` colour
    originals, or leave them out)."""
    colour = of - len(grey)
    others = "the other one" if colour == 1 else f"the other {colour}"
    if len(grey) == 1:
        what = f"this {noun} has no colour (grey), unlike {others}: a model reads it unlike them"
        todo = "record it in colour" if fix == "record" else "use a colour original"
        return Problem(grey[0], f"{what} ({why}); {todo}, or leave it out", "warning")
    named = ", ".join(p.name for p in grey[:_FEW_GREY])
    more = f" and {len(grey) - _FEW_GREY} more" if len(grey) > _FEW_GREY else ""
    what = (
        f"{len(grey)} of the {of} {noun}s have no colour (grey), unlike {others}: "
        f"{named}{more}; a model reads them unlike the others"
    )
    todo = "record them in colour" if fix == "record" else "use colour originals"
    return Problem(grey[0], f"{what} ({why}); {todo}, or leave them out", "warning")


_GREY_IMAGE_READ = {
    Modality.COLOR: "a photo's colours are part of what the colour network reads, and a grey "
    "image gives the same value in each channel",
    Modality.TOUCH: "GelSight's and DIGIT's colours carry the surface's slopes, and a grey "
    "frame gives the same value in each channel",
}
_IMAGE_NOUN = {Modality.DEPTH: "depth image", Modality.COLOR: "colour image"}


def _grey_image_problems(fabrics: Sequence[Fabric], greys: dict[Path, bool]) -> list[Problem]:
    """One warning per modality (colour, touch) whose still images mix grey ones (the same
    value in each channel everywhere: `_is_grey`, as ``greys`` says of each decoded file) and
    colour ones, as `_colour_problems` warns of press videos: a grey image is read as colour
    with red, green and blue equal, unlike anything a network trained on the colour ones saw.
    The warning names the first grey image, counts them and names a few. Press videos
    (`_colour_problems`) and depth (always one channel) are not counted; a modality whose
    images are all grey is not warned of (a network trained on it reads it alike)."""
    out = []
    for m in (Modality.COLOR, Modality.TOUCH):
        files = [p for f in fabrics for it in f.items.get(m, ()) for p in it.frames if p in greys]
        grey = [p for p in files if greys[p]]
        if not grey or len(grey) == len(files):
            continue
        noun = "touch frame" if m is Modality.TOUCH else _IMAGE_NOUN[m]
        out.append(_grey_among_colour(grey, len(files), noun, _GREY_IMAGE_READ[m], "use"))
    return out


def _small_problems(fabrics: Sequence[Fabric], sizes: dict[Path, tuple[int, int]]) -> list[Problem]:
    """One warning per modality with images (or press videos) whose shorter side is below
    `MIN_SIDE`: each is enlarged to the network's input and holds no texture. It names the
    first such file and its size, counts the others and names a few."""
    out = []
    for m in Modality:
        small = [
            p
            for f in fabrics
            for it in f.items.get(m, ())
            for p in it.frames
            if p in sizes and min(sizes[p]) < MIN_SIDE
        ]
        if not small:
            continue
        if m is not Modality.TOUCH:
            noun = _IMAGE_NOUN[m]
        elif all(is_video(p) for p in small):
            noun = "touch press video"
        else:
            noun = "touch frame" if not any(is_video(p) for p in small) else "touch file"
        w, h = sizes[small[0]]
        if len(small) == 1:
            what = f"this {noun} is {w}x{h} px: smaller than {MIN_SIDE} px on its shorter side"
            rest = "it holds no texture, and is"
            fix = "use the full-size file, or leave it out"
        else:
            named = ", ".join(p.name for p in small[1 : 1 + _FEW_GREY])
            left = len(small) - 1 - _FEW_GREY
            more = f" and {left} more" if left > 0 else ""
            what = (
                f"this {noun} is {w}x{h} px, and {len(small) - 1} more are smaller than "
                f"{MIN_SIDE} px on their shorter side too: {named}{more}"
            )
            rest = "they hold no texture, and each is"
            fix = "use the full-size files, or leave them out"
        out.append(
            Problem(
                small[0],
                f"{what}; {rest} enlarged to the network's input (data.image_size, mostly 64 to "
                f"320 px); {fix}",
                "warning",
            )
        )
    return out


PRESSED_START_LEVELS = 4.0
"""How far, in grey levels, a press video's no-contact reference may differ locally from the
references of the other videos of its object (`_pressed_start_problems`), once a change of the
whole frame's light is removed, before ``data check`` says its first frames look pressed.

The change is measured as the press detector measures contact (`lookfeel.data.video`'s
``_light_change``: the mean of the 5% most changed pixels of the small grey frame, after the
best gain and offset of the whole frame), from the per-pixel median of the object's references.
On the 398 PhysiCLeAR presses it is 1.0 (median), 1.5 (95th percentile), 6.8 (99th) and at most
18.5; above 4 are 4 videos recorded in another session than their object's other videos
(``wood_ruler_5``, ``toothbrush_handle_5`` ...: 15-18.5) and ``tissue_0`` and ``tissue_1``
(5.4, 6.5), each within 2.6 of the reference of another object's video (the next check), so
none is warned. Of 84 clips cut from 21 of those videos to begin inside the contact span (5
frames into it, at its deepest frame, 30 frames from 10 before it, wholly inside it), the press
detector refuses 40 (most for a moving start); the other 44 differ by about as much as the
press is deep at their first frame, 1.7-16.3 (QA's two egg clips, held pressed: about 8). Above
4 are 33: every clip of a press deeper than 3.5 grey levels (a press: median 7.3; 15% are
shallower) but one cut wholly inside a 5.3-level press (3.4); the other 10, of presses of 1-3
levels, differ hardly more than untouched gels do from each other (2.6, above)."""


def _pressed_start_problems(
    fabrics: Sequence[Fabric], refs: dict[Path, np.ndarray]
) -> list[Problem]:
    """A warning per press video whose first frames look pressed, compared with the other
    videos of its object.

    `read_press` takes a video's first frames as the untouched gel. A video that begins
    mid-press but held still passes for one (`lookfeel.data.video.detect_press` refuses a
    moving start only), and every run reads its press against a pressed gel. One video alone
    cannot tell; but the videos of one object are mostly recorded in one session (one sensor,
    one light), so their references (``refs``, small and grey: `_small_reference`) are alike.
    A reference that differs from the per-pixel median of its object's references (the other
    one's, for an object of two videos) locally, once a change of the whole frame's light is
    removed (`lookfeel.data.video._light_change`), by more than `PRESSED_START_LEVELS`, and from
    every reference that is like its own object's, began pressed; one like some other object's
    reference was recorded untouched in another session (PhysiCLeAR has four). Objects with one
    video, and references of another size than the object's others, are not compared."""
    groups: list[tuple[Fabric, list[Path]]] = []
    for f in fabrics:
        by_size: dict[tuple[int, ...], list[Path]] = defaultdict(list)
        for it in f.items.get(Modality.TOUCH, ()):
            if it.frames[0] in refs:
                by_size[refs[it.frames[0]].shape].append(it.frames[0])
        groups.extend((f, paths) for paths in by_size.values() if len(paths) >= 2)
    unlike: list[tuple[Fabric, Path, float]] = []
    alike: dict[tuple[int, ...], list[np.ndarray]] = defaultdict(list)
    for f, paths in groups:
        stack = np.stack([refs[p] for p in paths])
        centre = np.median(stack, axis=0) if len(paths) > 2 else None
        for i, path in enumerate(paths):
            change = _light_change(stack[1 - i] if centre is None else centre, stack[i])[0]
            if change > PRESSED_START_LEVELS:
                unlike.append((f, path, change))
            else:
                alike[stack[i].shape].append(stack[i])
    out = []
    for f, path, change in unlike:
        if _like_one_of(refs[path], alike[refs[path].shape]):
            continue
        out.append(
            Problem(
                path,
                f"its first frames look pressed compared with the other videos of "
                f"{f.display_name}: once a change of the whole frame's light is removed, they "
                f"differ from theirs by {change:.1f} grey levels where they differ most (an "
                f"untouched gel: less than {PRESSED_START_LEVELS:g}; a press: about 7), and "
                "from every other object's too, so the recording most likely began mid-press "
                "and runs read its press against a pressed gel: record from before the press, "
                "or leave this video out",
                "warning",
            )
        )
    return out


_NEAREST = 32
"""References `_like_one_of` compares, the closest by mean difference first."""


def _like_one_of(reference: np.ndarray, others: Sequence[np.ndarray]) -> bool:
    """Whether ``reference`` differs from one of ``others`` (of its size) by at most
    `PRESSED_START_LEVELS` once a change of the whole frame's light is removed: of the
    `_NEAREST` closest to it in mean absolute difference (their means removed), nearest first."""
    if not others:
        return False
    stack = np.stack(others)
    flat = stack.reshape(len(stack), -1)
    flat = flat - flat.mean(axis=1, keepdims=True)
    mine = reference.reshape(-1) - reference.mean()
    order = np.argsort(np.abs(flat - mine).mean(axis=1))[:_NEAREST]
    return any(_light_change(stack[j], reference)[0] <= PRESSED_START_LEVELS for j in order)


def _modality_folder(path: Path, root: Path) -> Modality | None:
    """The modality of the layout folder ``path`` lies directly in, if it lies in one."""
    if path.parent.parent != root:
        return None
    low = path.parent.name.lower()
    for m, names in FOLDER_ALIASES.items():
        if low in names or (m is Modality.TOUCH and low.startswith("image_rand")):
            return m
    return None


def _holds_images(folder: Path) -> bool:
    """Whether ``folder`` directly holds an image file (one lookfeel reads or not)."""
    suffixes = {*IMAGE_SUFFIXES, *UNREAD_IMAGE_SUFFIXES}
    return any(q.suffix.lower() in suffixes and q.is_file() for q in folder.iterdir())


_PRESS_FOLDER = re.compile(r"^F0*(\d+)_(?:(fold|flat|rand)_)?([A-Za-z0-9-]+)$", re.IGNORECASE)


def unread_problems(catalog: Catalog) -> tuple[list[Problem], tuple[Problem, ...]]:
    """Errors for what the scan skipped but was meant as data, and the skips left.

    Files in a modality folder whose suffix is an image format lookfeel does not read
    (`UNREAD_IMAGE_SUFFIXES`: a float TIFF of depth in metres) are one error per folder and
    suffix, saying what to convert them to; subfolders of a modality folder that hold a press's
    frames (named ``F<id>_<kind>_<press>``), or that hold the only images of a folder from
    which nothing was read, are one error per folder, saying the layout expected. A ``.jpg``
    in ``depth/`` is an error of the scan already; these are the same mistake."""
    root = catalog.root
    read_from = {it.path.parent for f in catalog.fabrics for its in f.items.values() for it in its}
    files: dict[tuple[Path, str], list[Path]] = defaultdict(list)
    folders: dict[Path, list[Path]] = defaultdict(list)
    left = []
    for p in catalog.skipped:
        path = p.path
        m = None if path is None else _modality_folder(path, root)
        if path is None or m is None:
            left.append(p)
        elif not path.is_dir() and path.suffix.lower() in UNREAD_IMAGE_SUFFIXES:
            files[(path.parent, path.suffix.lower())].append(path)
        elif (
            path.is_dir()
            and (_PRESS_FOLDER.match(path.name) or path.parent not in read_from)
            and _holds_images(path)
        ):
            folders[path.parent].append(path)
        else:
            left.append(p)
    out = []
    for (folder, suffix), paths in files.items():
        m = _modality_folder(paths[0], root)
        assert m is not None
        more = f" (and {len(paths) - 1} more {suffix} in {folder.name}/)" if len(paths) > 1 else ""
        out.append(
            Problem(
                paths[0],
                f"lookfeel does not read {suffix} files{more}: {m.value} must be "
                f"{_CONVERT[m]}; convert {'each' if more else 'it'} (the scan skips these "
                f"files, so runs read no {m.value} from them)",
            )
        )
    for folder, subs in folders.items():
        m = _modality_folder(subs[0], root)
        assert m is not None
        more = f" (and {len(subs) - 1} more subfolders)" if len(subs) > 1 else ""
        suffixes = {*IMAGE_SUFFIXES, *UNREAD_IMAGE_SUFFIXES}
        example = min(q.name for q in subs[0].iterdir() if q.suffix.lower() in suffixes)
        press = _PRESS_FOLDER.match(subs[0].name)
        if m is Modality.TOUCH and press is not None:
            fid, kind, name = int(press.group(1)), press.group(2) or "fold", press.group(3)
            frames = "touch" if folder.name.lower() == "videos" else folder.name
            how = (
                f"put each frame in {frames}/ itself, named F<id>_<kind>_<frame>_<press>.png "
                f"(here F{fid:04d}_{kind}_01_{name}.png, F{fid:04d}_{kind}_02_{name}.png ... in "
                f"frame order), or the press as one video in {folder.name}/ "
                f"(F{fid:04d}_{kind}_{name}.mp4)"
            )
        else:
            how = f"put its files in {folder.name}/ itself, named F<id>_... (e.g. F0012_1.png)"
        out.append(
            Problem(
                subs[0],
                f"a subfolder of {folder.name}/{more} holding images (e.g. {example}), which "
                f"are not read (the layout is flat): {how}",
            )
        )
    return out, tuple(left)


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
