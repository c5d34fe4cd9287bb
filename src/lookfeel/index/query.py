"""Query images: decoded and preprocessed exactly as in training, checked with clear errors.

A query is one or more image files of one modality, each image a PNG or JPEG (`QUERY_IMAGES`,
as ``lookfeel serve`` takes them). Depth is a 16-bit PNG in millimetres, colour an 8-bit RGB
photo, touch a press's video (`VIDEO_SUFFIXES`: .mov, .mp4 ...; its frame of deepest contact is
found as in training) or one GelSight frame per press (the frame you would use for training: by
default the second-to-last of a press; for a model that reads several frames of a press
together, ``data.touch_frames``, any one of them, the others read from beside it).
Preprocessing is the run's `DataConfig` through `lookfeel.data.images.preprocess_depth` /
`preprocess_rgb`, the functions training uses. No image is cached, so a path reused for
different content is always read afresh.

A touch query must be what the model's touch branch was trained on (the checkpoint's
``touch_input``, `lookfeel.checkpoint.LoadedModel.touch_input`): a model trained on press
videos read as their change from the no-contact frames (``data.video_reference: subtract``)
refuses a still frame, which has no such frames (`check_touch_query`). A model trained on still
frames takes a video too, read as `lookfeel.data.video` reads one, with a warning where that
read is such a difference, which the model never saw; a checkpoint from before the record is not
checked.

A query whose orientation (portrait or landscape, `orientation_of`) differs from that of the
images its model is compared with is taken with one warning (`warn_orientation`): each is
resized to the network's one square input, so such a query is stretched unlike them and is
most likely turned (a DIGIT's 240x320 press given as 320x240). Only a record of those images'
shape says what they were: a library records its items' (`shape_record`, in its manifest) and
a checkpoint since session 51 its training items' (``shapes``, `LoadedModel.shapes`, which
``lookfeel predict`` checks); an older one is not checked. Shapes are as the model reads the
files: a press video's turned by ``data.video_rotate`` (`seen_size`), which the warning about
a turned video names. A file is taken for a video as it is read: a file on disk by its suffix
(as `lookfeel.data.video.is_video` reads it), an upload by its content (`sniff_video`, as
`load_query_bytes` reads it).
"""

from __future__ import annotations

import io
import math
import os
import stat
import tempfile
import warnings
from collections import Counter
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from lookfeel.checkpoint import TOUCH_FRAMES, TOUCH_VIDEOS
from lookfeel.config import DataConfig
from lookfeel.data import decode_depth
from lookfeel.data.check import SAME_SHAPE_LOG_RATIO
from lookfeel.data.images import (
    DEFAULT_MAX_PIXELS,
    GELSIGHT_SIZE,
    ImageError,
    ImageLoader,
    declared_size,
    open_rgb,
    preprocess_depth,
    preprocess_rgb,
    read_image_file,
    stack_views,
    to_tensor,
)
from lookfeel.data.layout import IMAGE_SUFFIXES, VIDEO_SUFFIXES, sniff_video
from lookfeel.data.video import NoPressError, is_grey_video
from lookfeel.errors import LookfeelError, caller_stacklevel
from lookfeel.modality import Modality
from lookfeel.models.backbone import ModelInputError

__all__ = [
    "IMAGE_TYPES",
    "NO_VALID_DEPTH",
    "ORIENTATIONS",
    "QUERY_IMAGES",
    "STILL_TOUCH_REFUSED",
    "VIDEOS_ARE_TOUCH",
    "VIDEO_FOR_STILL_MODEL",
    "QueryFiles",
    "bytes_frame_size",
    "check_touch_files",
    "check_touch_query",
    "frame_size",
    "load_query_bytes",
    "load_query_files",
    "load_query_image",
    "orientation_note",
    "orientation_of",
    "query_batch",
    "query_paths",
    "seen_size",
    "shape_record",
    "sniff_type",
    "warn_orientation",
]

QueryFiles = str | os.PathLike[str] | Iterable[str | os.PathLike[str]]
"""The files of a query: one path (a ``str`` or `~pathlib.Path`), or several."""


def query_paths(paths: QueryFiles) -> list[Path]:
    """The files of a query as a list: a single path, a ``str`` included, is one file (not a
    sequence of one-letter names); any other iterable gives its paths in order.

    Raises:
        LookfeelError: no file given (an empty list).
    """
    files = _paths(paths)
    if not files:
        raise LookfeelError("no query file given: a query needs at least one file")
    return files


def _paths(paths: QueryFiles) -> list[Path]:
    """`query_paths`, an empty list allowed."""
    if isinstance(paths, (str, os.PathLike)):
        return [Path(paths)]
    return [Path(p) for p in paths]


IMAGE_TYPES = {"image/png": b"\x89PNG\r\n\x1a\n", "image/jpeg": b"\xff\xd8\xff"}
"""The image types a query may be: content type -> the bytes its files begin with."""


def sniff_type(head: bytes) -> str | None:
    """The content type of an image from its first bytes (PNG or JPEG), else None."""
    for mime, magic in IMAGE_TYPES.items():
        if head.startswith(magic):
            return mime
    return None


QUERY_IMAGES = f"a PNG or JPEG image ({', '.join(IMAGE_SUFFIXES)})"
"""The images a query may be, in every command: `IMAGE_TYPES` by content (as ``lookfeel serve``
checks an upload), `lookfeel.data.layout.IMAGE_SUFFIXES` by name (as the dataset layout reads
files); a GIF or WebP is refused alike by the CLI and the server."""

_OTHER_IMAGES = (
    (b"GIF8", "a GIF"),
    (b"II*\x00", "a TIFF"),
    (b"MM\x00*", "a TIFF"),
    (b"BM", "a BMP"),
)


def _not_a_query_image(head: bytes) -> str:
    """Why a file beginning with ``head`` is no query image (not PNG or JPEG), naming its kind
    where its first bytes tell it."""
    kind = next((k for magic, k in _OTHER_IMAGES if head.startswith(magic)), None)
    if head.startswith(b"RIFF") and head[8:12] == b"WEBP":
        kind = "a WebP"
    if kind is None and sniff_video(head[:16]):
        return f"not {QUERY_IMAGES}: a video ({VIDEOS_ARE_TOUCH})"
    if kind is None:
        return f"not {QUERY_IMAGES}: it does not begin as one"
    return f"is {kind} image, not {QUERY_IMAGES}: convert it"


STILL_TOUCH_REFUSED = (
    "this model was trained on press videos, each read as its change from the frames before "
    "contact; a still image has none: give the press's video"
)
"""Why a still touch image is refused for a model trained on press videos (`check_touch_query`)."""

VIDEO_FOR_STILL_MODEL = (
    "this model was trained on still GelSight frames, and a press video is read as its change "
    "from the frames before contact (data.video_reference: subtract), which it never saw: its "
    "answer may mean little; give a still frame of the press"
)
"""Why a press video for a model trained on still frames is warned about (`check_touch_query`)."""


def check_touch_query(
    name: str | Path,
    video: bool,
    trained_on: str | None,
    config: DataConfig,
    warn: Callable[[str], None] | None = None,
) -> None:
    """Refuse a still touch image for a model that saw only press videos as differences.

    Such a model never saw a raw GelSight frame: each press it was trained on was read as
    ``128 + video_gain * (frame - no-contact frame)`` (``data.video_reference: subtract``), and
    a still image has no no-contact frame, so its answer would be confident and meaningless.
    A model trained with ``video_reference: none`` read raw frames, and one trained on still
    frames (or both kinds), or from a checkpoint that does not say (``trained_on`` None), is
    not refused anything. A model trained on still frames only takes a press video with a
    warning where the video is read as a difference image (`VIDEO_FOR_STILL_MODEL`): it never
    saw one, and its answer may mean little.

    Args:
        name: the query's file (or an upload's name), named in the error.
        video: whether the query is a press video.
        trained_on: the checkpoint's ``touch_input`` (`lookfeel.checkpoint.TOUCH_VIDEOS`, ...).
        config: the run's data settings.
        warn: where the warning goes, one line (``lookfeel serve`` collects it for its answer,
            thread-safely); default `warnings.warn`.

    Raises:
        ImageError: naming the file, when it is a still image and the model needs a video.
    """
    subtract = config.video_reference == "subtract"
    if trained_on == TOUCH_VIDEOS and not video and subtract:
        raise ImageError(Path(name), STILL_TOUCH_REFUSED)
    if trained_on == TOUCH_FRAMES and video and subtract:
        message = f"{name}: {VIDEO_FOR_STILL_MODEL}"
        if warn is not None:
            warn(message)
        else:
            warnings.warn(message, stacklevel=caller_stacklevel())


def check_touch_files(
    paths: QueryFiles,
    trained_on: str | None,
    config: DataConfig,
    warn: Callable[[str], None] | None = None,
) -> None:
    """`check_touch_query` of every file of a touch query (a video by its suffix), before any
    of them is decoded, its warnings to ``warn`` as there; a folder is refused as one (a press
    is a video or frame files).

    Raises:
        ImageError: naming a folder, or a still image the model does not take.
    """
    for p in _paths(paths):
        if Path(p).is_dir():
            videos_only = trained_on == TOUCH_VIDEOS and config.video_reference == "subtract"
            give = "the press's video" if videos_only else "a press's video or its frame files"
            raise ImageError(Path(p), f"is a folder, not a press: give {give}")
        check_touch_query(p, Path(p).suffix.lower() in VIDEO_SUFFIXES, trained_on, config, warn)


NO_VALID_DEPTH = "the depth map has no valid pixel (every pixel is 0, no reading)"
"""Why a depth query of holes only is refused: it shows nothing to match."""

VIDEOS_ARE_TOUCH = "videos are read as touch only"
"""Said of a press video given as depth or colour."""


def _preprocess(
    name: Path, data: bytes, modality: Modality | str, config: DataConfig, max_pixels: int
) -> torch.Tensor:
    modality = Modality.of(modality)
    if modality is Modality.DEPTH:
        mm = decode_depth(name, data, max_pixels)
        if not mm.any():  # 0 is a hole (no reading): nothing to match, whatever it would score
            raise ImageError(name, NO_VALID_DEPTH)
        a = preprocess_depth(mm, config)  # (S, S) float32
        return torch.from_numpy(np.ascontiguousarray(a)).unsqueeze(0)
    rgb = preprocess_rgb(open_rgb(name, data, max_pixels), modality, config)  # (S, S, 3)
    return torch.from_numpy(rgb).permute(2, 0, 1).float().div_(255.0)


def load_query_image(
    path: str | os.PathLike[str],
    modality: Modality | str,
    config: DataConfig,
    max_pixels: int = DEFAULT_MAX_PIXELS,
    *,
    on_video: Callable[[Path, bool], None] | None = None,
) -> torch.Tensor:
    """Decode and preprocess one query image of ``modality`` (a `Modality` or its name,
    ``"color"``) as training does.

    The file must be a regular file (a FIFO or device is refused at once, never waited on) of
    at most ``max_pixels`` pixels, checked from its header before decoding. Whether a touch
    query suits what the model was trained on is the caller's to check first, for every file
    of a query before any is decoded (`check_touch_query`, as `lookfeel.predict.predict_files`
    and `lookfeel.index.Matcher.load` do).

    ``on_video``, where given, is called once a touch press video is read, with its path and
    whether it has no colour (`lookfeel.data.video.Press.grey`, as the read found it: the video
    is not decoded again to ask).

    Returns:
        Float32 in [0, 1], S the side the model was trained on (``config.size_of(modality)``):
        (1, S, S) for depth, (3, S, S) for colour, (C, S, S) for touch with C =
        ``config.touch_channels``: 3, or 3 per frame where ``data.touch_frames`` reads
        several frames of a press together (9 for the default synthetic recipe's 3 frames);
        for a press video with ``data.video_embed: views``, its (V, C, S, S) views.

    Raises:
        ImageError: naming the file when it is missing, not a regular file, empty, not a PNG or
            JPEG image by its content (`QUERY_IMAGES`: a GIF or WebP is refused, as ``lookfeel
            serve`` refuses it), too large, or the wrong kind (e.g. an 8-bit PNG given as
            depth).
        ModalityError: ``modality`` names no modality.
    """
    path = Path(path)
    modality = Modality.of(modality)
    if modality is Modality.TOUCH and config.stacks_touch_frames:
        # Several frames of the press stacked (``data.touch_frames``): read with the file's
        # sibling frames, as in training.
        return to_tensor(ImageLoader(config, cache_dir=None).embed_file(path, modality))
    if modality is Modality.TOUCH and path.suffix.lower() in VIDEO_SUFFIXES:
        # A press recorded as a video: its frame(s) chosen and preprocessed as in training
        # (with ``data.video_embed: views``, all its views: (V, 3, S, S)).
        return _read_video(path, config, on_video)
    data = read_image_file(path)
    if not data:  # said as `lookfeel data check` says it, not as a file of another kind
        raise ImageError(path, "file is empty")
    if sniff_type(data[:16]) is None:  # as `lookfeel serve` refuses an upload (415)
        raise ImageError(path, _not_a_query_image(data[:16]))
    return _preprocess(path, data, modality, config, max_pixels)


def _read_video(
    path: Path, config: DataConfig, on_video: Callable[[Path, bool], None] | None
) -> torch.Tensor:
    """A press video's `load_query_image`; then ``on_video(path, grey)``, ``grey`` as its one
    decoding found (`ImageLoader.is_grey`), or, read from a disk cache entry that does not say
    (``data.cache_dir``, written before it was kept), as `is_grey_video` finds."""
    loader = ImageLoader(config, cache_dir=None)
    x = to_tensor(loader.embed_file(path, Modality.TOUCH))
    if on_video is not None:
        grey = loader.is_grey(path)
        on_video(path, is_grey_video(path) if grey is None else grey)
    return x


def load_query_files(
    paths: QueryFiles,
    modality: Modality | str,
    config: DataConfig,
    *,
    on_video: Callable[[Path, bool], None] | None = None,
) -> tuple[list[torch.Tensor], list[Path]]:
    """`load_query_image` of each file of one query (a single path is one file:
    `query_paths`), and the files read: of several, a press video without a press is left out
    with a warning (as a run leaves it out), so that one bad recording among an object's
    presses does not lose the whole answer.

    Raises:
        LookfeelError: no file given.
        NoPressError: the only file, or every file, holds no press (the first one's error).
        ImageError: as `load_query_image`.
    """
    modality = Modality.of(modality)
    images: list[torch.Tensor] = []
    used: list[Path] = []
    failed: list[NoPressError] = []
    for p in query_paths(paths):
        try:
            images.append(load_query_image(p, modality, config, on_video=on_video))
            used.append(Path(p))
        except NoPressError as e:
            failed.append(e)
    if not images:
        raise failed[0]
    for missed in failed:
        warnings.warn(f"{missed}: left out of the pooled query", stacklevel=caller_stacklevel())
    return images, used


def load_query_bytes(
    data: bytes,
    name: str,
    modality: Modality | str,
    config: DataConfig,
    max_pixels: int = DEFAULT_MAX_PIXELS,
    *,
    trained_on: str | None = None,
    warn: Callable[[str], None] | None = None,
    on_video: Callable[[str, bool], None] | None = None,
) -> torch.Tensor:
    """`load_query_image` for an upload, decoded from memory: errors name ``name`` (the
    client's file name) and nothing of the server's disk. A touch upload is a video by its
    content (`sniff_video`), whatever its name. A model that stacks a press's frames refuses
    a touch upload before anything else is said of it (no warning first).

    Args:
        warn: where a warning about the upload goes (`check_touch_query`'s), one line each;
            default `warnings.warn`. ``lookfeel serve`` passes a list's ``append`` to answer
            them to the client.
        on_video: called, once an upload that is a press video has been read, with ``name``
            and whether it has no colour (`lookfeel.data.video.Press.grey`, as that one
            decoding found: nothing is decoded again to ask): a model reads a press's colours.
            ``lookfeel serve`` says so in one line, as ``lookfeel match`` warns
            (`lookfeel.index.match.press_colour_line`). Default: not asked.

    Raises:
        ImageError: as `load_query_image`, naming ``name``.
        ModalityError: ``modality`` names no modality.
    """
    modality = Modality.of(modality)
    if modality is Modality.TOUCH and config.stacks_touch_frames:
        raise ImageError(
            Path(name),
            f"this model reads frames {list(config.touch_frame_indices)} of each press "
            "together (data.touch_frames), and an upload is one image: match the press's "
            "frame files with `lookfeel match` instead",
        )
    if modality is Modality.TOUCH:
        check_touch_query(name, sniff_video(data[:16]), trained_on, config, warn)
    if modality is Modality.TOUCH and sniff_video(data[:16]):
        return _video_bytes(data, name, config, on_video)
    return _preprocess(Path(name), data, modality, config, max_pixels)


def _video_bytes(
    data: bytes, name: str, config: DataConfig, on_video: Callable[[str, bool], None] | None = None
) -> torch.Tensor:
    """An uploaded press video: FFmpeg reads files, so it is written to a private temporary
    folder (removed at once) and read as `load_query_image` reads one; errors name ``name``.
    Once it is read, ``on_video(name, grey)`` is called (`load_query_image`'s ``on_video``)."""
    suffix = Path(name).suffix.lower()
    with tempfile.TemporaryDirectory(prefix="lookfeel-query-") as tmp:
        path = Path(tmp) / ("query" + (suffix if suffix in VIDEO_SUFFIXES else ".mov"))
        path.write_bytes(data)
        # Said after reading: a video that cannot be read, or holds no press, gets its error.
        named = None if on_video is None else (lambda _, grey: on_video(name, grey))
        try:
            return _read_video(path, config, named)
        except ImageError as e:
            raise ImageError(Path(name), e.reason) from None


def query_batch(images: Sequence[torch.Tensor], modality: Modality | str) -> torch.Tensor:
    """Stack preprocessed images (`load_query_image`'s) into the model's input for one
    modality.

    Depth and colour images are separate queries: (N, C, S, S). Touch images (a
    `Modality.pooled` modality's) are the presses of one query, pooled by the Multi-input Net:
    (1, P, C, S, S), or (1, P, V, C, S, S) when presses come as V views each (a single image
    among them counts as every view); C is 3, or 3 per frame with ``data.touch_frames``
    (`lookfeel.config.DataConfig.touch_channels`: 9 for the default synthetic recipe).

    Raises:
        ModelInputError: no image given, an image that is not a (C, S, S) or (V, C, S, S)
            tensor, or images of different shapes (or numbers of views), naming the first
            that differs.
        ModalityError: ``modality`` names no modality.
    """
    modality = Modality.of(modality)
    images = list(images)
    if not images:
        raise ModelInputError("query_batch: no image given: a query needs at least one image")
    for i, a in enumerate(images):
        if not isinstance(a, torch.Tensor) or a.dim() not in (3, 4):
            what = tuple(a.shape) if isinstance(a, torch.Tensor) else type(a).__name__
            raise ModelInputError(
                f"query_batch: image {i} is {what}; expected a (C, S, S) tensor (or "
                "(V, C, S, S) views of a press), as load_query_image returns"
            )
    first = images[0]
    for i, a in enumerate(images[1:], 1):
        if a.shape[-3:] != first.shape[-3:]:
            raise ModelInputError(
                f"query_batch: image {i} is {tuple(a.shape)} and image 0 {tuple(first.shape)}: "
                "every image of a query must have one shape; load_query_image reads each file "
                "at the model's size"
            )
    views = {len(a) for a in images if a.dim() == 4}
    if len(views) > 1:
        raise ModelInputError(
            f"query_batch: presses with different numbers of views {sorted(views)}: a query's "
            "press videos must be read with one data.video_views"
        )
    x = stack_views(images)
    if modality.pooled:
        return x.unsqueeze(0)  # (P, C, S, S) -> (1, P, C, S, S)
    return x.contiguous(memory_format=torch.channels_last)


# ---------------------------------------------------------------------------------------------
# Orientation: a query turned against the images its model is compared with.

ORIENTATIONS = ("portrait", "landscape", "square")
"""What `orientation_of` names a shape."""


_HEAD_BYTES = 256 * 1024
"""Bytes read of an image for its size: a JPEG's frame header follows its metadata (EXIF with
a thumbnail: up to 64 KiB a segment)."""


def frame_size(path: str | os.PathLike[str]) -> tuple[int, int] | None:
    """(width, height) of an image or a video's frames, read cheaply: an image's (PNG, JPEG)
    from its header bytes, a video's (by its content, `sniff_video`) from its first video
    stream as FFmpeg opens it, without decoding a frame. None where the file is not a regular
    file, cannot be read or does not say (reading it as a query then says why)."""
    p = Path(path)
    try:
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    except OSError:
        return None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):  # a FIFO is never waited on
            return None
        head = os.read(fd, _HEAD_BYTES)
    except OSError:
        return None
    finally:
        os.close(fd)
    if not sniff_video(head[:16]):
        return declared_size(head)
    return _video_size(str(p))


def bytes_frame_size(data: bytes) -> tuple[int, int] | None:
    """`frame_size` of a file's bytes (an upload): an image's from its header, a video's from
    its first video stream; None where they do not say."""
    if not sniff_video(data[:16]):
        return declared_size(data[:_HEAD_BYTES])
    return _video_size(io.BytesIO(data))


def _video_size(source: str | io.BytesIO) -> tuple[int, int] | None:
    """(width, height) of the first video stream of a file (a path) or bytes, as FFmpeg opens
    it, no frame decoded; None where it cannot say."""
    try:
        import av
    except ImportError:
        return None
    try:
        with av.open(source, mode="r") as container:
            if not container.streams.video:
                return None
            ctx = container.streams.video[0].codec_context
            w, h = int(ctx.width), int(ctx.height)
    except (av.FFmpegError, OSError, ValueError, EOFError):
        return None
    return (w, h) if w > 0 and h > 0 else None


def orientation_of(size: tuple[int, int], modality: Modality | str, config: DataConfig) -> str:
    """``portrait``, ``landscape`` or ``square`` (`ORIENTATIONS`): the shape of a (width,
    height) image of ``modality`` as the model resizes it to its square input, after the crop
    the run's data settings make (`lookfeel.data.images.preprocess_rgb`): a touch frame cropped
    to its central square (``data.touch_crop: center``, or ``auto`` for a 960x720 GelSight
    frame) or a photo (``data.color_crop: center``) is square.

    Raises:
        ModalityError: ``modality`` names no modality.
    """
    modality = Modality.of(modality)
    w, h = size
    if modality is Modality.TOUCH:
        cropped = config.touch_crop == "center" or (
            config.touch_crop == "auto" and (w, h) == GELSIGHT_SIZE
        )
    else:
        cropped = modality is Modality.COLOR and config.color_crop == "center"
    if cropped or abs(math.log(w / h)) <= SAME_SHAPE_LOG_RATIO:
        return "square"
    return "portrait" if h > w else "landscape"


def seen_size(
    name: str | os.PathLike[str],
    size: tuple[int, int],
    modality: Modality | str,
    config: DataConfig,
    *,
    video: bool | None = None,
) -> tuple[int, int]:
    """The (width, height) of file ``name`` of ``modality`` as the model reads it: a touch press
    video's ``size`` turned by ``data.video_rotate`` (90 or 270 degrees swap width and height),
    any other file's as it is.

    Args:
        video: whether the file is read as a video; None decides by its name's suffix
            (`VIDEO_SUFFIXES`), as a file on disk is read. ``lookfeel serve`` reads an upload
            as a video by its content (`sniff_video`), whatever its name, and passes that.

    Raises:
        ModalityError: ``modality`` names no modality.
    """
    if video is None:
        video = Path(name).suffix.lower() in VIDEO_SUFFIXES
    turned = Modality.of(modality) is Modality.TOUCH and config.video_rotate in (90, 270) and video
    return (size[1], size[0]) if turned else size


def shape_record(
    paths: Sequence[str | os.PathLike[str]], modality: Modality | str, config: DataConfig
) -> dict[str, Any] | None:
    """What shape the files of one modality are, for a query to be checked against
    (`warn_orientation`): ``{"orientation": ..., "size": [w, h]}``, the orientation all of them
    share (`orientation_of`) and their most common size, as the model reads them (`seen_size`:
    a press video turned by ``data.video_rotate``); None when they come in more than one
    orientation (``lookfeel data check`` warns of that) or none says its size (`frame_size`).
    """
    sizes = [seen_size(p, s, modality, config) for p in paths if (s := frame_size(p)) is not None]
    kinds = {orientation_of(s, modality, config) for s in sizes}
    if len(kinds) != 1:
        return None
    w, h = Counter(sizes).most_common(1)[0][0]
    return {"orientation": kinds.pop(), "size": [w, h]}


def _recorded(record: Mapping[str, Any] | None) -> tuple[str, str] | None:
    """(orientation, "WxH" or "") of a `shape_record`; None for none, or one this version does
    not read (a newer lookfeel's), which is then not checked."""
    if not isinstance(record, Mapping) or record.get("orientation") not in ORIENTATIONS:
        return None
    size = record.get("size")
    if not isinstance(size, (list, tuple)) or len(size) != 2:
        return str(record["orientation"]), ""
    ok = all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in size)
    return str(record["orientation"]), f"{size[0]}x{size[1]}" if ok else ""


def warn_orientation(
    paths: Sequence[str | os.PathLike[str]],
    modality: Modality | str,
    record: Mapping[str, Any] | None,
    config: DataConfig,
    holder: str,
) -> None:
    """Warn once, in one line, where query files are portrait and the images they are compared
    with landscape, or the other way round (`orientation_note` on each file's `frame_size`):
    each is resized to the network's one square input, so such a query is stretched unlike
    them and most likely turned.

    Args:
        paths: the query's files, all of ``modality``.
        modality: what they show (a `Modality` or its name).
        record: the compared images' `shape_record` (or None).
        config: the model's data settings (its crops).
        holder: whose images they are, as the warning names them (``"the library"``).

    Raises:
        ModalityError: ``modality`` names no modality.
    """
    note = orientation_note(
        [(str(p), frame_size(p)) for p in paths], modality, record, config, holder
    )
    if note is not None:
        warnings.warn(note, stacklevel=caller_stacklevel())


def orientation_note(
    files: Sequence[tuple[str, tuple[int, int] | None]],
    modality: Modality | str,
    record: Mapping[str, Any] | None,
    config: DataConfig,
    holder: str,
    *,
    videos: Sequence[bool] | None = None,
) -> str | None:
    """The one line `warn_orientation` warns (None where nothing is turned) for files given as
    (name, (width, height) or None): where some are portrait and the images they are compared
    with landscape, or the other way round (`orientation_of` of each file's `seen_size`: a
    press video as ``data.video_rotate`` turns it). The first such file is named, the others
    counted; a square query or a square record, a file whose size is not known and a missing
    record (a library built before it was kept) are not checked. ``lookfeel serve`` answers it
    for uploads, whose sizes come from their bytes (`bytes_frame_size`). For a press video, the
    line also names ``data.video_rotate``: the turns that would read it in the other
    orientation.

    Args:
        videos: for each file, in order, whether it is read as a video; None decides by each
            name's suffix, as a file on disk is read (`seen_size`). ``lookfeel serve`` passes
            what it found of each upload's content (`sniff_video`), so that a video named
            ``press.bin`` is a video and a PNG named ``frame.mp4`` a frame, as it reads them.

    Raises:
        ModalityError: ``modality`` names no modality.
    """
    modality = Modality.of(modality)
    known = _recorded(record)
    if known is None or known[0] == "square":
        return None
    want, want_size = known
    flags: list[bool | None] = [None] * len(files) if videos is None else list(videos)
    odd = []
    for (name, size), video in zip(files, flags, strict=True):
        if size is None:
            continue
        if video is None:
            video = Path(name).suffix.lower() in VIDEO_SUFFIXES
        seen = seen_size(name, size, modality, config, video=video)
        got = orientation_of(seen, modality, config)
        if got not in (want, "square"):
            odd.append((Path(name), got, size, seen, video))
    if not odd:
        return None
    first, got, (w, h), seen, video = odd[0]
    n = len(odd) - 1
    also = f" (and {n} other such file{'s' if n > 1 else ''})" if n else ""
    if modality is Modality.TOUCH:
        what = "video" if video else "frame"
        theirs = "presses"
    elif modality is Modality.COLOR:
        what, theirs = "image", "images"
    else:
        what, theirs = "map", "maps"
    their = f" ({want_size})" if want_size else ""
    shown = f"{w}x{h}"
    if seen != (w, h):
        shown += f", {seen[0]}x{seen[1]} as data.video_rotate={config.video_rotate} turns it"
    line = (
        f"{first}{also}: a {got} {modality.value} {what} ({shown}), but {holder}'s "
        f"{modality.value} {theirs} are {want}{their}: each is resized to the network's one "
        f"square input, so this one is stretched unlike them and most likely turned; turn it "
        f"to {want}"
    )
    if what == "video":  # a press video can be turned as it is decoded
        a, b = sorted({(config.video_rotate + 90) % 360, (config.video_rotate + 270) % 360})
        line += (
            f" (or train with --set data.video_rotate={a} or {b}, which turns every press "
            "video clockwise as it is decoded)"
        )
    return line
