"""Matching a query against a library: which known fabric, how it looks and feels, its properties.

For a query embedding e of modality q against the gallery modality g (by default the one that
matched best in calibration), every gallery item i gets ``P_i = exp(-c D_i^2) / sum_j exp(-c
D_j^2)`` with c calibrated for (q, g) (paper section 5.2, eq. 3-4), and a fabric's probability
is the sum over its items, times ``1 - P(unknown)``, the calibrated unknown class
(`lookfeel.index.calibrate`). The fabrics are ranked by probability; for each, its items nearest
to e in every modality of the library say what it looks like (depth, colour) and how it feels
(touch). Physical properties are predicted from the top ``k_properties`` fabrics, each weighted
by its probability: the weighted mean and standard deviation of their known labels, rounded to
`PROPERTY_DIGITS` significant digits of the column's largest value in the library (a weight of
1e-20 does not make a mean of 5e-20); for a column of classes (words such as material, ranks
such as hardness 0/1/2: `Library.classes`) the most likely class, the one whose fabrics carry
the most weight, with that share as its probability, as ``lookfeel predict`` answers a class
head. They come as ``lookfeel predict`` gives its own (`lookfeel.predict.PropertyValue`): a
mapping from label column to its `PropertyEstimate`, whose ``value`` is the answer in the
column's own terms (the mean, the rank 2, the word ``metal``), ``probability`` beside a class,
and the spread ``std`` and the count of fabrics ``fabrics`` beside. Fabrics are named by name
where the data names its objects (``sponge``), else by id (``fabric 7``). When the best
probability is below the calibrated threshold the answer is "no known fabric", with the chance
level 1/F beside it, and a note when the pair's threshold accepted no known fabric at all in
calibration (its ranking is then still worth reading).

A pair that calibration found better matched through its cross-modal map (``mapped``, see
`lookfeel.index.calibrate`) is matched that way: D is then the map's distance (both routes and
the hub correction, `lookfeel.metrics.cross_map.CrossMap.distances`; a library built before
session 22 has no hubs and is matched without it), computed exactly over every gallery item, and
so are the distances to each fabric's nearest items of that modality.

A query whose embedding is identical (distance below `IDENTICAL_DISTANCE`) to a library item of
its own modality is that item: it is reported as known, its fabric named, whatever the
threshold says (a user matching a file of the library expects its fabric, not "unknown").

A query turned against the library's items of its modality (a portrait press among landscape
ones: `lookfeel.index.query.warn_orientation`) is matched with one warning, naming the file and
both orientations; the library records its items' shape when built (`Matcher.shape`; a library
built before that is not checked). A press video with no colour (grey: `warn_grey_videos`) is
matched with one warning naming it: the model reads a press's colours. A model whose checkpoint
records that it was trained on grey presses (`lookfeel.checkpoint.LoadedModel.trained_on_grey`)
is warned of a colour press video instead, and of no grey one.

`Matcher.match_files` raises on the first file it cannot use; `Matcher.match_each` (``lookfeel
match``) answers such a file's query with a `MatchFailure` naming it and matches the others, as
``lookfeel predict`` answers each query (`lookfeel.predict.predict_files`).
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np
import torch
from numpy.typing import NDArray

from lookfeel.config import DataConfig
from lookfeel.config.model import EMBED_BATCH
from lookfeel.data.files import VIDEO_SUFFIXES, ImageError
from lookfeel.data.layout import press_kind
from lookfeel.data.video import is_grey_video
from lookfeel.devices import resolve_device
from lookfeel.errors import caller_stacklevel
from lookfeel.index.calibrate import unknown_probability
from lookfeel.index.library import Library, LibraryError, LibraryItem
from lookfeel.index.query import (
    VIDEO_FOR_STILL_MODEL,
    QueryFiles,
    check_touch_files,
    check_touch_query,
    load_query_files,
    load_query_image,
    query_batch,
    query_paths,
    warn_orientation,
)
from lookfeel.index.search import ExactSearch
from lookfeel.metrics import match_probabilities
from lookfeel.metrics.cross_map import CrossMap
from lookfeel.modality import Modality, Pair
from lookfeel.progress import bar as progress_bar

__all__ = [
    "COLOUR_VIDEO",
    "EMBED_BATCH",
    "GREY_VIDEO",
    "FabricMatch",
    "ItemRef",
    "MatchFailure",
    "MatchResult",
    "Matcher",
    "PropertyEstimate",
    "check_touch_dataset",
    "check_touch_input",
    "class_value",
    "format_match",
    "grey_line",
    "press_colour_line",
    "press_kind",
    "stacked_frames_refused",
    "warn_grey_videos",
    "warn_press_kinds",
]

IDENTICAL_DISTANCE = 1e-3
"""Embedding distance under which a query is taken to be the library item itself (unit-norm
embeddings: distinct images are typically 0.1-1.4 apart; one file re-embedded, ~1e-6)."""
FAISS_CANDIDATES = 2048
"""Items a faiss search returns; probabilities are normalised over these."""
PROPERTY_DIGITS = 4
"""Significant digits of a property estimate, relative to the column's largest value in the
library (labels are written with 2-3; more would be the weights' rounding noise)."""


def stacked_frames_refused(config: DataConfig) -> str:
    """Why a press video is refused by a model that stacks frame images of a press
    (``data.touch_frames``), with what to give instead (`check_touch_input`)."""
    return (
        f"this model reads frames {list(config.touch_frame_indices)} of each press stacked "
        "together, from the press's frame images (data.touch_frames), and a video has none: "
        "give the press's frame images, named F<id>_<kind>_<frame>_<press>.<ext> side by "
        "side, or train a model on press videos (data.touch_frames=[])"
    )


def _is_video(path: Path) -> bool:
    return path.suffix.lower() in VIDEO_SUFFIXES


def check_touch_input(
    paths: Sequence[str | Path],
    trained_on: str | None,
    config: DataConfig,
    warn: Callable[[str], None] | None = None,
) -> None:
    """Refuse, before any is decoded, the files of a touch query that the model cannot take:
    for a model that stacks a press's frame images (``data.touch_frames``), a press video or a
    folder (`stacked_frames_refused`: one error, without the warning a still-frame model gives
    a video it can read); else as `lookfeel.index.query.check_touch_files` (a still image
    for a model trained on press videos, a folder; a warning for a video given to a model
    trained on still frames, to ``warn`` where given, else `warnings.warn`).

    Raises:
        ImageError: naming the first file refused.
    """
    files = [Path(p) for p in paths]
    if config.stacks_touch_frames:
        for p in files:
            if p.is_dir():
                raise ImageError(
                    p,
                    "is a folder, not a press: give the press's frame images "
                    "(F<id>_<kind>_<frame>_<press>.<ext>)",
                )
            if _is_video(p):
                raise ImageError(p, stacked_frames_refused(config))
    check_touch_files(files, trained_on, config, warn)


def warn_press_kinds(
    paths: Sequence[str | Path],
    config: DataConfig,
    holder: str = "the model",
    warn: Callable[[str], None] | None = None,
) -> None:
    """Warn once, in one line, where touch query files are presses of a kind (`press_kind`)
    the model was not trained on (its ``data.touch_kinds``: a flat press given to a model
    trained on fold presses only), naming the first and counting the rest; files that do not
    say their kind are taken as they are. The line goes to ``warn`` where given (``lookfeel
    serve`` collects it for its answer), else to `warnings.warn`."""
    trained = {k.value for k in config.touch_kinds}
    other = [(p, k) for p in paths if (k := press_kind(p)) is not None and k.value not in trained]
    if not other:
        return
    first, kind = other[0]
    n = len(other) - 1
    also = f" (and {n} other such press{'es' if n > 1 else ''})" if n else ""
    kinds = "/".join(sorted(trained))
    message = (
        f"{first}{also}: a {kind.value} press, but {holder} was trained on {kinds} presses only "
        f"(its data.touch_kinds), so it may answer a {kind.value} press less well"
    )
    if warn is not None:
        warn(message)
    else:
        warnings.warn(message, stacklevel=caller_stacklevel())


GREY_VIDEO = (
    "the video has no colour (grey); lookfeel reads a press's colours, and a model trained on "
    "colour presses reads a grey one unlike them"
)
"""What `warn_grey_videos` says of a grey press video, after its name."""


COLOUR_VIDEO = (
    "the video has colour; the model was trained on grey presses (no colour), and reads a "
    "colour one unlike them"
)
"""What `warn_grey_videos` says of a colour press video for a model trained on grey presses,
after its name."""


def warn_grey_videos(
    paths: Sequence[str | Path],
    grey: Mapping[Path, bool] | None = None,
    trained_on_grey: bool | None = None,
) -> None:
    """Warn once, in one line, where touch query files are press videos with no colour,
    naming the first and counting the rest (`GREY_VIDEO`): a GelSight's or DIGIT's colours
    carry the surface's slopes, and a grey video gives the same value in each channel, which
    a model trained on colour presses never saw. For a model trained on grey presses
    (``trained_on_grey``: `lookfeel.checkpoint.LoadedModel.trained_on_grey`) the colour ones
    are warned of instead (`COLOUR_VIDEO`); where its checkpoint does not say (None), every
    grey video is, as before the record.

    Args:
        paths: the query's files (those that are not videos are passed over).
        grey: whether each video has no colour, as reading it found (`load_query_files`'s
            ``on_video``); a video it lacks is decoded again to ask (`is_grey_video`).
        trained_on_grey: what the model was trained on (None: not recorded).
    """
    known = grey or {}
    videos = [Path(p) for p in paths if _is_video(Path(p))]
    line = press_colour_line(
        [(p, known[p] if p in known else is_grey_video(p)) for p in videos], trained_on_grey
    )
    if line is not None:
        warnings.warn(line, stacklevel=caller_stacklevel())


def press_colour_line(
    videos: Sequence[tuple[str | Path, bool]], trained_on_grey: bool | None
) -> str | None:
    """The one line said of a query's press videos (each with whether it has no colour) for
    a model trained on grey presses or not (`warn_grey_videos`, and ``serve``'s note): of a
    model trained on colour presses, or not recorded, the grey ones (`grey_line`); of one
    trained on grey presses, the colour ones (`COLOUR_VIDEO`); None when none is."""
    if not trained_on_grey:
        return grey_line([p for p, g in videos if g])
    colour = [p for p, g in videos if not g]
    if not colour:
        return None
    n = len(colour) - 1
    also = f" (and {n} other colour video{'s' if n > 1 else ''})" if n else ""
    return f"{colour[0]}{also}: {COLOUR_VIDEO}"


def grey_line(grey: Sequence[str | Path]) -> str | None:
    """The one line said of the grey press videos ``grey`` (`warn_grey_videos`, and ``serve``'s
    note): the first named, the others counted, then `GREY_VIDEO`; None when there is none."""
    if not grey:
        return None
    n = len(grey) - 1
    also = f" (and {n} other grey video{'s' if n > 1 else ''})" if n else ""
    return f"{grey[0]}{also}: {GREY_VIDEO}"


def check_touch_dataset(
    paths: Sequence[Path], trained_on: str | None, config: DataConfig, root: Path
) -> None:
    """`check_touch_input` for the touch presses of a dataset (``paths``: each press's first
    file) that a library build or an evaluation would embed, before any is decoded: a press
    that ``lookfeel match`` would refuse is refused here too, naming the first such file and
    how many of the dataset's presses are alike; the warning for press videos given to a model
    trained on still frames is given once, for all of them.

    Raises:
        ImageError: naming the first press the model cannot take.
    """
    videos = [p for p in paths if _is_video(p)]
    stills = [p for p in paths if not _is_video(p)]

    def share(n: int, what: str) -> str:
        part = "all" if n == len(paths) else f"{n} of the"
        return f"{part} {len(paths)} touch presses of {root} are {what}"

    if config.stacks_touch_frames and videos:
        raise ImageError(
            videos[0],
            f"{stacked_frames_refused(config)} ({share(len(videos), 'videos')})",
        )
    try:
        check_touch_input(stills[:1], trained_on, config)
    except ImageError as e:
        raise ImageError(e.path, f"{e.reason} ({share(len(stills), 'still images')})") from None
    caught: list[str] = []
    if videos:
        check_touch_query(videos[0], True, trained_on, config, warn=caught.append)
    if caught:  # one warning for all the videos, the first named
        n = len(videos) - 1
        also = f" (and {n} other press video{'s' if n > 1 else ''} of {root})" if n else ""
        warnings.warn(f"{videos[0]}{also}: {VIDEO_FOR_STILL_MODEL}", stacklevel=caller_stacklevel())


def class_value(name: str) -> int | float | str:
    """A class name in its column's own terms: ``"2"`` -> 2, ``"0.5"`` -> 0.5, words as they are."""
    try:
        number = float(name)
    except ValueError:
        return name
    return int(number) if number.is_integer() else number


@dataclass(frozen=True)
class ItemRef:
    """A library item shown for a matched fabric."""

    id: str
    """``"<modality>:<row>"``; the web app serves its image at ``/api/items/{id}/image``."""
    modality: Modality
    path: str
    """The file it was embedded from."""
    distance: float
    """Its distance D to the query (through the pair's cross-modal map when the library
    matches that pair through one)."""


@dataclass(frozen=True, kw_only=True)
class PropertyEstimate:
    """A physical property predicted from the best-matching fabrics, in the shape of ``lookfeel
    predict``'s `lookfeel.predict.PropertyValue` (its fields first, in its order), with the
    spread and the count of fabrics beside: ``MatchResult.properties`` maps each label column
    to one.

    The column's kind says which fields are set: a column of numbers gives ``value`` (the mean)
    and ``std``; a column of words (material) ``value`` (the class), ``probability`` and
    ``probabilities``; a column of ranks (hardness 0/1/2, a class of numbers) all of them, the
    rank as ``value`` and the mean of the ranks as ``number``. A column that none of the
    likeliest fabrics carries: ``value`` None and ``fabrics`` 0. Its fields are given by name
    (they were ``name, mean, ...`` before session 57: a call by position is refused, not
    misread).
    """

    value: int | float | str | None = None
    """The answer in the column's own terms: for a column of classes (`Library.classes`) the
    most likely class (the rank ``2``, the word ``"metal"``); for other numbers the
    probability-weighted mean over the likeliest fabrics with the label known, rounded to
    `PROPERTY_DIGITS` digits of the column's scale. None when none of them has the label."""
    probability: float | None = None
    """The most likely class's probability: the share of the fabrics' weight that carries it;
    None for a column of numbers that are not classes."""
    probabilities: dict[str, float] = field(default_factory=dict)
    """Every class's share, in the column's class order (classes no top fabric carries: 0)."""
    number: float | None = None
    """For a column of ranks (classes of numbers), the probability-weighted mean of the ranks
    behind ``value`` (``0.7`` for the rank ``1``), as ``predict`` gives the number behind a rank
    it reads from a property head (``predict`` leaves it None for a column with a class head);
    None otherwise (a column of plain numbers has its mean as ``value``)."""
    std: float | None = None
    """Probability-weighted standard deviation of the number (``value``, or ``number`` for a
    column of ranks): the spread among plausible fabrics. None for a column of words."""
    fabrics: int = 0
    """How many fabrics carried the label."""


@dataclass(frozen=True)
class FabricMatch:
    """One ranked library fabric."""

    rank: int
    fabric_id: int
    name: str | None
    """The object's name (``sponge``) where the data names its objects; None for a numbered
    fabric and in a library built before names were recorded (then it is ``fabric <id>``)."""
    probability: float
    """Calibrated P(the query shows this fabric); with P(unknown), these sum to 1."""
    distance: float
    """Distance from the query to the fabric's nearest gallery item."""
    cluster: int | None
    labels: dict[str, float]
    nearest: dict[str, list[ItemRef]]
    """Modality -> the fabric's items nearest to the query: what it looks like and feels like."""
    text_labels: dict[str, str] = field(default_factory=dict)
    """Every known label cell as written, words included (``material: metal``); empty in a
    library built before they were recorded."""


@dataclass(frozen=True)
class MatchResult:
    """The answer to one query."""

    query_modality: Modality
    gallery_modality: Modality
    path: str
    """The query's file (the first, of a multi-press touch query)."""
    paths: list[str]
    """The query's files (several for a multi-press touch query), as ``lookfeel predict``
    names them."""
    presses: int
    """Images pooled into this query (touch presses; 1 for depth and colour)."""
    known: bool
    """Whether the best match reaches the calibrated threshold."""
    best_probability: float
    unknown_probability: float
    """P(none of the library's fabrics): the calibrated unknown class."""
    threshold: float
    c: float
    message: str
    fabrics: list[FabricMatch]
    properties: dict[str, PropertyEstimate]
    """Label column -> its estimate, as ``lookfeel predict``'s ``properties`` (numeric columns
    in the dataset's order, then the columns of words that are classes)."""
    property_fabrics: int
    """How many of the likeliest fabrics the properties were drawn from (whatever ``top``)."""
    backend: str
    timing_ms: dict[str, float] = field(default_factory=dict)

    @property
    def query(self) -> list[str]:
        """The query's files: ``paths``, by its name before it was named as ``predict``'s."""
        return self.paths


@dataclass(frozen=True)
class MatchFailure:
    """A query `Matcher.match_each` could not match, and why: as ``lookfeel predict`` answers
    such a query (`lookfeel.predict.Prediction` with its ``error``)."""

    path: str
    """The query's file (the first, of a multi-press touch query)."""
    paths: list[str]
    """Every file of the query."""
    query_modality: Modality | None
    """What the files show; None where that could not be told (``lookfeel match`` without
    ``--modality``, of a file it could not read)."""
    error: str
    """Why it is not matched, in one line naming the file: it is missing, a folder, not an
    image or video, cannot be decoded, is a still touch image for a model trained on press
    videos, or holds no press (every press of a touch query: one without is left out)."""

    def entry(self) -> dict[str, Any]:
        """This failure in a `MatchResult`'s shape, as ``lookfeel match --json`` and ``lookfeel
        serve`` answer it: its files, modality and ``error``; the result's other keys null, or
        empty where they are lists and mappings (``fabrics``, ``properties``, ``timing_ms``)."""
        blank: dict[str, Any] = dict.fromkeys(f.name for f in fields(MatchResult))
        blank.update(fabrics=[], properties={}, timing_ms={})
        return blank | asdict(self)


class Matcher:
    """Embeds queries with a library's model and matches them against the library.

    Args:
        library: an opened `Library`.
        device: where the model runs.

    Raises:
        LibraryError: the library's checkpoint is missing or changed.

    Example:
        >>> matcher = Matcher(Library.open("lib"))
        >>> [r] = matcher.match_files(["press1.png", "press2.png"], Modality.TOUCH)
        >>> r.fabrics[0].fabric_id, r.fabrics[0].probability, r.known
    """

    def __init__(self, library: Library, device: torch.device | str = "cpu") -> None:
        self.library = library
        self.device = resolve_device(device)  # a device this machine lacks: one line
        loaded = library.load_model(self.device)
        self.model = loaded.model
        self.touch_input = loaded.touch_input
        """What the model's touch branch was trained on (`LoadedModel.touch_input`): a touch
        query must suit it (`lookfeel.index.query.check_touch_query`)."""
        self.trained_on_grey = loaded.trained_on_grey
        """Whether the model was trained on grey press videos (`LoadedModel.trained_on_grey`;
        None: not recorded): which press videos of a query are warned of
        (`warn_grey_videos`)."""
        self._against: dict[Pair, Callable[[NDArray[np.floating]], NDArray[np.float64]]] = {}
        self._scales: dict[str, float] = {}  # per numeric column, its largest |label|
        for record in library.fabrics.values():
            for col, v in record.labels.items():
                self._scales[col] = max(self._scales.get(col, 0.0), abs(v))

    @property
    def data_config(self) -> DataConfig:
        """How query images are preprocessed: the run's own data settings."""
        return self.library.config.data

    def check_modality(self, modality: Modality | str) -> Modality:
        """``modality`` (a `Modality` or its name) as a `Modality`, which the model embeds.

        Raises:
            ModalityError: ``modality`` names no modality.
            LibraryError: the model cannot embed it.
        """
        modality = Modality.of(modality)
        if modality not in self.model.modalities:
            have = ", ".join(m.value for m in self.model.modalities)
            raise LibraryError(
                f"the library's model has no {modality.value} branch (it embeds: {have})"
            )
        return modality

    def shape(self, modality: Modality | str) -> dict[str, Any] | None:
        """The shape of the library's items of ``modality`` (a `Modality` or its name) that
        its manifest records (`lookfeel.index.query.shape_record`: their one orientation and
        most common size), which a query is checked against (`warn_orientation`); None for a
        modality the library lacks, items of several orientations, or a library built before
        it was recorded."""
        entries = self.library.manifest.get("modalities")
        entry = entries.get(Modality.of(modality).value) if isinstance(entries, dict) else None
        shape = entry.get("shape") if isinstance(entry, dict) else None
        return shape if isinstance(shape, dict) else None

    @torch.inference_mode()
    def embed(self, x: torch.Tensor, modality: Modality | str) -> NDArray[np.float32]:
        """Embed a `query_batch` (N, C, S, S) or (1, P, 3, S, S) -> (N, D) float32.

        Separate queries (depth, colour) go through the model `EMBED_BATCH` at a time, so
        memory does not grow with N; a touch query is one pooled query, and all its presses
        go through the model together."""
        modality = self.check_modality(modality)
        step = len(x) if modality is Modality.TOUCH else EMBED_BATCH
        out = [
            self.model({modality.value: x[start : start + step].to(self.device)})[modality.value]
            .float()
            .cpu()
            for start in range(0, len(x), max(step, 1))
        ]
        return torch.cat(out).numpy()

    def load(self, paths: QueryFiles, modality: Modality | str) -> torch.Tensor:
        """Read query files (a single path is one file) into a `query_batch`; errors name the
        file (a still touch image for a model trained on press videos is refused before any
        file is decoded)."""
        return self._load(paths, modality)[0]

    def _load(self, paths: QueryFiles, modality: Modality | str) -> tuple[torch.Tensor, list[Path]]:
        """`load`, and the files it read: of several touch presses (one query), a video
        without a press is left out with a warning, as a run leaves it out; the only one, or
        every one, is an error."""
        modality = self.check_modality(modality)
        paths = self._check(paths, modality)
        grey: dict[Path, bool] = {}
        images, used = load_query_files(
            paths, modality, self.data_config, on_video=grey.__setitem__
        )
        if modality is Modality.TOUCH:  # of the presses read: one left out has its own warning
            warn_grey_videos(used, grey, self.trained_on_grey)
        return query_batch(images, modality), used

    def _check(self, paths: QueryFiles, modality: Modality) -> list[Path]:
        """The files of a query as a list, checked and warned of before any is decoded (a
        touch query's files the model cannot take; a turned query: one warning for all)."""
        files = query_paths(paths)
        if modality is Modality.TOUCH:
            check_touch_input(files, self.touch_input, self.data_config)
            warn_press_kinds(files, self.data_config, "the library's model")
        warn_orientation(files, modality, self.shape(modality), self.data_config, "the library")
        return files

    def match_files(
        self,
        paths: QueryFiles,
        modality: Modality | str,
        top: int = 5,
        gallery: Modality | str | None = None,
        k_properties: int = 5,
        n_items: int = 2,
        *,
        progress: bool = False,
    ) -> list[MatchResult]:
        """Match image files: one result per depth/colour image, one for all touch presses.

        Args:
            paths: the query's files; a single path (``str`` or `~pathlib.Path`) is one file.
            modality: what the files show: a `Modality` or its name (``"color"``).
            top, gallery, k_properties, n_items: as `match_embedding`.
            progress: show a progress bar (tqdm) on stderr while depth or colour images are
                decoded and embedded, when they are more than one batch (`EMBED_BATCH`): the
                images done of all of them (``lookfeel match``; 3,000 photos take ~25 s on 2
                cores). One batch, or a touch query (one pooled query), shows none.

        Raises:
            ImageError: naming a file that cannot be used (`match_each` answers its query
                with a `MatchFailure` instead, and matches the others).
            LibraryError: the modality or gallery is not in the library.
            ModalityError: ``modality`` or ``gallery`` names no modality.
            LookfeelError: no file given.
        """
        out = []
        for r in self._match(
            paths, modality, top, gallery, k_properties, n_items, progress, each=False
        ):
            assert isinstance(r, MatchResult)  # without ``each``, a file's error is raised
            out.append(r)
        return out

    def match_each(
        self,
        paths: QueryFiles,
        modality: Modality | str,
        top: int = 5,
        gallery: Modality | str | None = None,
        k_properties: int = 5,
        n_items: int = 2,
        *,
        progress: bool = False,
    ) -> list[MatchResult | MatchFailure]:
        """`match_files`, but a file that cannot be used (missing, a folder, undecodable, of a
        kind the model does not take, a press video without a press) is its own query's
        `MatchFailure`, naming it, and the other queries are matched (``lookfeel match``,
        as ``lookfeel predict`` answers each query). Depth and colour files are each a query;
        touch files are one pooled query, which one such file fails (a press video without a
        press among others is left out with a warning, as `match_files` leaves it out).

        Returns:
            One entry per depth/colour file, in their order, or one for all touch presses.

        Raises:
            LibraryError: the modality or gallery is not in the library (every query's).
            ModalityError: ``modality`` or ``gallery`` names no modality.
            LookfeelError: no file given.
        """
        return self._match(
            paths, modality, top, gallery, k_properties, n_items, progress, each=True
        )

    def _match(
        self,
        paths: QueryFiles,
        modality: Modality | str,
        top: int,
        gallery: Modality | str | None,
        k_properties: int,
        n_items: int,
        progress: bool,
        *,
        each: bool,
    ) -> list[MatchResult | MatchFailure]:
        """`match_files` (``each`` False: a file's error is raised) or `match_each`."""
        modality = Modality.of(modality)
        gallery = None if gallery is None else Modality.of(gallery)  # before any file is read
        modality = self.check_modality(modality)
        loading = embedding = 0.0
        failed: dict[int, MatchFailure] = {}  # position in the answer -> its failure
        groups: list[list[str]] = []  # of the queries read, their files
        if modality is Modality.TOUCH:  # one query: every press is pooled, read together
            t0 = time.perf_counter()
            try:
                x, used = self._load(paths, modality)
            except ImageError as e:
                if not each:
                    raise
                given = [str(p) for p in query_paths(paths)]
                return [MatchFailure(given[0], given, modality, str(e))]
            t1 = time.perf_counter()
            emb = self.embed(x, modality)
            loading, embedding = t1 - t0, time.perf_counter() - t1
            groups = [[str(p) for p in used]]
        else:  # separate queries: decoded and embedded EMBED_BATCH at a time (memory)
            files = self._check(paths, modality)
            parts: list[NDArray[np.float32]] = []
            show = progress and len(files) > EMBED_BATCH
            bar = progress_bar(total=len(files), desc="match", unit="image", show=show)
            with bar:  # closed (its line cleared) before an error is printed
                for start in range(0, len(files), EMBED_BATCH):
                    t0 = time.perf_counter()
                    images = []
                    for i, p in enumerate(files[start : start + EMBED_BATCH], start):
                        try:
                            images.append(load_query_image(p, modality, self.data_config))
                        except ImageError as e:  # this file's own query
                            if not each:
                                raise
                            failed[i] = MatchFailure(str(p), [str(p)], modality, str(e))
                            continue
                        groups.append([str(p)])
                    t1 = time.perf_counter()
                    if images:
                        parts.append(self.embed(query_batch(images, modality), modality))
                    del images  # this batch's decoded images go before the next is read
                    loading += t1 - t0
                    embedding += time.perf_counter() - t1
                    bar.update(min(EMBED_BATCH, len(files) - start))
            dim = self.library.embed_dim
            emb = np.concatenate(parts) if parts else np.zeros((0, dim), np.float32)
        matched = iter(zip(emb, groups, strict=True))
        results: list[MatchResult | MatchFailure] = []
        for i in range(len(failed) + len(groups)):
            if i in failed:
                results.append(failed[i])
                continue
            vector, group = next(matched)
            r = self.match_embedding(
                vector,
                modality,
                group,
                top=top,
                gallery=gallery,
                k_properties=k_properties,
                n_items=n_items,
            )
            r.timing_ms.update(load=1e3 * loading, embed=1e3 * embedding)
            results.append(r)
        return results

    def match_item(
        self,
        item_id: str,
        top: int = 5,
        gallery: Modality | str | None = None,
        k_properties: int = 5,
        n_items: int = 2,
    ) -> MatchResult:
        """Match a library item as if it were a new query (itself left out of the gallery).

        Raises:
            KeyError: naming an unknown item id.
        """
        item = self.library.item(item_id)
        e = self.library.tables[item.modality].embeddings[item.row]
        return self.match_embedding(
            e,
            item.modality,
            [item.image],
            top=top,
            gallery=gallery,
            k_properties=k_properties,
            n_items=n_items,
            exclude=item_id,
        )

    def match_embedding(
        self,
        e: NDArray[np.floating] | torch.Tensor,
        modality: Modality | str,
        files: Sequence[str],
        *,
        top: int = 5,
        gallery: Modality | str | None = None,
        k_properties: int = 5,
        n_items: int = 2,
        exclude: str | None = None,
    ) -> MatchResult:
        """Rank the library's fabrics for one query embedding (see the module docstring).

        Args:
            e: (D,) the query's embedding, D the library's (`Library.embed_dim`).
            modality: the query's modality (a `Modality` or its name).
            files: the query's files, for the report (one name may be given as such).
            top: fabrics to return.
            gallery: the modality to match against (a `Modality` or its name); default:
                calibration's best for ``modality``.
            k_properties: fabrics the property estimate is drawn from.
            n_items: nearest items shown per fabric and modality.
            exclude: a library item id left out everywhere (a library item used as query).

        Raises:
            LibraryError: ``gallery`` is not in the library or was not calibrated; ``e`` is
                not one (D,) embedding, or holds NaN or infinite values.
            ModalityError: ``modality`` or ``gallery`` names no modality.
        """
        modality = Modality.of(modality)
        gallery = None if gallery is None else Modality.of(gallery)
        files = [files] if isinstance(files, str) else list(files)  # one name, not its letters
        e = self._query_embedding(e, files)
        if top < 1:
            raise LibraryError(f"top must be >= 1; got {top}")
        if k_properties < 1:
            raise LibraryError(f"k_properties must be >= 1; got {k_properties}")
        lib = self.library
        t0 = time.perf_counter()
        g = gallery if gallery is not None else lib.calibration.default_gallery.get(modality)
        if g is None:
            raise LibraryError(
                f"the library has no calibrated gallery for {modality.value} queries"
            )
        table = lib.table(g)
        try:
            cal = lib.calibration.pair(modality, g)
        except KeyError as err:
            raise LibraryError(str(err.args[0])) from None
        search = lib.search(g)
        left_out = -1  # the gallery row of a library item used as the query
        if exclude is not None and exclude.startswith(f"{g.value}:"):
            left_out = int(exclude.partition(":")[2])
        q = np.asarray(e)[None, :]
        through_map = self._mapped(modality, g)
        exact = through_map
        if exact is None and isinstance(search, ExactSearch):
            exact = search.distances
        if exact is None:  # faiss: the nearest rows
            d, idx = search.search(q, min(len(search), FAISS_CANDIDATES))
            keep = idx[0] != left_out
            d, fi = d[0][keep], table.fabric_index[idx[0][keep]]
        else:  # every row, unsorted: no sort is needed
            d, fi = exact(q)[0], table.fabric_index
            if left_out >= 0:
                d[left_out] = np.inf  # probability exp(-inf) = 0, never the nearest
        p_items = match_probabilities(d[None, :], cal.c)[0]
        logits = -cal.c * np.square(d)
        top_logit = logits.max()
        lse = top_logit + math.log(float(np.exp(logits - top_logit).sum()))
        p_unknown = float(unknown_probability(lse, cal.unknown_logit))
        nf = len(table.fabrics)
        pf = np.bincount(fi, weights=p_items, minlength=nf) * (1.0 - p_unknown)  # (F,)
        dmin = np.full(nf, np.inf)
        np.minimum.at(dmin, fi, d)
        found = np.flatnonzero(np.isfinite(dmin))
        order = found[np.lexsort((dmin[found], -pf[found]))]
        t1 = time.perf_counter()

        best = float(pf[order[0]]) if len(order) else 0.0
        known = best >= cal.threshold
        fabrics = [
            self._fabric(
                modality,
                r + 1,
                int(table.fabrics[j]),
                float(pf[j]),
                float(dmin[j]),
                e,
                exclude,
                n_items,
            )
            for r, j in enumerate(order[:top])
        ]
        ranked = [(int(table.fabrics[j]), float(pf[j])) for j in order[:k_properties]]
        properties = self._properties(ranked)
        best_id = int(table.fabrics[order[0]]) if len(order) else None
        best_name = self._title(best_id) if best_id is not None else "fabric None"
        chance = f"chance 1/{nf} = {1 / max(nf, 1):.3f}"
        same = self._identical(e, modality, exclude)
        if same is not None:
            known = True
            message = f"{self._title(same.fabric_id)}: the query is library item {same.id} itself"
            if best_id != same.fabric_id:
                message += (
                    f"; against {g.value} the best match is {best_name} (P = {best:.3f}, {chance})"
                )
        elif known:
            message = f"{best_name} (P = {best:.3f}, P(unknown) = {p_unknown:.3f}, {chance})"
        else:
            # A library of named objects (``sponge``) says "object", as `format_match` does.
            noun = "object" if any(r.name is not None for r in lib.fabrics.values()) else "fabric"
            message = (
                f"no known {noun}: the best match, {best_name}, has P = {best:.3f} "
                f"(P(unknown) = {p_unknown:.3f}, {chance}), below the threshold "
                f"{cal.threshold:.3f} chosen for a {100 * cal.target_false_accept:g}% "
                f"false-accept rate in-sample (on the library's own {noun}s, each left out of "
                "the gallery in turn: not a rate measured on new ones)"
            )
            if cal.n_absent and not cal.true_accept > 0:
                message += (
                    f" (at that rate this pair accepted no known {noun} in calibration, true "
                    f"accept {cal.true_accept:.3f}: read the ranking, not the verdict)"
                )
        if through_map is not None:
            message += f" (matched through the {modality.value}-{g.value} cross-modal map)"
        return MatchResult(
            query_modality=modality,
            gallery_modality=g,
            path=files[0] if files else "",
            paths=list(files),
            presses=len(files) if modality is Modality.TOUCH else 1,
            known=known,
            best_probability=best,
            unknown_probability=p_unknown,
            threshold=cal.threshold,
            c=cal.c,
            message=message,
            fabrics=fabrics,
            properties=properties,
            property_fabrics=len(ranked),
            backend=search.name,
            timing_ms={"search": 1e3 * (t1 - t0)},
        )

    def _query_embedding(
        self, e: NDArray[np.floating] | torch.Tensor, files: Sequence[str]
    ) -> NDArray[np.floating]:
        """``e`` as a numpy array, checked: one embedding of the library's dimension, finite
        (a NaN is no distance from anything, and would otherwise pass for a library item)."""
        if isinstance(e, torch.Tensor):
            e = e.detach().cpu().numpy()
        q = np.asarray(e)
        what = f"the query embedding of {', '.join(files)}" if files else "the query embedding"
        dim = self.library.embed_dim
        if q.shape != (dim,) or q.dtype.kind not in "fiu":
            raise LibraryError(
                f"{what} has shape {q.shape} ({q.dtype}); expected ({dim},): one embedding "
                f"of the library's dimension {dim}"
            )
        if not np.isfinite(q).all():
            raise LibraryError(
                f"{what} holds non-finite values (NaN or infinity); it matches nothing "
                "(a model whose weights diverged gives such embeddings)"
            )
        return q

    def _title(self, fabric_id: int) -> str:
        """A fabric as a person reads it: its name (``sponge``), else ``fabric 7``."""
        record = self.library.fabrics.get(fabric_id)
        return record.title if record is not None else f"fabric {fabric_id}"

    def _map(self, query: Modality, gallery: Modality) -> CrossMap | None:
        """The pair's cross-modal map when calibration chose to match through it."""
        key = Pair(query, gallery)
        cal = self.library.calibration.pairs.get(key)
        return self.library.cross_maps.get(key) if cal is not None and cal.mapped else None

    def _mapped(
        self, query: Modality, gallery: Modality
    ) -> Callable[[NDArray[np.floating]], NDArray[np.float64]] | None:
        """Distances through the pair's map to every gallery item (its reverse map of the
        gallery computed on first use and kept); None when the pair is not matched through a
        map."""
        key = Pair(query, gallery)
        if key not in self._against:
            cmap = self._map(query, gallery)
            if cmap is None:
                return None
            self._against[key] = cmap.against(self.library.table(gallery).embeddings)
        return self._against[key]

    def _identical(
        self, e: NDArray[np.floating], modality: Modality, exclude: str | None
    ) -> LibraryItem | None:
        """The library item of the query's modality whose embedding is the query's, if any."""
        if modality not in self.library.tables:
            return None
        table = self.library.table(modality)
        d, idx = self.library.search(modality).search(np.asarray(e)[None, :], 2)
        for dist, row in zip(d[0], idx[0], strict=True):
            if row < 0 or f"{modality.value}:{int(row)}" == exclude:
                continue
            if not dist <= IDENTICAL_DISTANCE:  # a NaN distance is no identity either
                return None
            return table.item(int(row))
        return None

    def _fabric(
        self,
        modality: Modality,
        rank: int,
        fabric_id: int,
        probability: float,
        distance: float,
        e: NDArray[np.floating],
        exclude: str | None,
        n_items: int,
    ) -> FabricMatch:
        lib = self.library
        nearest: dict[str, list[ItemRef]] = {}
        q = np.asarray(e, dtype=np.float64)
        for m, table in lib.tables.items():
            rows = table.rows_of(fabric_id)
            if exclude is not None:
                rows = rows[[f"{m.value}:{r}" != exclude for r in rows]]
            if not len(rows):
                continue
            gallery = table.embeddings[rows].astype(np.float64)
            cmap = self._map(modality, m)
            if cmap is not None:
                dist = cmap.distances(q[None, :], gallery)[0]
            else:
                dist = np.linalg.norm(gallery - q, axis=1)
            best = np.argsort(dist, kind="stable")[:n_items]
            nearest[m.value] = [
                ItemRef(f"{m.value}:{rows[i]}", m, table.item(int(rows[i])).image, float(dist[i]))
                for i in best
            ]
        record = lib.fabrics.get(fabric_id)
        return FabricMatch(
            rank=rank,
            fabric_id=fabric_id,
            name=record.name if record else None,
            probability=probability,
            distance=distance,
            cluster=record.cluster if record else None,
            labels=dict(record.labels) if record else {},
            nearest=nearest,
            text_labels=dict(record.text_labels) if record else {},
        )

    def _properties(self, ranked: list[tuple[int, float]]) -> dict[str, PropertyEstimate]:
        """Per label column (numeric ones in the dataset's order, then the columns of words
        that are classes), the estimate from the ``ranked`` (fabric id, probability) pairs."""
        lib = self.library
        columns = [*lib.label_columns, *(c for c in lib.classes if c not in lib.label_columns)]
        out: dict[str, PropertyEstimate] = {}
        for name in columns:
            cells: list[tuple[float | None, str | None, float]] = []
            for fid, p in ranked:
                record = lib.fabrics.get(fid)
                if record is None:
                    continue
                number = record.labels.get(name)
                cls = f"{number:g}" if number is not None else record.text_labels.get(name)
                if number is not None or cls is not None:
                    cells.append((number, cls, p))
            if not cells:
                out[name] = PropertyEstimate()
                continue
            w = np.asarray([p for _, _, p in cells], dtype=np.float64)
            w = w / w.sum() if w.sum() > 0 else np.full(len(w), 1.0 / len(w))
            mean = std = None
            if name in lib.label_columns:
                v = np.asarray([x for x, _, _ in cells], dtype=np.float64)
                m = float((w * v).sum())
                spread = math.sqrt(max(float((w * (v - m) ** 2).sum()), 0.0))
                mean, std = self._round(name, m), self._round(name, spread)
            if name not in lib.classes:
                out[name] = PropertyEstimate(value=mean, std=std, fabrics=len(cells))
                continue
            share = dict.fromkeys(lib.classes[name], 0.0)
            for (_, cls, _), wi in zip(cells, w, strict=True):
                assert cls is not None
                share[cls] = share.get(cls, 0.0) + float(wi)
            best = max(share, key=lambda k: share[k])  # ties: the first in class order
            out[name] = PropertyEstimate(
                value=class_value(best),
                probability=round(share[best], 4),
                probabilities={k: round(q, 4) for k, q in share.items()},
                number=mean,  # a column of ranks: the mean rank behind the class
                std=std,
                fabrics=len(cells),
            )
        return out

    def _round(self, column: str, x: float) -> float:
        """``x`` to `PROPERTY_DIGITS` significant digits of the column's largest value (0 when
        the column is all zeros); never -0.0."""
        scale = self._scales.get(column, 0.0)
        if not scale > 0:
            return 0.0
        decimals = PROPERTY_DIGITS - 1 - math.floor(math.log10(scale))
        return round(x, decimals) + 0.0


def format_match(result: MatchResult, width: int = 48) -> str:
    """A match result as a person reads it (``lookfeel match`` without ``--json``)."""
    files = ", ".join(Path(f).name for f in result.paths)
    video = any(Path(f).suffix.lower() in VIDEO_SUFFIXES for f in result.paths)
    what = f"{result.presses} presses" if result.presses > 1 else "1 video" if video else "1 image"
    lines = [
        f"Query {result.query_modality.value} ({what}: {files}) against "
        f"{result.gallery_modality.value}, c = {result.c:.4g}, unknown below P = "
        f"{result.threshold:.3f}",
        ("  match: " + result.message)
        if result.known
        else "  " + result.message[:1].upper() + result.message[1:],
    ]
    mods = sorted(
        {m for f in result.fabrics for m in f.nearest},
        key=lambda m: list(Modality).index(Modality(m)),
    )
    # A fabric is its name where the data names its objects (left-aligned, as words), else
    # its id (right-aligned, as numbers).
    names = [f.name if f.name is not None else str(f.fabric_id) for f in result.fabrics]
    named = any(f.name is not None for f in result.fabrics)
    col = max([6, *(len(n) for n in names)]) if named else 6
    align = "<" if named else ">"
    noun = "object" if named else "fabric"
    header = f"  {'rank':>4}  {noun:{align}{col}}  {'P':>6}  {'D':>7}  " + "  ".join(
        f"{m:<{width}}" for m in mods
    )
    lines.append(header.rstrip())
    for f, name in zip(result.fabrics, names, strict=True):
        cells = []
        for m in mods:
            refs = f.nearest.get(m, [])
            cells.append(_shorten(refs[0].path, width) if refs else "-")
        lines.append(
            (
                f"  {f.rank:>4}  {name:{align}{col}}  {f.probability:6.3f}  {f.distance:7.3f}  "
                + "  ".join(f"{c:<{width}}" for c in cells)
            ).rstrip()
        )
    props = [_property(c, p) for c, p in result.properties.items() if p.value is not None]
    if props:
        k = result.property_fabrics
        likeliest = f"the likeliest {noun}" if k == 1 else f"the {k} likeliest {noun}s"
        # With no known fabric the weights are the nearest fabrics' shares of a small P: what
        # those feel like, not a finding about the query.
        guess = "" if result.known else f"; no known {noun}: the nearest ones', a guess"
        lines.append(f"  properties ({likeliest} weighted by P{guess}): " + ", ".join(props))
    return "\n".join(lines)


def _property(column: str, p: PropertyEstimate) -> str:
    """``hardness 2 (87%)`` for a column of classes, as ``lookfeel predict`` prints a class
    head; ``thickness_mm 1.43 ± 0.3`` for a number."""
    if p.probability is not None or isinstance(p.value, str):
        return f"{column} {p.value} ({p.probability or 0:.0%})"
    return f"{column} {float(p.value or 0):.3g} ± {p.std or 0:.2g}"


def _shorten(path: str, width: int) -> str:
    p = Path(path)
    s = f"{p.parent.name}/{p.name}" if p.parent.name else p.name
    return s if len(s) <= width else "…" + s[-(width - 1) :]
