"""What an input feels like: a trained model's heads read on query files.

`predict_files` embeds each query (a touch video, a touch frame, a depth map or a photo) as
training did and reads the model's heads: each class head (``model.class_heads``: ranks such as
hardness 0/1/2, or words such as material) gives its most likely class and every class's
probability; a property-regression head (``model.num_properties``) gives values in the label
columns' own units. Several presses of one object can be pooled into one query, as the
Multi-input Net pools presses (``together=True``).

A touch query must be what the model was trained on: a model trained on press videos refuses a
still GelSight frame (`lookfeel.index.query.check_touch_query`), naming the file; a model
trained on still frames takes a press video with a warning, unless it stacks a press's frame
images (``data.touch_frames``), which no video has: it refuses one, saying what to give
(`lookfeel.index.match.check_touch_input`). Without a modality given, each
file's own kind says what it shows (`guess_modality`); one the model lacks is refused.

A query whose orientation (portrait or landscape) differs from that of the items the model was
trained on is answered with one warning (`lookfeel.index.query.warn_orientation`): it is
stretched unlike them and most likely turned. A checkpoint from before the record
(`lookfeel.checkpoint.LoadedModel.shapes`) is not checked. A press video with no colour (grey)
is answered with one warning naming it (`lookfeel.index.match.warn_grey_videos`): the model
reads a press's colours, and one trained on colour presses reads a grey one unlike them. A
model whose checkpoint says it was trained on grey presses (`lookfeel.checkpoint.LoadedModel.
trained_on_grey`) is warned of a colour press video instead.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from lookfeel.checkpoint import LoadedModel, load_model
from lookfeel.data.files import ImageError
from lookfeel.data.images import png_header
from lookfeel.data.layout import FOLDER_ALIASES, IMAGE_SUFFIXES
from lookfeel.data.video import VIDEO_SUFFIXES, NoPressError
from lookfeel.devices import resolve_device
from lookfeel.errors import LookfeelError, caller_stacklevel
from lookfeel.index.match import (
    check_touch_input,
    class_value,
    warn_grey_videos,
    warn_press_kinds,
)
from lookfeel.index.query import (
    QUERY_IMAGES,
    QueryFiles,
    load_query_files,
    query_batch,
    query_paths,
    warn_orientation,
)
from lookfeel.modality import Modality
from lookfeel.models import CLASSES, PROPERTY, eval_mode

__all__ = ["PredictError", "Prediction", "PropertyValue", "guess_modality", "predict_files"]


class PredictError(LookfeelError):
    """A query the model cannot answer (no head to read, a modality it lacks)."""


@dataclass(frozen=True)
class PropertyValue:
    """One predicted property.

    Attributes:
        value: the class in the label column's own terms (the rank ``2``, the word ``"metal"``)
            or a regressed number. A column of ranks without a class head: the rank nearest
            the property head's number (``number``), among the ranks the training data held.
        probability: the class's probability (class heads); None for a regressed number.
        probabilities: every class's probability, in the head's class order.
        number: for a rank read from the property head, the number it regressed (``0.93``
            for the rank ``1``); None otherwise.
    """

    value: int | float | str
    probability: float | None = None
    probabilities: dict[str, float] = field(default_factory=dict)
    number: float | None = None


@dataclass(frozen=True)
class Prediction:
    """What one query is predicted to feel like.

    Attributes:
        path: the query's file (the first, when presses are pooled).
        paths: every file of the query.
        modality: what the files show (None when that could not be told: ``error`` says why).
        properties: label column -> its predicted `PropertyValue` (empty with ``error``).
        error: why nothing is predicted, naming the file: it is missing, a folder or of no
            kind the model takes (a still touch image for a model of press videos), it cannot
            be read or decoded (an empty file, an image renamed ``.mp4``), or a press video
            holds no press (too short, no contact). None when the query was answered.
    """

    path: str
    paths: list[str]
    modality: str | None
    properties: dict[str, PropertyValue]
    error: str | None = None


def guess_modality(
    path: Path, model_modalities: Sequence[Modality], holder: str = "the model"
) -> Modality:
    """The modality of a query file: a video is touch; an image in a folder of the dataset
    layout (``depth/``, ``color/``, ``touch/`` and their aliases,
    `lookfeel.data.layout.FOLDER_ALIASES`) is that folder's; a 16-bit greyscale PNG is depth;
    else an image is the model's only modality.

    What the file itself says (its suffix, folder or PNG header) decides first, whatever the
    model has: a photo in ``color/`` is not read as touch because the model has touch only; it
    is refused, naming what the model has and ``--modality``, which reads it so anyway.

    Args:
        path: the query file.
        model_modalities: the modalities queries may be of: the model's (``lookfeel
            match``: those of the library's model that the library holds).
        holder: what has ``model_modalities``, as errors name it (``"the library"``).

    Raises:
        PredictError: the file does not say and the model has several modalities; or it says
            one the model lacks.
        ImageError: the path is a folder or does not exist, or is neither an image
            (`QUERY_IMAGES`) nor a video by its suffix.
    """
    if path.is_dir():
        raise ImageError(path, "is a folder, not an image or video file: give the files in it")
    if not path.exists():  # before its folder is read as a modality the model may lack
        raise ImageError(path, "file not found")
    suffix = path.suffix.lower()
    names = [m.value for m in model_modalities]
    have = ", ".join(names[:-1]) + " or " + names[-1] if len(names) > 1 else "".join(names)
    folder = path.parent.name.lower()
    by_folder = next((m for m, aliases in FOLDER_ALIASES.items() if folder in aliases), None)
    if suffix in VIDEO_SUFFIXES:
        modality, why = Modality.TOUCH, "a video is a touch press"
    elif suffix not in IMAGE_SUFFIXES:
        videos = ", ".join(VIDEO_SUFFIXES)
        raise ImageError(path, f"not {QUERY_IMAGES} or a press video ({videos})")
    elif by_folder is not None:
        modality, why = (
            by_folder,
            f"an image in a {path.parent.name}/ folder shows {by_folder.value}",
        )
    elif suffix == ".png" and _is_16_bit_grey(path):
        modality, why = Modality.DEPTH, "a 16-bit greyscale PNG is a depth map"
    elif len(model_modalities) == 1:
        return model_modalities[0]
    else:
        raise PredictError(
            f"{path}: cannot tell which modality the image shows (it is in no depth/, color/ "
            f"or touch/ folder, and not a 16-bit depth PNG): say which with --modality {have}"
        )
    if modality in model_modalities:
        return modality
    force = (
        ""
        if suffix in VIDEO_SUFFIXES  # a video is read as nothing else
        else f"; give --modality {have} to read it as "
        + (have if len(names) == 1 else "one of those")
        + " anyway"
    )
    raise PredictError(
        f"{path}: {why}, which {holder} does not take (it takes {', '.join(names)}){force}"
    )


def _is_16_bit_grey(path: Path) -> bool:
    """Whether a PNG's header declares 16-bit greyscale (a depth map), read from its first 26
    bytes; False for anything unreadable."""
    try:
        with path.open("rb") as f:
            header = png_header(f.read(26))
    except OSError:
        return False
    return header is not None and header[2:] == (16, 0)


def _heads(loaded: LoadedModel) -> None:
    cfg = loaded.config.model
    if not cfg.class_heads and not cfg.num_properties:
        raise PredictError(
            f"{loaded.path}: this model has no property heads to read; train one with "
            "model.class_heads (classes such as hardness or material) or model.num_properties "
            "(e.g. configs/physiclear.yaml)"
        )


def predict_files(
    loaded: LoadedModel | str | os.PathLike[str],
    paths: QueryFiles,
    modality: Modality | str | None = None,
    *,
    together: bool = False,
    device: torch.device | str = "cpu",
) -> list[Prediction]:
    """Predict the properties of each query file (or of all of them as one object).

    Args:
        loaded: a checkpoint's model (`lookfeel.checkpoint.load_model`), or a checkpoint's
            path, loaded onto ``device``.
        paths: query files: videos or images of one modality; a single path (``str`` or
            `~pathlib.Path`) is one file.
        modality: what the files show, a `Modality` or its name (``"touch"``); default:
            guessed per file (`guess_modality`).
        together: the files are presses of one object: pool them into one query (touch only).
        device: where the network runs.

    Returns:
        One `Prediction` per file, or one for all with ``together``. A query whose file the
        model cannot take (missing, a folder, by its suffix neither an image nor a video, a
        still touch image for a model trained on press videos, a press video for a model that
        stacks frame images: each file is asked before any is decoded,
        `lookfeel.index.match.check_touch_input`), cannot be read (a video FFmpeg
        cannot decode, an empty file, an image renamed ``.mp4``, a damaged image) or whose
        video holds no press (too short, no contact) is answered with its ``error``, naming
        the file, and no properties, the only query as well as one of several (the others are
        still predicted); ``lookfeel predict`` exits with 1 when
        every query was answered so. With ``together``, a press without one is left out of
        the pooled query with a warning (as a run leaves it out), and the query is answered
        from the others (its ``paths``); a file that cannot be read is the pooled query's
        ``error``, which names it. A press video with no colour (grey) is answered with a
        warning naming it (`lookfeel.index.match.warn_grey_videos`); by a model trained on
        grey presses, a colour one instead.

    Raises:
        PredictError: the model has no heads, or lacks a file's modality, what a file shows
            cannot be told, no file is given, or with ``together`` the files mix modalities or
            are not touch presses.
        ModalityError: ``modality`` names no modality.
        DeviceError: ``device`` is none this machine can use.
        CheckpointError: ``loaded`` is a path that holds no usable checkpoint.
    """
    device = resolve_device(device)  # a device this machine lacks: one line
    if not isinstance(loaded, LoadedModel):
        loaded = load_model(loaded, device)
    _heads(loaded)
    if modality is not None:
        modality = Modality.of(modality)
    cfg = loaded.config.model
    if cfg.class_heads and not any(c in cfg.class_temperature for c in cfg.class_heads):
        warnings.warn(
            f"{loaded.path}: its class heads' probabilities are as trained, not calibrated "
            "(no model.class_temperature): on objects they never saw, such heads are often "
            "far surer than they are right; `lookfeel cv` fits a temperature for each",
            stacklevel=caller_stacklevel(),
        )
    model = loaded.model
    have = list(model.modalities)
    try:
        files = query_paths(paths)
    except LookfeelError:
        raise PredictError("no input file given") from None
    # Each file is asked, before any is decoded, whether this model can take it: a missing
    # file, a folder, a file of no known kind or of a modality the model lacks, a still touch
    # image for a model of press videos ... is its own query's error; the others are answered.
    refused: dict[Path, str] = {}
    mods: list[Modality | None] = []
    for p in files:
        m, why = _query_modality(p, modality, have, loaded)
        mods.append(m)
        if why is not None:  # this file's own problem (a question of modality stops all)
            refused[p] = why
    known = {m for p, m in zip(files, mods, strict=True) if m is not None and p not in refused}
    if together and len(known) > 1:
        raise PredictError(
            "--together (together) pools presses of one object: give files of one modality"
        )
    if together and known and Modality.TOUCH not in known:
        raise PredictError(
            "--together (together) pools touch presses; depth and colour are one image each"
        )
    data = loaded.config.data
    ok = [(p, m) for p, m in zip(files, mods, strict=True) if m is not None and p not in refused]
    touch = [p for p, m in ok if m is Modality.TOUCH]
    if touch:
        check_touch_input(touch, loaded.touch_input, data)  # its one warning, if any
        warn_press_kinds(touch, data)
    for om in dict.fromkeys(m for _, m in ok):  # a query turned against the training items
        of_m = [p for p, m in ok if m is om]
        warn_orientation(of_m, om, loaded.shapes.get(om), data, "the model")
    groups = [files] if together else [[p] for p in files]
    group_mods = [next(iter(known), None)] if together else mods
    out = []
    # Not a decorator: a warning above names the caller's line, not torch's wrapper.
    with torch.inference_mode(), eval_mode(model):
        for group, m in zip(groups, group_mods, strict=True):
            if m is None or any(p in refused for p in group):
                first = next(p for p in group if p in refused)
                error = _input_error(ImageError(first, ""), group, refused[first])
                shown = m.value if m is not None else None
                out.append(Prediction(str(group[0]), [str(p) for p in group], shown, {}, error))
                continue
            grey: dict[Path, bool] = {}  # of each press video, as reading it found
            try:
                images, group = load_query_files(group, m, data, on_video=grey.__setitem__)
            except ImageError as e:  # this input only: undecodable, unreadable, or no press
                error = _input_error(e, group)
                out.append(Prediction(str(group[0]), [str(p) for p in group], m.value, {}, error))
                continue
            if m is Modality.TOUCH:
                warn_grey_videos(group, grey, loaded.trained_on_grey)  # answered all the same
            x = query_batch(images, m).to(device)
            outputs = model({m.value: x}, heads=True)
            out.append(
                Prediction(
                    path=str(group[0]),
                    paths=[str(p) for p in group],
                    modality=m.value,
                    properties=_read_heads(loaded, outputs, m.value),
                )
            )
    return out


def _input_error(e: ImageError, group: Sequence[Path], said: str | None = None) -> str:
    """Why one query is not answered, in one line naming the file at fault: ``e`` names it
    (``said``: the line, where it was said before); for presses given together it also says
    that the pooled query was lost with it (a file that cannot be decoded or that the model
    cannot take), or that every press lacks contact (a `NoPressError`: one without is left
    out, so the error of the first means all of them)."""
    line = str(e) if said is None else said
    if len(group) < 2:
        return line
    if isinstance(e, NoPressError):
        return f"{line}; none of the {len(group)} presses given together holds a usable press"
    return f"{line}; it is one of the {len(group)} presses given together"


def _unsaid(line: str) -> None:
    """A warning not said here (`_query_modality`: the caller says it once for every file)."""


def _query_modality(
    path: Path, modality: Modality | None, have: Sequence[Modality], loaded: LoadedModel
) -> tuple[Modality | None, str | None]:
    """What query file ``path`` shows (``modality``, else `guess_modality`; None when that
    cannot be asked of a missing file or a folder), and why the model cannot take it, if it
    cannot: the file is missing, a folder, or a touch file of a kind its model does not read
    (`lookfeel.index.match.check_touch_input`, its warning left to the caller, who gives it
    once for all the files). That is the file's own query's error.

    Raises:
        PredictError: what it shows cannot be told, or the model lacks it (every query's:
            ``--modality`` answers it).
    """
    if not path.exists():  # before asking what a missing file shows
        return modality, str(ImageError(path, "file not found"))
    try:
        m = modality or guess_modality(path, have)
    except ImageError as e:  # a folder, a file of no known kind
        return modality, str(e)
    if m not in have:
        raise PredictError(
            f"{path}: the model has no {m.value} branch (it has {', '.join(x.value for x in have)})"
        )
    if m is Modality.TOUCH:
        try:  # its warning is said once for every file, by the caller
            check_touch_input([path], loaded.touch_input, loaded.config.data, warn=_unsaid)
        except ImageError as e:
            return m, str(e)
    return m, None


def _read_heads(
    loaded: LoadedModel, outputs: dict[str, torch.Tensor], slot: str
) -> dict[str, PropertyValue]:
    cfg = loaded.config.model
    props: dict[str, PropertyValue] = {}
    logits = outputs.get(f"{slot}/{CLASSES}")
    if logits is not None:
        parts = logits[0].float().split(cfg.class_sizes)
        for col, z in zip(cfg.class_heads, parts, strict=True):
            z = z / float(cfg.class_temperature.get(col, 1.0))
            p = torch.softmax(z, dim=0).cpu().numpy().astype(np.float64)
            names = cfg.classes[col]
            best = int(p.argmax())
            props[col] = PropertyValue(
                value=class_value(names[best]),
                probability=round(float(p[best]), 4),
                probabilities={n: round(float(q), 4) for n, q in zip(names, p, strict=True)},
            )
    reg = outputs.get(f"{slot}/{PROPERTY}")
    if reg is not None:
        stats = loaded.label_stats
        for col, v in zip(loaded.label_columns, reg[0].float().cpu().tolist(), strict=False):
            if col in props:
                continue  # a class head answers in the column's own terms already
            mean, std = stats.get(col, (0.0, 1.0))
            number = round(mean + std * float(v), 4)
            ranks = loaded.rank_columns.get(col)
            if ranks:  # a column of ranks: answered in its own terms, the number beside
                rank = min(ranks, key=lambda r: (abs(r - number), r))
                props[col] = PropertyValue(value=rank, number=number)
            else:
                props[col] = PropertyValue(value=number)
    return props
